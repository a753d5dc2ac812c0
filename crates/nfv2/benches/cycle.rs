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
    let filter = std::env::args().skip(1).find(|a| !a.starts_with('-')).unwrap_or_default();
    let seconds = std::env::var("MOTUS_NFV2_BENCH_SECONDS").ok().and_then(|s| s.parse().ok()).unwrap_or(5);
    if filter.is_empty() || "cycle".contains(&filter) {
        run(Packing::Packed, seconds);
        run(Packing::Unpacked, seconds);
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
