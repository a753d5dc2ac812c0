//! Per-cycle evaluation of the juggler rule set (target: below 5 us).
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use motus_safety::{CycleInput, Mode, RuleSet, Sample, Supervisor, JUGGLER_TOML};
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let rules = RuleSet::from_toml(JUGGLER_TOML).expect("juggler rules");
    let mut sup = Supervisor::new(rules);
    let safe = [-500.0, 1000.0, -500.0, 10_000.0, -7100.0];
    let mut samples: Vec<Option<Sample>> =
        safe.iter().map(|p| Some(Sample { position: *p, speed: 1000.0, cycle: 0, homed: true })).collect();
    let mut cycle = 0u64;
    c.bench_function("juggler_cycle_safe", |b| {
        b.iter(|| {
            cycle += 1;
            for s in samples.iter_mut().flatten() {
                s.cycle = cycle;
            }
            let d = sup.evaluate(black_box(&CycleInput {
                now: Duration::from_micros(400 * cycle),
                cycle,
                mode: Mode::Normal,
                samples: &samples,
                params_ok: true,
            }));
            black_box(d.safe_to_run())
        })
    });
    // Worst case: the last rule fails and a diagnosis is built.
    let stop: Vec<Option<Sample>> = [-500.0, 1000.0, 950.0, 5500.0, -7100.0]
        .iter()
        .map(|p| Some(Sample { position: *p, speed: 0.0, cycle: 1, homed: true }))
        .collect();
    c.bench_function("juggler_cycle_stop_with_diagnosis", |b| {
        b.iter(|| {
            let d = sup.evaluate(black_box(&CycleInput {
                now: Duration::from_micros(400),
                cycle: 1,
                mode: Mode::Normal,
                samples: &stop,
                params_ok: true,
            }));
            black_box(d.safe_to_run())
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
