//! socketcand codec: format and parse one frame message.
#![allow(missing_docs, clippy::unwrap_used)]

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use motus_can::socketcand::{Message, StreamParser};
use motus_can::CanFrame;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let frame = CanFrame::new(0x181, &[0x37, 0x06, 0x00, 0x00, 0x10, 0x27, 0x00, 0x00]).unwrap();
    let msg = Message::Frame { frame: frame.clone(), timestamp: Duration::new(1_700_000_000, 123_456_000) };
    let mut g = c.benchmark_group("socketcand");
    g.throughput(Throughput::Elements(1));
    g.bench_function("format_frame", |b| {
        let mut s = String::with_capacity(64);
        b.iter(|| {
            s.clear();
            black_box(&msg).format_into(&mut s);
            black_box(s.len())
        })
    });
    let text = msg.format();
    g.bench_function("parse_frame", |b| {
        let mut p = StreamParser::new();
        b.iter(|| {
            p.push(black_box(text.as_bytes()));
            black_box(p.next())
        })
    });
    let send = Message::Send(frame).format();
    g.bench_function("parse_send", |b| {
        let mut p = StreamParser::new();
        b.iter(|| {
            p.push(black_box(send.as_bytes()));
            black_box(p.next())
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
