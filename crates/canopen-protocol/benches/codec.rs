//! Criterion benchmarks for the hot paths: candump parse, decode and encode.
#![allow(missing_docs, clippy::unwrap_used)]

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use motus_canopen_protocol::{CanFrame, CanOpenMessage};

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("canopen");
    g.throughput(Throughput::Elements(1));
    let sdo: CanFrame = "583#43646000E8030000".parse().unwrap();
    let pdo: CanFrame = "183#2706E8030000".parse().unwrap();
    let msg = CanOpenMessage::decode(&sdo);
    g.bench_function("parse_candump", |b| b.iter(|| black_box("583#43646000E8030000").parse::<CanFrame>()));
    g.bench_function("decode_sdo", |b| b.iter(|| CanOpenMessage::decode(black_box(&sdo))));
    g.bench_function("decode_pdo", |b| b.iter(|| CanOpenMessage::decode(black_box(&pdo))));
    g.bench_function("encode_sdo", |b| b.iter(|| black_box(&msg).encode()));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
