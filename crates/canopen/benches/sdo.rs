//! SDO benchmarks: sans-IO client throughput, and expedited round trips of the threaded
//! master against a scripted responder over MemoryHub and over the socketcand hub on
//! loopback TCP. After criterion, each round trip is timed in a loop for a second and printed
//! as a `REALTIME sdo.roundtrip.<hub> <us> us` line for `scripts/realtime.sh`.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

#[path = "../tests/common/mod.rs"]
mod common;

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use motus_can::socketcand::{Hub, HubConfig, SocketcandBus};
use motus_can::{CanBus, CanFrame, MemoryHub};
use motus_canopen::sdo_client::{SdoStep, SdoTransfer};
use motus_canopen::Master;

fn sans_io(c: &mut Criterion) {
    let mut g = c.benchmark_group("sdo_sans_io");
    g.throughput(Throughput::Elements(1));
    let now = Instant::now();
    // 585#4B41600037020000: expedited upload response, 2 bytes.
    let resp: CanFrame = "585#4B41600037020000".parse().unwrap();
    g.bench_function("expedited_upload", |b| {
        b.iter(|| {
            let (mut t, f) = SdoTransfer::upload(5, 0x6041, 0, now, Duration::from_millis(500)).unwrap();
            std::hint::black_box(f);
            match t.on_frame(&resp, now) {
                SdoStep::Done(d) => d,
                other => panic!("{other:?}"),
            }
        })
    });
    let objects: common::Objects = Arc::new(Mutex::new(HashMap::new()));
    objects.lock().unwrap().insert((0x2000, 0), vec![0xA5; 100]);
    let mut server = common::SdoServer::new(objects);
    g.throughput(Throughput::Bytes(100));
    g.bench_function("segmented_upload_100B_with_scripted_server", |b| {
        b.iter(|| {
            let (mut t, mut req) =
                SdoTransfer::upload(5, 0x2000, 0, now, Duration::from_millis(500)).unwrap();
            loop {
                let resp = server.handle(&req.data().try_into().unwrap()).unwrap();
                match t.on_frame(&CanFrame::new(0x585, &resp).unwrap(), now) {
                    SdoStep::Send(f) => req = f,
                    SdoStep::Done(d) => break d,
                    other => panic!("{other:?}"),
                }
            }
        })
    });
    g.finish();
}

fn round_trips(
    c: &mut Criterion,
    name: &str,
    key: &str,
    master_bus: Arc<dyn CanBus>,
    node_bus: Arc<dyn CanBus>,
) {
    let _node = common::spawn_node(node_bus, 5, None);
    let m = Master::new(master_bus);
    // Let the socketcand handshake settle and the boot-up pass.
    std::thread::sleep(Duration::from_millis(200));
    let mut g = c.benchmark_group("sdo_round_trip");
    g.throughput(Throughput::Elements(1));
    g.sample_size(20).measurement_time(Duration::from_secs(3));
    g.bench_function(name, |b| b.iter(|| m.read_u16(5, 0x6041, 0).unwrap()));
    g.finish();
    let t0 = Instant::now();
    let mut n = 0u64;
    while t0.elapsed() < Duration::from_secs(1) {
        m.read_u16(5, 0x6041, 0).unwrap();
        n += 1;
    }
    let us = t0.elapsed().as_secs_f64() * 1e6 / n.max(1) as f64;
    println!("{name}: {n} round trips in 1 s, {us:.1} us each");
    println!("REALTIME sdo.roundtrip.{key} {us:.1} us");
}

fn memory(c: &mut Criterion) {
    let hub = MemoryHub::new();
    round_trips(c, "memory_hub_expedited_upload", "memory", Arc::new(hub.connect()), Arc::new(hub.connect()));
}

fn socketcand(c: &mut Criterion) {
    let hub = Hub::start(HubConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        bitrate: None,
        channel: "can0".into(),
    })
    .unwrap();
    let a = SocketcandBus::connect(hub.local_addr(), "can0").unwrap();
    let b = SocketcandBus::connect(hub.local_addr(), "can0").unwrap();
    round_trips(c, "socketcand_loopback_expedited_upload", "socketcand", Arc::new(a), Arc::new(b));
}

criterion_group!(benches, sans_io, memory, socketcand);
criterion_main!(benches);
