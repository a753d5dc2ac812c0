//! Interpretation speed on a generated 100,000-line program (lines per second).
#![allow(missing_docs, clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use criterion::{criterion_group, criterion_main, Criterion, Throughput};

/// The benchmark program: a mix of G1/G2/G3, parameters and expressions (deterministic).
pub fn program(lines: usize) -> String {
    let mut s = String::from("G21 G90 G17 F1000\n#1=0\n");
    let mut k = 0;
    while k + 3 < lines {
        match k % 4 {
            0 => s.push_str("G1 X0 Y0 Z[-[#1 MOD 5] * 0.01]\n"),
            1 => s.push_str("G2 X2 Y0 I1 J0\n"),
            2 => s.push_str("G3 X4 Y0 R1\n"),
            _ => s.push_str("#1=[#1 + 1.5] G1 X[4 + SIN[#1]] Y[COS[#1] * 2]\n"),
        }
        k += 1;
    }
    s.push_str("M2\n");
    s
}

fn bench(c: &mut Criterion) {
    let src = program(100_000);
    let n = src.lines().count() as u64;
    let mut g = c.benchmark_group("interpret");
    g.throughput(Throughput::Elements(n));
    g.sample_size(10);
    g.bench_function("100k_lines", |b| {
        b.iter(|| {
            let calls = motus_gcode::interpret(&src).unwrap();
            assert!(calls.len() > 1000);
        })
    });
    g.finish();
    // Also print a plain lines/s figure (one full pass, after criterion's warm-up).
    let t = std::time::Instant::now();
    let calls = motus_gcode::interpret(&src).unwrap();
    let dt = t.elapsed().as_secs_f64();
    println!("interpret: {n} lines, {} calls in {dt:.3} s = {:.0} lines/s", calls.len(), n as f64 / dt);
    if let Ok(path) = std::env::var("MOTUS_GCODE_BENCH_FILE") {
        std::fs::write(path, &src).unwrap();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
