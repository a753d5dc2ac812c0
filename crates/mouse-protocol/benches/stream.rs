//! Throughput of the streaming decoders on a realistic stream (converter packets with a
//! little garbage between them), reported in bytes/s.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use motus_mouse_protocol::{ConverterPacket, MicrosoftPacket, Packet, PacketScanner, Stream};

fn converter_bytes() -> Vec<u8> {
    let mut bytes = Vec::new();
    for i in 0..1000i16 {
        bytes.extend_from_slice(&ConverterPacket::motion(i % 300 - 150, 97 - i % 200).encode());
        if i % 10 == 0 {
            bytes.extend_from_slice(&[0x00, b'a', 0x13]);
        }
    }
    bytes
}

/// Decodes `bytes` in 64-byte chunks and sums the packets' `dx`.
fn sum_dx<P: Packet>(bytes: &[u8], dx: fn(&P) -> i64) -> i64 {
    let mut s = Stream::<PacketScanner<P>>::default();
    let mut sum = 0i64;
    for chunk in bytes.chunks(64) {
        s.push(black_box(chunk));
        while let Some(p) = s.next_frame() {
            sum += dx(&p);
        }
    }
    sum
}

fn streams(c: &mut Criterion) {
    let conv = converter_bytes();
    let mut g = c.benchmark_group("mouse_stream");
    g.throughput(Throughput::Bytes(conv.len() as u64));
    g.bench_function("converter", |b| b.iter(|| black_box(sum_dx(&conv, |p: &ConverterPacket| p.dx.into()))));
    let ms: Vec<u8> = (0..2000i32)
        .flat_map(|i| {
            MicrosoftPacket { left: i % 2 == 0, right: false, dx: (i % 100) as i8, dy: -3 }.encode()
        })
        .collect();
    g.throughput(Throughput::Bytes(ms.len() as u64));
    g.bench_function("microsoft", |b| b.iter(|| black_box(sum_dx(&ms, |p: &MicrosoftPacket| p.dx.into()))));
    g.finish();
}

criterion_group!(benches, streams);
criterion_main!(benches);
