//! The pan-tilt head's cycle over a pty against two simulated 1209A with 57600 Bd pacing:
//! the scheduler runs back to back (requested cycle 0) with both drives holding a position
//! (a position set-point and two queries per slave and cycle), packed and unpacked,
//! against the physical limit of the wire (target: within 10 % of it); the source's 2 ms
//! cycle is checked against the same limit. Then criterion measures cheap hot paths:
//! scanning an answer, planning a cycle, one tracking-filter step, "where at t" in a full
//! history.
//!
//! `cargo bench -p motus-nfv2 --bench cycle` (`-- <name>`, e.g. `-- position_at`, runs one
//! criterion benchmark without the pty runs;
//! `MOTUS_NFV2_BENCH_SECONDS` to change their length, 5 s by default).
#![allow(missing_docs, clippy::panic, clippy::unwrap_used, clippy::expect_used)]

use criterion::{black_box, Criterion};
use motus_nfv2::pantilt::filter::{Limits, SecondOrderLimiter};
use motus_nfv2::{
    CyclePlan, DriveConfig, Nfv2Bus, Packing, PositionSample, SampleHistory, Scheduler, SchedulerConfig,
};
use motus_nfv2_protocol::{
    Command, CommandCode as C, DeviceProfile, Frame, FrameScanner, Revision, RS485_BAUD,
};
use motus_nfv2_sim::{LineOptions, SimLine};
use motus_serial::{BusConfig, BusMaster, LineSettings, PtyLink, SerialLink, ServeThread};
use motus_wire::Scanner;
use std::sync::Arc;
use std::time::Duration;

struct Rig {
    /// Stops serving first (dropped first), before the folder of its pty goes.
    _line: ServeThread<SimLine>,
    _dir: tempfile::TempDir,
    path: String,
}

impl Rig {
    fn new() -> Rig {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("nfv2");
        let pty = PtyLink::create(Some(&path), LineSettings::n81(RS485_BAUD)).unwrap();
        let options = LineOptions { addresses: vec![1, 2], baud_pacing: true, ..LineOptions::default() };
        let line = SimLine::new(Box::new(pty), options).unwrap();
        let line = ServeThread::spawn("nfv2-sim", line, SimLine::run).unwrap();
        Rig { _dir: dir, path: path.to_str().unwrap().to_string(), _line: line }
    }

    fn bus(&self) -> Nfv2Bus {
        let link = SerialLink::open(&self.path, RS485_BAUD).unwrap();
        let config = BusConfig { margin: Duration::from_millis(2), retries: 2 };
        Nfv2Bus::new(Arc::new(BusMaster::new(Box::new(link), config)))
    }
}

fn run(packing: Packing, seconds: u64) {
    let rig = Rig::new();
    let config = SchedulerConfig {
        cycle: Duration::ZERO,
        packing,
        current_every: 0,
        inputs_every: 0,
        ..SchedulerConfig::default()
    };
    let sched = Scheduler::start(rig.bus(), vec![DriveConfig::new(1), DriveConfig::new(2)], config).unwrap();
    for d in sched.drives() {
        d.enable().unwrap();
    }
    std::thread::sleep(Duration::from_millis(300));
    sched.reset_stats();
    std::thread::sleep(Duration::from_secs(seconds));
    let s = sched.stats();
    let limit = sched.plan().min_cycle;
    let ms = |d: Duration| d.as_secs_f64() * 1000.0;
    let within = s.mean.as_secs_f64() <= limit.as_secs_f64() * 1.1;
    println!(
        "pan+tilt {packing}: achieved cycle mean {:.3} ms, p99 {:.3} ms, max {:.3} ms; wire limit {:.3} ms ({} B per cycle at {} Bd, turnaround {:.1} ms); \
         {:.1} % of the limit [target within 10 %: {}]; line utilisation {:.1} %; {} missed answer(s) in {} cycles",
        ms(s.mean),
        ms(s.p99),
        ms(s.max),
        ms(limit),
        sched.plan().bytes_per_cycle(),
        sched.plan().baud,
        ms(sched.plan().turnaround),
        (s.mean.as_secs_f64() / limit.as_secs_f64() - 1.0) * 100.0 + 100.0,
        if within { "MET" } else { "NOT MET" },
        s.utilisation * 100.0,
        s.missed_answers,
        s.cycles
    );
    println!(
        "REALTIME nfv2.cycle.{packing}.of_limit {:.1} %",
        s.mean.as_secs_f64() / limit.as_secs_f64() * 100.0
    );
    if packing == Packing::Packed {
        let two_ms = limit <= Duration::from_millis(2);
        println!(
            "source's 2 ms cycle for pan+tilt on RS-485 at 57600 Bd: physical limit {:.3} ms [{}]",
            ms(limit),
            if two_ms { "MET" } else { "NOT MET: impossible on this line" }
        );
    }
}

