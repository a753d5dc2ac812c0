//! Hub round trip over loopback: client A -> hub -> client B -> hub -> client A.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use motus_can::socketcand::{Hub, HubConfig, SocketcandBus, SETTLE};
use motus_can::{CanBus, CanFrame};
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let hub = Hub::start(HubConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        bitrate: None,
        channel: "can0".into(),
    })
    .unwrap();
    let a = SocketcandBus::connect(hub.local_addr(), "can0").unwrap();
    let b = std::sync::Arc::new(SocketcandBus::connect(hub.local_addr(), "can0").unwrap());
    std::thread::sleep(SETTLE * 2);
    // B echoes every frame with id + 1 until it sees id 0x7FF.
    let echo = {
        let b = b.clone();
        std::thread::spawn(move || loop {
            let Ok(Some(r)) = b.recv(Duration::from_secs(5)) else { return };
            if r.frame.id() == 0x7FF {
                return;
            }
            let reply = CanFrame::new(r.frame.id() + 1, r.frame.data()).unwrap();
            b.send(&reply).unwrap();
        })
    };
    let request = CanFrame::new(0x605, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap();
    let mut g = c.benchmark_group("hub");
    g.throughput(Throughput::Elements(1));
    g.bench_function("round_trip", |bench| {
        bench.iter(|| {
            a.send(&request).unwrap();
            a.recv(Duration::from_secs(5)).unwrap().expect("echo")
        })
    });
    g.finish();
    a.send(&CanFrame::new(0x7FF, &[]).unwrap()).unwrap();
    echo.join().unwrap();
}

criterion_group!(benches, bench);
criterion_main!(benches);
