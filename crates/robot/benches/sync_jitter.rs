//! The PDO cycle at 1 kHz with three drives (issue 5 point 5): the socketcand hub on
//! 127.0.0.1 (no bit-rate model), the simulated robot (three IclA drives at nodes 2, 3, 4
//! on one connection) and Motus's master on another. All nodes are started (NMT), the
//! master produces SYNC every 1 ms and listens to TPDO2 (0x280 + node, transmission
//! type 1: statusword + position after every SYNC).
//!
//! * Criterion measures one cycle by hand: SYNC sent, wait for the three TPDO2 replies.
//! * Then the SYNC producer runs for 10 s (5 s with `BENCH_QUICK` set; `MOTUS_SYNC_SECONDS`
//!   sets it) and the bench
//!   prints the period and its jitter (|period − 1 ms|, from the instants the producer
//!   handed SYNC to the transport) and how many cycles got all three TPDO2 replies before
//!   the next SYNC.
//!
//! The figures are also printed as `REALTIME <name> <value> <unit>` lines for
//! `scripts/realtime.sh`.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use std::sync::mpsc::Receiver;
use std::sync::Arc;
use std::time::{Duration, Instant};

use criterion::{Criterion, Throughput};
use motus_can::socketcand::{Hub, HubConfig, SocketcandBus, SETTLE};
use motus_can::{CanBus, CanFrame, Received};
use motus_canopen::{Master, NmtCommand, NmtState};
use motus_robot::sim::{SimRobot, SimRobotConfig};

const NODES: [u8; 3] = [2, 3, 4];
const TPDO2: u32 = 0x280;
const PERIOD: Duration = Duration::from_millis(1);

fn connect(hub: &Hub) -> Arc<dyn CanBus> {
    Arc::new(SocketcandBus::connect(hub.local_addr(), "can0").unwrap())
}

fn drain(rx: &Receiver<Received>) {
    while rx.try_recv().is_ok() {}
}

/// One cycle by hand: SYNC, then wait until every node's TPDO2 arrived.
fn one_cycle(master: &Master, rx: &Receiver<Received>) {
    drain(rx);
    master.send_sync().unwrap();
    let mut seen = 0u8;
    while seen != 0b111 {
        let r = rx.recv_timeout(Duration::from_millis(100)).expect("TPDO2 within 100 ms of SYNC");
        let bit = r.frame.id() - TPDO2 - 2;
        seen |= 1 << bit;
    }
}

