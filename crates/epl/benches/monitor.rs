//! Monitor per-frame processing: decode + cycle tracking + value extraction, on one simulated
//! cycle (SoC, 5 × PReq/PRes, SoA) of the five-drive segment.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use motus_epl::sim::{Actual, SetPoint};
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

criterion_group!(benches, bench);
criterion_main!(benches);