fn answer_bytes() -> Vec<u8> {
    let answer = Frame {
        address: 1,
        commands: vec![
            Command::values(C::ReadDrivesPosition, [123_456]),
            Command::values(C::ReadDrivesStatus, [0x10]),
        ],
    };
    answer.encode(Revision::LATEST).unwrap()
}

fn main() {
    // Scheduling as the binary's `--realtime` sets it: MOTUS_REALTIME (auto, nice, off).
    if let Some(obtained) = motus_realtime::set_policy_from_env().unwrap() {
        println!("real-time: {obtained}; {}", motus_realtime::wake_latency::hold_if_fifo());
    }
    let filter = std::env::args().skip(1).find(|a| !a.starts_with('-')).unwrap_or_default();
    let seconds = std::env::var("MOTUS_NFV2_BENCH_SECONDS").ok().and_then(|s| s.parse().ok()).unwrap_or(5);
    if filter.is_empty() || "cycle".contains(&filter) {
        run(Packing::Packed, seconds);
        run(Packing::Unpacked, seconds);
    }
    if filter.is_empty() || "where_at_t".contains(&filter) {
        where_at_t_on_real_time();
    }
    let mut c = Criterion::default().configure_from_args();
    let bytes = answer_bytes();
    let scanner = FrameScanner::new(Revision::LATEST);
    c.bench_function("scan_answer", |b| b.iter(|| scanner.scan(black_box(&bytes))));
    let frames: Vec<(Frame, Revision)> = [1u8, 2]
        .iter()
        .map(|&a| {
            let f = Frame {
                address: a,
                commands: vec![
                    Command::values(C::SetDrivesPosition, [1000]),
                    Command::query(C::ReadDrivesPosition),
                    Command::query(C::ReadDrivesStatus),
                ],
            };
            (f, Revision::LATEST)
        })
        .collect();
    let profile = DeviceProfile::axis_1209a();
    c.bench_function("plan_two_slaves", |b| {
        b.iter(|| {
            CyclePlan::new(
                Duration::from_millis(15),
                RS485_BAUD,
                Duration::from_micros(200),
                Packing::Packed,
                &frames,
                &profile,
            )
        })
    });
    let mut f = SecondOrderLimiter::new(0.0, Limits { velocity: 30.0, acceleration: 120.0 }, 0.015);
    let mut t = 0.0f64;
    c.bench_function("filter_step", |b| {
        b.iter(|| {
            t += 0.015;
            f.step(black_box(20.0 * (t * 1.2566).sin()), 25.1 * (t * 1.2566).cos())
        })
    });
    // "Where was the head at t": the weighted local fit in a full 8192-sample history.
    let t0 = std::time::Instant::now();
    let mut history = SampleHistory::new(8192, Duration::from_millis(20), Duration::from_millis(40));
    for k in 0..8192u32 {
        let at = t0 + Duration::from_micros(15_000 * u64::from(k));
        let counts = (20_000.0 * (f64::from(k) * 0.015 * 1.2566).sin()) as i64;
        let rtt = Duration::from_micros(5_500 + u64::from(k % 7) * 400);
        history.push(PositionSample::new(at, at + rtt, counts, Duration::ZERO));
    }
    let query = t0 + Duration::from_micros(15_000 * 6000 + 7_300);
    c.bench_function("position_at", |b| b.iter(|| history.position_at(black_box(query))));
    c.final_summary();
}

