//! Kinematics (inverse + forward) and fusion updates per second.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use motus_mouse_protocol::Calibration;
use motus_omni::{Fusion, Geometry, Motion, Pose, SlipTolerance};

fn bench(c: &mut Criterion) {
    let g = Geometry::default();
    let mut grp = c.benchmark_group("omni");
    grp.throughput(Throughput::Elements(1));
    grp.bench_function("inverse_forward", |b| {
        let mut m = Motion::new(0.1, -0.05, 0.01);
        b.iter(|| {
            let s = g.inverse(black_box(m));
            m = g.forward(s);
            black_box(m)
        })
    });
    grp.bench_function("fusion_update", |b| {
        let mut f = Fusion::new(g, Calibration::default(), SlipTolerance::default(), Pose::default());
        let mut pos = [0i32; 3];
        f.update(pos, None);
        let mut k = 0i32;
        b.iter(|| {
            // 10 ms at 248 Inc/s on wheel 1: ~2.5 Inc per cycle; the sensor sees 3.75 counts.
            k = k.wrapping_add(1);
            pos[0] = pos[0].wrapping_add(3);
            pos[1] = pos[1].wrapping_sub(1 + (k & 1));
            pos[2] = pos[2].wrapping_sub(2 - (k & 1));
            black_box(f.update(black_box(pos), Some((4, 0))))
        })
    });
    grp.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
