//! Frames handled per second by one `SimDrive`: an SDO expedited upload, and a SYNC that
//! makes it sample and send three synchronous TPDOs.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::time::Instant;

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use motus_canopen_protocol::CanFrame;
use motus_icla_sim::{SimConfig, SimDrive};

fn booted() -> (SimDrive, Instant) {
    let now = Instant::now();
    let mut d = SimDrive::new(SimConfig::node(2));
    d.poll(now);
    (d, now)
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("sim_drive");
    g.throughput(Throughput::Elements(1));
    let (mut d, now) = booted();
    let upload: CanFrame = "602#4041600000000000".parse().unwrap();
    g.bench_function("sdo_expedited_upload", |b| b.iter(|| black_box(d.handle(black_box(&upload), now))));

    let (mut d, now) = booted();
    // Enable TPDO3 (0x6064 + 0x606C, type 1) and make TPDO1 synchronous too (type 1).
    for f in [
        "602#2302180182030040",
        "602#2300180182010080",
        "602#2F00180201000000",
        "602#2300180182010040",
        "000#0102",
    ] {
        d.handle(&f.parse().unwrap(), now);
    }
    let sync: CanFrame = "080#".parse().unwrap();
    assert_eq!(d.handle(&sync, now).len(), 3);
    g.bench_function("sync_three_tpdos", |b| b.iter(|| black_box(d.handle(black_box(&sync), now))));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
