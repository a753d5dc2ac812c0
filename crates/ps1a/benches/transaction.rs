//! Bus benchmarks against the simulator over a real pty:
//! * latency of one status transaction without pacing (criterion, plus p50/p99 over
//!   10 000 transactions printed first) — target: median below 100 us;
//! * line utilisation of a continuous status-polling loop over 4 modules with baud-rate
//!   pacing at 9600 Bd — target: at least 90 % of the wire limit.
#![allow(missing_docs, clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use criterion::{Criterion, Throughput};
use motus_ps1a::Ps1aBus;
use motus_ps1a_protocol::Command;
use motus_ps1a_sim::{LineOptions, SimLine};
use motus_serial::{BusConfig, BusMaster, LineSettings, PtyLink, SerialLink, ServeThread};
use std::sync::Arc;
use std::time::{Duration, Instant};

struct Rig {
    /// Stops serving first (dropped first), before the folder of its pty goes.
    _line: ServeThread<SimLine>,
    _dir: tempfile::TempDir,
    bus: Ps1aBus,
}

impl Rig {
    fn new(baud: u32, pacing: bool, addresses: &[u8]) -> Rig {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("line");
        let pty = PtyLink::create(Some(&path), LineSettings::n81(baud)).unwrap();
        let line = SimLine::new(
            Box::new(pty),
            LineOptions { addresses: addresses.to_vec(), baud_pacing: pacing, ..LineOptions::default() },
        )
        .unwrap();
        let line = ServeThread::spawn("ps1a-sim", line, SimLine::run).unwrap();
        let link = SerialLink::open(path.to_str().unwrap(), baud).unwrap();
        let bus = Ps1aBus::new(Arc::new(BusMaster::new(Box::new(link), BusConfig::default())));
        Rig { _dir: dir, bus, _line: line }
    }
}

fn percentiles() {
    let rig = Rig::new(115_200, false, &[1]);
    for _ in 0..1000 {
        rig.bus.transact(1, Command::StatusRequest).unwrap();
    }
    let mut samples: Vec<Duration> = (0..10_000)
        .map(|_| {
            let t = Instant::now();
            rig.bus.transact(1, Command::StatusRequest).unwrap();
            t.elapsed()
        })
        .collect();
    samples.sort();
    let p = |q: f64| samples[((samples.len() as f64 - 1.0) * q) as usize];
    println!(
        "ps1a status transaction over pty (no pacing), 10000 samples: p50 {:?}  p99 {:?}  max {:?}  [target: median < 100 us: {}]",
        p(0.5),
        p(0.99),
        samples[samples.len() - 1],
        if p(0.5) < Duration::from_micros(100) { "MET" } else { "NOT MET" }
    );
}

fn utilisation() {
    let rig = Rig::new(9600, true, &[1, 2, 3, 4]);
    // Warm up, then poll continuously for 5 s.
    for a in 1..=4 {
        rig.bus.transact(a, Command::StatusRequest).unwrap();
    }
    rig.bus.master().reset_stats();
    let end = Instant::now() + Duration::from_secs(5);
    let mut addr = 1u8;
    while Instant::now() < end {
        rig.bus.transact(addr, Command::StatusRequest).unwrap();
        addr = addr % 4 + 1;
    }
    let s = rig.bus.master().stats();
    let per_tx = LineSettings::n81(9600).wire_time(4 + 8);
    println!(
        "ps1a polling 4 modules at 9600 Bd with pacing: {:.1} transactions/s (wire limit {:.1}/s), line utilisation {:.1} % [target >= 90 %: {}], time-outs {}",
        s.transactions_per_second(),
        1.0 / per_tx.as_secs_f64(),
        s.utilisation() * 100.0,
        if s.utilisation() >= 0.9 { "MET" } else { "NOT MET" },
        s.totals.timeouts
    );
}

fn main() {
    let filter = std::env::args().skip(1).find(|a| !a.starts_with('-')).unwrap_or_default();
    if filter.is_empty() || "percentiles".contains(&filter) {
        percentiles();
    }
    if filter.is_empty() || "utilisation".contains(&filter) {
        utilisation();
    }
    let mut c = Criterion::default().configure_from_args();
    let rig = Rig::new(115_200, false, &[1]);
    let mut g = c.benchmark_group("ps1a_bus");
    g.throughput(Throughput::Elements(1));
    g.bench_function("status_transaction_pty", |b| {
        b.iter(|| rig.bus.transact(1, Command::StatusRequest).unwrap())
    });
    g.finish();
    c.final_summary();
}