/// Value at quantile `q` of sorted `v` (nearest rank).
fn quantile(v: &[f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    v[rank - 1]
}

fn sorted(mut v: Vec<f64>) -> Vec<f64> {
    v.sort_by(f64::total_cmp);
    v
}

struct Figures {
    syncs: usize,
    period_ms: Vec<f64>,
    jitter_us: Vec<f64>,
    cycles: usize,
    complete: usize,
    skipped_deadlines: usize,
    latency_us: Vec<f64>,
    stray: usize,
    /// |send instant − its slot on the grid first SYNC + k·1 ms|, sorted.
    grid_us: Vec<f64>,
}

/// Assigns every TPDO2 to the SYNC period it arrived in (the last SYNC sent before it) and
/// counts the periods (those closed by a next SYNC) in which all three nodes answered.
fn analyse(sends: &[Instant], replies: &[Received]) -> Figures {
    let period_ms: Vec<f64> =
        sends.windows(2).map(|w| w[1].saturating_duration_since(w[0]).as_secs_f64() * 1e3).collect();
    let jitter_us = sorted(period_ms.iter().map(|p| (p - 1.0).abs() * 1e3).collect());
    // A period over 1.5 ms means the producer skipped at least one deadline.
    let skipped_deadlines = period_ms.iter().filter(|p| **p > 1.5).count();
    let cycles = sends.len().saturating_sub(1);
    let mut seen = vec![0u8; sends.len()];
    let mut last = vec![Duration::ZERO; sends.len()];
    let mut stray = 0;
    for r in replies {
        let k = sends.partition_point(|s| *s <= r.at);
        let Some(cycle) = k.checked_sub(1) else {
            stray += 1;
            continue;
        };
        let bit = r.frame.id() - TPDO2 - 2;
        if seen[cycle] & (1 << bit) != 0 {
            stray += 1; // a second reply of one node in one period: a late one
        }
        seen[cycle] |= 1 << bit;
        last[cycle] = last[cycle].max(r.at.saturating_duration_since(sends[cycle]));
    }
    let complete_idx: Vec<usize> = (0..cycles).filter(|&i| seen[i] == 0b111).collect();
    let latency_us = sorted(complete_idx.iter().map(|&i| last[i].as_secs_f64() * 1e6).collect());
    // Signed offset of each send from the grid of the first one, in -500..500 us; the grid's
    // phase is taken as the median offset (the first SYNC itself may be late, e.g. by the
    // producer thread's start-up), and the figure is each send's distance from that phase.
    let signed: Vec<f64> = sends
        .first()
        .map(|s0| {
            sends
                .iter()
                .map(|s| {
                    let t = s.saturating_duration_since(*s0).as_secs_f64() * 1e3;
                    (t - t.round()) * 1e3
                })
                .collect()
        })
        .unwrap_or_default();
    let phase = quantile(&sorted(signed.clone()), 0.5);
    let grid_us = sorted(
        signed
            .iter()
            .map(|o| {
                let d = o - phase;
                (d - (d / 1e3).round() * 1e3).abs()
            })
            .collect(),
    );
    Figures {
        grid_us,
        syncs: sends.len(),
        period_ms: sorted(period_ms),
        jitter_us,
        cycles,
        complete: complete_idx.len(),
        skipped_deadlines,
        latency_us,
        stray,
    }
}

fn main() {
    // Scheduling as the binary's `--realtime` sets it: MOTUS_REALTIME (auto, nice, off).
    if let Some(obtained) = motus_realtime::set_policy_from_env().unwrap() {
        println!("real-time: {obtained}; {}", motus_realtime::wake_latency::hold_if_fifo());
    }
    self_check();
    let mut c = Criterion::default().configure_from_args();
    let run_for = std::env::var("MOTUS_SYNC_SECONDS")
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s > 0.0)
        .map(Duration::from_secs_f64)
        .unwrap_or(if std::env::var_os("BENCH_QUICK").is_some() {
            Duration::from_secs(5)
        } else {
            Duration::from_secs(10)
        });

    let hub = Hub::start(HubConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        bitrate: None,
        channel: "can0".into(),
    })
    .unwrap();
    let _robot = SimRobot::start(connect(&hub), SimRobotConfig::seed()).unwrap();
    let master = Master::new(connect(&hub));
    std::thread::sleep(SETTLE * 2);
    master.nmt(0, NmtCommand::Start).unwrap();
    for n in NODES {
        // Heartbeat every 1000 ms: the first one in Operational comes within about a second.
        master.wait_state(n, NmtState::Operational, Duration::from_secs(3)).unwrap();
    }
    let rx = master.subscribe(TPDO2 + 2..=TPDO2 + 4);

    let mut g = c.benchmark_group("pdo_cycle_socketcand");
    g.throughput(Throughput::Elements(1));
    g.sample_size(30).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    g.bench_function("sync_to_three_tpdo2", |b| b.iter(|| one_cycle(&master, &rx)));
    g.finish();

    // The 1 kHz run.
    std::thread::sleep(Duration::from_millis(20));
    drain(&rx);
    let mut producer = master.start_sync(PERIOD, None).unwrap();
    let start = Instant::now();
    let mut replies = Vec::with_capacity(run_for.as_millis() as usize * 3 + 64);
    while start.elapsed() < run_for {
        if let Ok(r) = rx.recv_timeout(Duration::from_millis(10)) {
            replies.push(r);
        }
    }
    producer.stop();
    let until = Instant::now() + Duration::from_millis(50);
    while let Some(left) = until.checked_duration_since(Instant::now()) {
        if let Ok(r) = rx.recv_timeout(left) {
            replies.push(r);
        }
    }
    let sends = producer.send_instants();
    let f = analyse(&sends, &replies);
    let stats = master.stats();
    println!(
        "== PDO cycle at 1 kHz, 3 simulated drives (nodes 2,3,4), socketcand hub 127.0.0.1, {run_for:?} =="
    );
    println!(
        "SYNC 1 kHz: {} SYNC sent; period p50 {:.3} ms (min {:.3}, max {:.3}); |jitter| p50 {:.1} us, p99 {:.1} us, max {:.1} us; {} periods > 1.5 ms (deadline skipped)",
        f.syncs,
        quantile(&f.period_ms, 0.5),
        f.period_ms.first().copied().unwrap_or(f64::NAN),
        f.period_ms.last().copied().unwrap_or(f64::NAN),
        quantile(&f.jitter_us, 0.5),
        quantile(&f.jitter_us, 0.99),
        f.jitter_us.last().copied().unwrap_or(f64::NAN),
        f.skipped_deadlines,
    );
    println!(
        "SYNC 1 kHz: |offset from the 1 ms grid (phase = median)| p50 {:.1} us, p99 {:.1} us, max {:.1} us (the producer keeps absolute deadlines)",
        quantile(&f.grid_us, 0.5),
        quantile(&f.grid_us, 0.99),
        f.grid_us.last().copied().unwrap_or(f64::NAN),
    );
    println!(
        "TPDO2 replies complete in {} of {} cycles ({} missed, {:.3} %); {} TPDO2 received, {} outside their period",
        f.complete,
        f.cycles,
        f.cycles - f.complete,
        100.0 * (f.cycles - f.complete) as f64 / f.cycles.max(1) as f64,
        replies.len(),
        f.stray,
    );
    println!(
        "SYNC -> third TPDO2 (complete cycles): p50 {:.0} us, p99 {:.0} us, max {:.0} us; master rx frames {}, transport errors {}",
        quantile(&f.latency_us, 0.5),
        quantile(&f.latency_us, 0.99),
        f.latency_us.last().copied().unwrap_or(f64::NAN),
        stats.frames_received,
        stats.transport_errors,
    );
    println!("REALTIME sync.1khz.jitter.p99 {:.1} us", quantile(&f.jitter_us, 0.99));
    println!("REALTIME sync.1khz.grid.p99 {:.1} us", quantile(&f.grid_us, 0.99));
    println!(
        "REALTIME sync.1khz.tpdo2_missed {:.3} %",
        100.0 * (f.cycles - f.complete) as f64 / f.cycles.max(1) as f64
    );
    println!("REALTIME sync.1khz.latency.p99 {:.0} us", quantile(&f.latency_us, 0.99));
    drop(master);
    c.final_summary();
}

