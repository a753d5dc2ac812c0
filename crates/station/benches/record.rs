//! Cost of `Recorder::record` (target: well under 1 us per sample).
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use motus_station::trace::{Condition, Recorder, Trigger};

fn bench_record(c: &mut Criterion) {
    let mut r = Recorder::new(100_000);
    let id = r.register("x.position", "m").unwrap();
    let mut t = 0u64;
    c.bench_function("record/one signal", |b| {
        b.iter(|| {
            t += 1;
            r.record(black_box(id), Duration::from_micros(t), black_box(0.5)).unwrap();
        })
    });

    let mut r = Recorder::new(100_000);
    let id = r.register("x.position", "m").unwrap();
    r.arm(Trigger { signal: id, condition: Condition::Above(1e9), pre_samples: 1000, post_samples: 1000 })
        .unwrap();
    let mut t = 0u64;
    c.bench_function("record/one signal, armed trigger", |b| {
        b.iter(|| {
            t += 1;
            r.record(black_box(id), Duration::from_micros(t), black_box(0.5)).unwrap();
        })
    });

    let mut r = Recorder::new(10_000);
    let ids: Vec<_> = (0..32).map(|i| r.register(&format!("s{i}"), "").unwrap()).collect();
    let mut t = 0u64;
    c.bench_function("record/32 signals (one cycle)", |b| {
        b.iter(|| {
            t += 1;
            for (k, id) in ids.iter().enumerate() {
                r.record(*id, Duration::from_micros(t), k as f64).unwrap();
            }
        })
    });
}

criterion_group!(benches, bench_record);
criterion_main!(benches);
