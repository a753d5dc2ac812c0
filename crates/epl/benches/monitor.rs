//! Monitor per-frame processing: decode + cycle tracking + value extraction, on one simulated
//! cycle (SoC, 5 × PReq/PRes, SoA) of the five-drive segment (criterion).
//!
//! Then the segment's real-time figures: the scenario of `tests/udp.rs` and `tests/veth.rs`
//! (`tests/common/mod.rs`: an MN, five drives, a monitor, a quick stop) at 1 ms and 400 us,
//! over UDP on loopback and over veth (needs root, skipped otherwise), each monitored for
//! `MOTUS_EPL_SECONDS` (5 s by default): cycles with a stale or invalid node, the MN's start
//! jitter, PReq -> PRes. Printed as `REALTIME <name> <value> <unit>` lines (`REALTIME-SKIP
//! <name> <reason>`) for `scripts/realtime.sh`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing, missing_docs)]

#[path = "../tests/common/mod.rs"]
mod common;

use std::sync::Arc;
use std::time::Duration;

use criterion::{black_box, Criterion, Throughput};
use motus_epl::netns::BridgedPorts;
use motus_epl::sim::MnConfig;
use motus_epl::sim::{Actual, SetPoint};
use motus_epl::{EthLink, UdpHub};
use motus_epl::{Monitor, MonitorConfig};
use motus_epl_protocol::{
    EplFrame, Flags, MacAddr, Message, NetTime, NmtState, PReq, PRes, PrRs, RequestedService, Soa, Soc,
    ValueMap,
};

fn cycle_frames() -> Vec<Vec<u8>> {
    let mn = MacAddr([2, 0, 0, 0, 0, 240]);
    let mut out = Vec::new();
    let soc = Soc {
        flags: Flags::empty(),
        net_time: NetTime::default(),
        relative_time: 400,
        reserved1: 0,
        reserved2: 0,
    };
    out.push(EplFrame::new(mn, MacAddr::SOC, 255, 240, Message::Soc(soc)).encode().unwrap());
    for n in 1..=5u8 {
        let cn = MacAddr([2, 0, 0, 0, 0, n]);
        let sp = SetPoint { control: 1, target: 1000 };
        let preq = PReq { flags: Flags::RD, payload: sp.encode().to_vec(), ..PReq::default() };
        out.push(EplFrame::new(mn, cn, n, 240, Message::PReq(preq)).encode().unwrap());
        let a = Actual { status: 1, position: 1234 * i32::from(n), speed: -50 };
        let pres = PRes {
            nmt_state: NmtState::Operational,
            flags: Flags::RD,
            pr_rs: PrRs::default(),
            pdo_version: 0,
            payload: a.encode(),
            reserved: 0,
        };
        out.push(EplFrame::new(cn, MacAddr::PRES, 255, n, Message::PRes(pres)).encode().unwrap());
    }
    let soa = Soa::new(NmtState::Operational, RequestedService::NoService, 0);
    out.push(EplFrame::new(mn, MacAddr::SOA, 255, 240, Message::Soa(soa)).encode().unwrap());
    out
}

fn bench(c: &mut Criterion) {
    let mut text = String::new();
    for n in 1..=5 {
        text.push_str(&format!(
            "[[node]]\nnode = {n}\nvalues = [{{ name = \"position\", offset = 16, type = \"i32\" }}, {{ name = \"speed\", offset = 20, type = \"i32\" }}]\n"
        ));
    }
    let map = ValueMap::from_toml(&text).unwrap();
    let frames = cycle_frames();
    let mut monitor = Monitor::new(map, MonitorConfig::default());
    let mut g = c.benchmark_group("monitor");
    g.throughput(Throughput::Elements(frames.len() as u64));
    let mut t = 0u64;
    g.bench_function("cycle_of_12_frames", |b| {
        b.iter(|| {
            for f in &frames {
                t += 1000;
                black_box(monitor.push(t, black_box(f)));
            }
        })
    });
    g.finish();
}

/// One segment scenario; prints its `REALTIME` lines under `name` (e.g. `epl.udp.400us`).
fn segment(name: &str, veth: bool, cycle: Duration, pres_timeout: Duration, spin: bool) {
    let label = name.replace('.', " ");
    let config = MnConfig { cycle, pres_timeout, spin_for_pres: spin, ..MnConfig::default() };
    let seconds = common::seconds(5.0);
    let out = if veth {
        let ports = ["mn", "cn1", "cn2", "cn3", "cn4", "cn5", "mon"];
        let ns = BridgedPorts::create("eplb", &ports).unwrap();
        let mut links = ns.open(&ports).unwrap();
        let mon = links.pop().unwrap();
        let mn = links.remove(0);
        let out = common::run_scenario(&label, mn, links, mon, config, seconds);
        drop(ns);
        out
    } else {
        let hub = UdpHub::new();
        let mn: Arc<dyn EthLink> = Arc::new(hub.connect().unwrap());
        let cns: Vec<Arc<dyn EthLink>> =
            (0..5).map(|_| Arc::new(hub.connect().unwrap()) as Arc<dyn EthLink>).collect();
        let mon: Arc<dyn EthLink> = Arc::new(hub.connect().unwrap());
        common::run_scenario(&label, mn, cns, mon, config, seconds)
    };
    let us = |ns: u64| ns as f64 / 1000.0;
    println!("REALTIME {name}.missed {:.3} %", out.missed_percent());
    println!(
        "REALTIME {name}.ran {:.1} %",
        100.0 * out.monitored_cycles as f64 / out.nominal_cycles.max(1.0)
    );
    println!("REALTIME {name}.jitter.p99 {:.1} us", us(out.mn.jitter().p99));
    println!("REALTIME {name}.rtt.p99 {:.1} us", us(out.mn.rtt().p99));
}

/// The scenarios to run: `MOTUS_EPL_SEGMENTS` (comma-separated names such as `udp.1ms`,
/// `veth.400us`), else all four.
fn selected(name: &str) -> bool {
    std::env::var("MOTUS_EPL_SEGMENTS")
        .map_or(true, |list| list.split(',').any(|s| format!("epl.{}", s.trim()) == name))
}

fn main() {
    // Scheduling as the binary's `--realtime` sets it: MOTUS_REALTIME (auto, nice, off).
    if let Some(obtained) = motus_realtime::set_policy_from_env().unwrap() {
        println!("real-time: {obtained}; {}", motus_realtime::wake_latency::hold_if_fifo());
    }
    let mut c = Criterion::default().configure_from_args();
    bench(&mut c);
    c.final_summary();
    // The segment scenarios take both cores for their cycle threads: one after another.
    let (ms, us400) = (Duration::from_millis(1), Duration::from_micros(400));
    let run = |name: &str, veth: bool, cycle: Duration, pres_timeout: Duration, spin: bool| {
        if selected(name) {
            segment(name, veth, cycle, pres_timeout, spin);
        }
    };
    run("epl.udp.1ms", false, ms, Duration::from_micros(300), false);
    run("epl.udp.400us", false, us400, Duration::from_micros(150), false);
    if motus_epl::netns::is_root() {
        run("epl.veth.1ms", true, ms, Duration::from_micros(300), false);
        // Five drives in 400 us between user-space threads need the polling CNs and MN.
        run("epl.veth.400us", true, us400, Duration::from_micros(150), true);
    } else {
        println!("segment over veth: skipped, network namespaces and veth need root");
        println!("REALTIME-SKIP epl.veth not root");
    }
}
