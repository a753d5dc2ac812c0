//! Decode + extract per PRes frame (the monitor's hot path), and encode.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use motus_epl_protocol::{EplFrame, Flags, MacAddr, Message, NmtState, PRes, PrRs, Sample, ValueMap};

fn pres_frame() -> Vec<u8> {
    // A 24-byte payload like the Acopos mapping: position at 16, speed at 20.
    let mut payload = vec![0u8; 16];
    payload.extend_from_slice(&123_456i32.to_le_bytes());
    payload.extend_from_slice(&(-789i32).to_le_bytes());
    let pres = PRes {
        nmt_state: NmtState::Operational,
        flags: Flags::RD,
        pr_rs: PrRs::default(),
        pdo_version: 0x10,
        payload,
        reserved: 0,
    };
    EplFrame::new(MacAddr([2, 0, 0, 0, 0, 1]), MacAddr::PRES, 255, 1, Message::PRes(pres)).encode().unwrap()
}

fn bench(c: &mut Criterion) {
    let bytes = pres_frame();
    let map = ValueMap::from_toml(include_str!("../examples/acopos-map.toml")).unwrap();
    c.bench_function("decode PRes", |b| b.iter(|| EplFrame::decode(black_box(&bytes)).unwrap()));
    let mut out: Vec<Sample<'_>> = Vec::with_capacity(4);
    c.bench_function("decode + extract PRes", |b| {
        b.iter(|| {
            let f = EplFrame::decode(black_box(&bytes)).unwrap();
            if let Message::PRes(p) = &f.message {
                map.extract_into(f.src_node, &p.payload, &mut out).unwrap();
            }
            black_box(out.len())
        })
    });
    let frame = EplFrame::decode(&bytes).unwrap();
    let mut buf = Vec::with_capacity(64);
    c.bench_function("encode PRes", |b| {
        b.iter(|| {
            buf.clear();
            black_box(&frame).encode_into(&mut buf).unwrap();
            black_box(buf.len())
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
