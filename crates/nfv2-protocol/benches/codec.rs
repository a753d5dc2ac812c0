//! Encode / decode of a typical packed pan-tilt exchange: a position set-point plus
//! position and status queries, and the slave's answer; plus the stream decoder on both.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use motus_nfv2_protocol::{
    decode_frame, Command, CommandCode as C, Frame, FrameBuilder, FrameScanner, Revision, StreamDecoder,
};

fn request() -> Frame {
    let mut b = FrameBuilder::new(1, Revision::LATEST);
    b.set(C::SetDrivesPosition, &[-5000])
        .and_then(|b| b.query(C::ReadDrivesPosition))
        .and_then(|b| b.query(C::ReadDrivesStatus))
        .unwrap();
    b.build()
}

fn reply() -> Frame {
    Frame {
        address: 1,
        commands: vec![
            Command::values(C::ReadDrivesPosition, [-4990]),
            Command::values(C::ReadDrivesStatus, [0x0010]),
        ],
    }
}

fn bench(c: &mut Criterion) {
    let rev = Revision::LATEST;
    let mut group = c.benchmark_group("nfv2");
    group.throughput(Throughput::Elements(1));
    for (name, frame) in [("request", request()), ("answer", reply())] {
        let bytes = frame.encode(rev).unwrap();
        let mut buf = [0u8; 256];
        group.bench_function(format!("encode_into/{name}"), |b| {
            b.iter(|| black_box(&frame).encode_into(black_box(&mut buf), rev).unwrap());
        });
        group.bench_function(format!("encode_vec/{name}"), |b| {
            b.iter(|| black_box(&frame).encode(rev).unwrap());
        });
        group.bench_function(format!("decode/{name}"), |b| {
            b.iter(|| decode_frame(black_box(&bytes), rev).unwrap());
        });
        let mut stream = StreamDecoder::new(FrameScanner::new(rev));
        group.bench_function(format!("stream/{name}"), |b| {
            b.iter(|| {
                stream.push(black_box(&bytes));
                stream.next_frame()
            });
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
