//! Planner and executor throughput: segments planned per second, set-points per second.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use motus_cnc_planner::{AxisLimits, Config, ExecState, Executor, PathItem, Planner, Segment};

const SEGMENTS: usize = 10_000;

fn config() -> Config<3> {
    let mut c = Config::new([
        AxisLimits { velocity: 200.0, acceleration: 2000.0 },
        AxisLimits { velocity: 150.0, acceleration: 1500.0 },
        AxisLimits { velocity: 50.0, acceleration: 500.0 },
    ]);
    c.buffer_capacity = 1_000_000;
    c
}

/// A spiral polyline of `SEGMENTS` short lines.
fn spiral() -> Vec<[f64; 3]> {
    (1..=SEGMENTS)
        .map(|k| {
            let t = k as f64 / SEGMENTS as f64;
            let phi = t * 20.0 * std::f64::consts::PI;
            let r = 20.0 + 60.0 * t;
            [r * phi.cos(), r * phi.sin(), 2.0 * (phi * 3.0).sin()]
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let pts = spiral();
    let mut g = c.benchmark_group("planner");
    g.throughput(Throughput::Elements(SEGMENTS as u64));
    g.bench_function("plan_10k_segments", |b| {
        b.iter(|| {
            let mut p = Planner::new(config(), [20.0, 0.0, 0.0]).unwrap();
            for (i, end) in pts.iter().enumerate() {
                p.push(i as u32, PathItem::Motion(Segment::Line { end: *end, feed: 100.0, rapid: false }))
                    .unwrap();
            }
            p.finish();
            p.pieces().len()
        })
    });
    g.finish();

    let mut ex = Executor::new(config(), [20.0, 0.0, 0.0]).unwrap();
    for (i, end) in pts.iter().enumerate() {
        ex.push(i as u32, PathItem::Motion(Segment::Line { end: *end, feed: 100.0, rapid: false })).unwrap();
    }
    ex.finish();
    let mut g = c.benchmark_group("executor");
    g.throughput(Throughput::Elements(1000));
    g.bench_function("1000_setpoints_1ms", |b| {
        b.iter(|| {
            let mut sum = 0.0;
            for _ in 0..1000 {
                sum += ex.tick(0.001).path_speed;
            }
            // Keep moving: back along the path at the end, forwards again at the start.
            match ex.state() {
                ExecState::Idle => ex.backward().unwrap(),
                ExecState::Held => ex.cycle_start().unwrap(),
                _ => {}
            }
            sum
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
