//! Round-trip rate of D2 fast messages to the six joints over a pty against the simulated
//! arm with baud-rate pacing at 115200 Bd, against the wire limit (target: at least 85 %),
//! and a criterion measurement of one unpaced D2 round trip.
#![allow(missing_docs, clippy::panic, clippy::unwrap_used, clippy::expect_used)]

use criterion::{Criterion, Throughput};
use motus_kv01::Kv01Bus;
use motus_kv01_protocol::{Address, Command, CrcMode, Message};
use motus_kv01_sim::{LineOptions, SimLine};
use motus_serial::{BusConfig, BusMaster, LineSettings, PtyLink, SerialLink, ServeThread};
use std::sync::Arc;
use std::time::{Duration, Instant};

struct Rig {
    /// Stops serving first (dropped first), before the folder of its pty goes.
    _line: ServeThread<SimLine>,
    _dir: tempfile::TempDir,
    bus: Kv01Bus,
}

impl Rig {
    fn new(pacing: bool) -> Rig {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("arm");
        let pty = PtyLink::create(Some(&path), LineSettings::n81(115_200)).unwrap();
        let line = SimLine::new(Box::new(pty), LineOptions { baud_pacing: pacing, ..LineOptions::default() })
            .unwrap();
        let line = ServeThread::spawn("kv01-sim", line, SimLine::run).unwrap();
        let link = SerialLink::open(path.to_str().unwrap(), 115_200).unwrap();
        let bus =
            Kv01Bus::new(Arc::new(BusMaster::new(Box::new(link), BusConfig::default())), CrcMode::Strict);
        Rig { _dir: dir, bus, _line: line }
    }
}

fn d2() -> Command {
    Command::Fast { text: "V0".into() }
}

fn utilisation() {
    let rig = Rig::new(true);
    let joints: Vec<Address> = (1..=6).filter_map(Address::joint).collect();
    for a in &joints {
        rig.bus.transact(*a, d2()).unwrap();
    }
    rig.bus.master().reset_stats();
    let end = Instant::now() + Duration::from_secs(5);
    let mut n = 0u64;
    while Instant::now() < end {
        for a in &joints {
            rig.bus.transact(*a, d2()).unwrap();
            n += 1;
        }
    }
    let s = rig.bus.master().stats();
    let req = Message::request(Address::joint(1).unwrap(), d2()).encode().unwrap().len();
    let per = LineSettings::n81(115_200).wire_time(req + 8);
    println!(
        "kv01 D2 round trips to six joints at 115200 Bd with pacing: {:.0}/s (wire limit {:.0}/s, {} + 8 bytes), six-joint cycle {:.2} ms, line utilisation {:.1} % [target >= 85 %: {}], time-outs {}",
        s.transactions_per_second(),
        1.0 / per.as_secs_f64(),
        req,
        6000.0 / s.transactions_per_second(),
        s.utilisation() * 100.0,
        if s.utilisation() >= 0.85 { "MET" } else { "NOT MET" },
        s.totals.timeouts
    );
    let _ = n;
}

fn main() {
    let filter = std::env::args().skip(1).find(|a| !a.starts_with('-')).unwrap_or_default();
    if filter.is_empty() || "utilisation".contains(&filter) {
        utilisation();
    }
    let mut c = Criterion::default().configure_from_args();
    let rig = Rig::new(false);
    let a = Address::joint(2).unwrap();
    let mut g = c.benchmark_group("kv01_bus");
    g.throughput(Throughput::Elements(1));
    g.bench_function("d2_round_trip_pty", |b| b.iter(|| rig.bus.transact(a, d2()).unwrap()));
    g.finish();
    c.final_summary();
}
