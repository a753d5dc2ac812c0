//! Interpretation speed on the generated 100,000-line program (lines per second):
//! `interpret` (all calls into a `Vec`) and the streaming `Interpreter` iterator.
//! `examples/vs_rs274.rs` compares the same program with LinuxCNC's `rs274`.
#![allow(missing_docs, clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

#[path = "common/program.rs"]
mod program;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};

fn bench(c: &mut Criterion) {
    let src = program::program(100_000);
    let n = src.lines().count() as u64;
    let mut g = c.benchmark_group("interpret");
    g.throughput(Throughput::Elements(n));
    g.sample_size(20);
    g.bench_function("100k_lines", |b| {
        b.iter(|| {
            let calls = motus_gcode::interpret(&src).unwrap();
            assert!(calls.len() > 1000);
        })
    });
    g.bench_function("100k_lines_streaming", |b| {
        b.iter(|| {
            let mut count = 0usize;
            for call in motus_gcode::Interpreter::new(&src) {
                call.unwrap();
                count += 1;
            }
            assert!(count > 1000);
        })
    });
    g.finish();
    // Also a plain lines/s figure (best of 5 full passes, after criterion's runs).
    let mut best = f64::MAX;
    let mut calls = 0;
    for _ in 0..5 {
        let t = std::time::Instant::now();
        calls = motus_gcode::interpret(&src).unwrap().len();
        best = best.min(t.elapsed().as_secs_f64());
    }
    println!("interpret: {n} lines, {calls} calls in {:.1} ms = {:.0} lines/s", best * 1e3, n as f64 / best);
    if let Ok(path) = std::env::var("MOTUS_GCODE_BENCH_FILE") {
        std::fs::write(path, &src).unwrap();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