/// Checks the cycle bookkeeping on hand-made instants before measuring (a harness=false
/// bench runs no `#[test]`s, so the check runs on every bench run).
fn self_check() {
    let t0 = Instant::now();
    let us = Duration::from_micros;
    let rx = |id: u32, at: Instant| Received { frame: CanFrame::new(id, &[0; 6]).unwrap(), at };
    // SYNC at 0, 1000, 2100, 3000 us: periods 1.0, 1.1, 0.9 ms -> |jitter| 0, 100, 100 us.
    let sends = [t0, t0 + us(1000), t0 + us(2100), t0 + us(3000)];
    // Period 0: nodes 2,3,4 (complete, last at 400 us). Period 1: nodes 2,3, node 4 only
    // after the next SYNC (incomplete). Period 2: node 4 twice (one stray), 2, 3 (complete,
    // last at 2400 - 2100 = 300 us).
    let replies = [
        rx(0x282, t0 + us(200)),
        rx(0x283, t0 + us(300)),
        rx(0x284, t0 + us(400)),
        rx(0x282, t0 + us(1200)),
        rx(0x283, t0 + us(1300)),
        rx(0x284, t0 + us(2150)),
        rx(0x282, t0 + us(2200)),
        rx(0x283, t0 + us(2300)),
        rx(0x284, t0 + us(2400)),
    ];
    let f = analyse(&sends, &replies);
    assert_eq!((f.syncs, f.cycles, f.complete, f.stray), (4, 3, 2, 1));
    assert_eq!(f.latency_us.len(), 2);
    assert!((f.latency_us[0] - 300.0).abs() < 1.0 && (f.latency_us[1] - 400.0).abs() < 1.0);
    assert!((quantile(&f.jitter_us, 1.0) - 100.0).abs() < 1e-6);
    assert!(quantile(&f.jitter_us, 0.3) < 1e-6);
    assert!((quantile(&f.period_ms, 0.5) - 1.0).abs() < 1e-9);
    assert_eq!(f.skipped_deadlines, 0);
    // Offsets from the grid of the first SYNC: 0, 0, 100, 0 us; median 0 -> 0, 0, 0, 100.
    assert!((quantile(&f.grid_us, 1.0) - 100.0).abs() < 1e-6 && quantile(&f.grid_us, 0.75) < 1e-6);
    // First SYNC 200 us late, the others on time (grid 0 of the others): offsets from the
    // first's grid -200, -200, -200, 0 -> phase -200 -> distances 0, 0, 0, 200.
    let late = [t0 + us(200), t0 + us(1000), t0 + us(2000), t0 + us(3000)];
    let g = analyse(&late, &[]).grid_us;
    assert!(g[..3].iter().all(|d| *d < 1e-6) && (g[3] - 200.0).abs() < 1e-6, "{g:?}");
}
