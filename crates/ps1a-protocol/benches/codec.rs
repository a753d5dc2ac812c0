//! Codec throughput: encode and decode of command frames and status replies.
#![allow(missing_docs, clippy::panic, clippy::unwrap_used)]

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use motus_ps1a_protocol::*;

fn codec(c: &mut Criterion) {
    let mut g = c.benchmark_group("ps1a_codec");
    g.throughput(Throughput::Elements(1));
    let cmd = CommandFrame::new(3, Command::MoveAbsolute { target: U24::new(123_456).unwrap() });
    let cmd_bytes = cmd.encode();
    let reply = StatusReply {
        addr: 3,
        low: LowStatus(0x20),
        high: HighStatus(3),
        position: U24::new(98_765).unwrap(),
    };
    let reply_bytes = reply.to_bytes();
    let mut buf = [0u8; MAX_COMMAND_LEN];
    g.bench_function("encode_move_absolute", |b| b.iter(|| black_box(&cmd).encode_into(black_box(&mut buf))));
    g.bench_function("decode_move_absolute", |b| b.iter(|| CommandFrame::decode(black_box(&cmd_bytes))));
    g.bench_function("encode_status_reply", |b| b.iter(|| black_box(&reply).to_bytes()));
    g.bench_function("decode_status_reply", |b| b.iter(|| StatusReply::decode(black_box(&reply_bytes))));
    g.finish();
}

criterion_group!(benches, codec);
criterion_main!(benches);