/// "Where was the head at t" on real time: the pan-tilt head tracks a sine (pan 20 deg at
/// 0.2 Hz, tilt 15 deg at 0.6 Hz, beyond its limits) over a real pty at 57600 Bd with baud
/// pacing against two simulated 1209A, for `MOTUS_NFV2_WHERE_SECONDS` (20 s by default); every
/// 37 ms it is asked where it was 10-160 ms ago (a camera frame's exposure), and each answer
/// is compared with the simulator's true trajectory. Target: within 0.05 deg, at least 80 %
/// of the questions answered (docs/decisions.md, "Where at t"). The functional tests run the
/// same head on virtual time; this is the figure on the host's real time.
#[allow(clippy::indexing_slicing)]
fn where_at_t_on_real_time() {
    use motus_nfv2::{PanTilt, PanTiltConfig, TargetPoint};
    use motus_nfv2_sim::lock;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::time::Instant;

    /// Counts per degree of the head's axes.
    const K: f64 = 200_000.0 / 360.0;
    let seconds: f64 =
        std::env::var("MOTUS_NFV2_WHERE_SECONDS").ok().and_then(|s| s.parse().ok()).unwrap_or(20.0);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nfv2-where");
    let pty = PtyLink::create(Some(&path), LineSettings::n81(RS485_BAUD)).unwrap();
    let options = LineOptions { addresses: vec![1, 2], baud_pacing: true, ..LineOptions::default() };
    let line = SimLine::new(Box::new(pty), options).unwrap();
    let controllers: Vec<_> = line.controllers().into_iter().map(|(_, c)| c).collect();
    let sim_clock = line.clock();
    // Near the HOME edges, to keep the homing short.
    for (c, at) in controllers.iter().zip([-18_000.0, -19_000.0]) {
        lock(c).place_axis(at).unwrap();
    }
    let _line = ServeThread::spawn("nfv2-sim", line, SimLine::run).unwrap();
    let link = SerialLink::open(path.to_str().unwrap(), RS485_BAUD).unwrap();
    let config = BusConfig { margin: Duration::from_millis(3), retries: 2 };
    let bus = Nfv2Bus::new(Arc::new(BusMaster::new(Box::new(link), config)));
    let pt = PanTilt::start(bus, PanTiltConfig::default()).unwrap();
    pt.home().unwrap();
    let n = (seconds * 50.0) as usize;
    let points: Vec<TargetPoint> = (0..=n)
        .map(|i| {
            let t = i as f64 / 50.0;
            TargetPoint {
                t,
                pan_deg: 20.0 * (std::f64::consts::TAU * 0.2 * t).sin(),
                tilt_deg: 15.0 * (std::f64::consts::TAU * 0.6 * t + 0.5).sin(),
            }
        })
        .collect();
    pt.goto(points[0].pan_deg, points[0].tilt_deg).unwrap();
    pt.wait_idle(Duration::from_secs(10)).unwrap();

    // The true trajectory, in the drives' counter coordinates: (simulated time, counts).
    let stop = Arc::new(AtomicBool::new(false));
    let recorder = {
        let (stop, controllers, sim_clock) = (Arc::clone(&stop), controllers.clone(), sim_clock.clone());
        std::thread::spawn(move || {
            let mut out: Vec<Vec<(Duration, f64)>> = vec![Vec::new(); controllers.len()];
            while !stop.load(Ordering::Relaxed) {
                for (c, rec) in controllers.iter().zip(out.iter_mut()) {
                    let mut g = lock(c);
                    g.advance_to(sim_clock.now());
                    let s = g.true_state();
                    drop(g);
                    if rec.last().is_some_and(|l| l.0 >= s.time) {
                        continue;
                    }
                    let offset = s.counter as f64 - s.position_counts.floor();
                    rec.push((s.time, s.position_counts + offset));
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            out
        })
    };
    let feed = pt.track(points).unwrap();
    let end = feed.origin() + Duration::from_secs_f64(seconds);
    let (mut wheres, mut asked) = (Vec::new(), 0usize);
    let mut k = 0u64;
    while Instant::now() < end {
        std::thread::sleep(Duration::from_millis(37));
        k += 1;
        let at = Instant::now() - Duration::from_millis(10 + (k * 7) % 150);
        asked += 1;
        if let Ok(pos) = pt.where_at(at) {
            wheres.push((at, pos));
        }
    }
    pt.wait_idle(Duration::from_secs(10)).unwrap();
    stop.store(true, Ordering::Relaxed);
    let truth = recorder.join().unwrap();
    // The true position at simulated time t, interpolated between regulator cycles.
    let truth_at = |rec: &[(Duration, f64)], t: Duration| -> Option<f64> {
        let i = rec.partition_point(|r| r.0 <= t);
        let (a, b) = (rec.get(i.checked_sub(1)?)?, rec.get(i)?);
        if b.0 - a.0 > Duration::from_millis(5) {
            return None;
        }
        let f = (t - a.0).as_secs_f64() / (b.0 - a.0).as_secs_f64().max(1e-9);
        Some(a.1 + (b.1 - a.1) * f)
    };
    let (mut worst, mut compared) = (0.0f64, 0usize);
    for (at, (pan, tilt)) in &wheres {
        let t = sim_clock.at(*at);
        let (Some(tp), Some(tt)) = (truth_at(&truth[0], t), truth_at(&truth[1], t)) else { continue };
        worst = worst.max((pan - tp / K).abs().max((tilt - tt / K).abs()));
        compared += 1;
    }
    let answered = 100.0 * wheres.len() as f64 / asked.max(1) as f64;
    println!(
        "where-at-t on real time, sine tracked {seconds} s: {asked} questions, {} answered ({answered:.1} %), \
         {compared} compared with the truth, worst error {worst:.4} deg",
        wheres.len()
    );
    assert!(compared > 10, "where-at-t: only {compared} answers compared with the truth");
    println!("REALTIME nfv2.where.worst {worst:.4} deg");
    println!("REALTIME nfv2.where.answered {answered:.1} %");
}
