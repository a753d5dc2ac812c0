//! Encode/decode throughput of the two hot messages of a KV-01 control loop: the D2 fast
//! message (speed command) and the D3-format resolver reply. Reported in frames/s.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use motus_kv01_protocol::{
    decode_message, Address, Command, CrcMode, Direction, JointStatus, Message, MessageScanner, ReplyBody,
    ResolverReading, StreamDecoder,
};

fn messages() -> (Message, Message) {
    let a = Address::joint(3).unwrap();
    let d2 = Message::request(a, Command::Fast { text: "V-1250".into() });
    let d3 = Message::reply(
        a,
        ReplyBody::Resolver(ResolverReading {
            position: 0x92B4,
            status: JointStatus { brake_released: true, ..JointStatus::default() },
        }),
    );
    (d2, d3)
}

fn codec(c: &mut Criterion) {
    let (d2, d3) = messages();
    let d2_bytes = d2.encode().unwrap();
    let d3_bytes = d3.encode().unwrap();
    let mut g = c.benchmark_group("kv01");
    g.throughput(Throughput::Elements(1));
    let mut buf = [0u8; 255];
    g.bench_function("encode_into_d2", |b| b.iter(|| black_box(&d2).encode_into(&mut buf).unwrap()));
    g.bench_function("encode_into_d3_reply", |b| b.iter(|| black_box(&d3).encode_into(&mut buf).unwrap()));
    g.bench_function("decode_d2", |b| {
        b.iter(|| decode_message(black_box(&d2_bytes), Direction::ToModule, CrcMode::Strict).unwrap())
    });
    g.bench_function("decode_d3_reply", |b| {
        b.iter(|| decode_message(black_box(&d3_bytes), Direction::FromModule, CrcMode::Strict).unwrap())
    });
    let mut stream = StreamDecoder::new(MessageScanner::replies(CrcMode::Strict));
    g.bench_function("stream_d3_reply", |b| {
        b.iter(|| {
            stream.push(black_box(&d3_bytes));
            stream.next_frame().unwrap()
        })
    });
    g.finish();
}

criterion_group!(benches, codec);
criterion_main!(benches);
