//! Benchmark of the hot path: one cycle of the drilling cell (task, spindle, machine).
#![allow(missing_docs, clippy::unwrap_used)]

use criterion::{criterion_group, criterion_main, Criterion};
use motus_cnc_tech::{DrillingCell, DrillingPara, MachineConfig, SpindlePara};

fn cycle(c: &mut Criterion) {
    let mut cell =
        DrillingCell::new(DrillingPara::default(), SpindlePara::default(), MachineConfig::default());
    c.bench_function("drilling cell cycle (idle)", |b| {
        b.iter(|| cell.cycle(0.001, [0.0, 0.0]));
    });
    let mut cell =
        DrillingCell::new(DrillingPara::default(), SpindlePara::default(), MachineConfig::default());
    c.bench_function("drilling cell: M63 + M60 on the simulated machine", |b| {
        b.iter(|| {
            let mut fresh = cell.clone();
            fresh.on_m_function(63).unwrap();
            while fresh.cycle(0.001, [0.0, 0.0]).acknowledged.is_empty() {}
            fresh.on_m_function(60).unwrap();
            while fresh.cycle(0.001, [0.0, 0.0]).acknowledged.is_empty() {}
            fresh
        });
    });
    cell.cycle(0.001, [0.0, 0.0]);
}

criterion_group!(benches, cycle);
criterion_main!(benches);
