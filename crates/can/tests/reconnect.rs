//! A [`ReconnectingBus`] on a real socketcand hub on 127.0.0.1 that is stopped and started
//! again on the same port: the link comes back by itself; a plain client's link does not.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_can::socketcand::{Hub, HubConfig, SocketcandBus, SETTLE};
use motus_can::{CanBus, CanError, CanFrame, ReconnectPolicy, ReconnectingBus, WhileDown};
use std::net::SocketAddr;
use std::time::{Duration, Instant};

fn hub_at(listen: SocketAddr) -> Hub {
    Hub::start(HubConfig { listen, bitrate: None, channel: "can0".into() }).unwrap()
}

/// Receives until `want` arrives (other frames are skipped), within a generous time-out.
fn expect_frame(bus: &dyn CanBus, want: &CanFrame) {
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(10) {
        if let Some(r) = bus.recv(Duration::from_millis(100)).unwrap() {
            if &r.frame == want {
                return;
            }
        }
    }
    panic!("{want} not received on {}", bus.describe());
}

#[test]
fn the_link_comes_back_after_the_hub_restarts_on_the_same_port() {
    let mut hub = hub_at("127.0.0.1:0".parse().unwrap());
    let addr = hub.local_addr();
    let uri = hub.uri();
    let master = ReconnectingBus::open(&uri, ReconnectPolicy::default()).unwrap();
    let node =
        ReconnectingBus::open(&uri, ReconnectPolicy { while_down: WhileDown::Discard, ..Default::default() })
            .unwrap();
    let plain = SocketcandBus::connect(addr, "can0").unwrap();
    std::thread::sleep(SETTLE + Duration::from_millis(50));
    let f1 = CanFrame::new(0x701, &[0x05]).unwrap();
    master.send(&f1).unwrap();
    expect_frame(&node, &f1);
    assert_eq!(master.connections(), 1);

    hub.stop();
    // The plain client reports the closed connection as an error; the reconnecting buses
    // report nothing but time-outs, and their sends fail fast or are discarded.
    let t0 = Instant::now();
    loop {
        match plain.recv(Duration::from_millis(50)) {
            Err(CanError::Closed(_)) => break,
            other => assert!(t0.elapsed() < Duration::from_secs(10), "plain client: {other:?}"),
        }
    }
    let t0 = Instant::now();
    while master.is_up() || node.is_up() {
        assert!(master.recv(Duration::from_millis(50)).unwrap().is_none());
        assert!(node.recv(Duration::from_millis(50)).unwrap().is_none());
        assert!(t0.elapsed() < Duration::from_secs(10), "the loss was not noticed");
    }
    match master.send(&f1) {
        Err(CanError::Closed(reason)) => assert!(reason.contains("reconnecting"), "{reason}"),
        other => panic!("a send while down must fail: {other:?}"),
    }
    node.send(&f1).unwrap();
    // Down for a while: several attempts fail (connection refused), with back-off.
    let down_until = Instant::now() + Duration::from_millis(700);
    while Instant::now() < down_until {
        assert!(master.recv(Duration::from_millis(20)).unwrap().is_none());
        assert!(node.recv(Duration::from_millis(20)).unwrap().is_none());
    }

    let _hub = hub_at(addr);
    let restarted = Instant::now();
    while !(master.is_up() && node.is_up()) {
        let _ = master.recv(Duration::from_millis(20)).unwrap();
        let _ = node.recv(Duration::from_millis(20)).unwrap();
        // Liveness: the back-off (100 ms doubling to 2 s) retries within 2 s of the restart.
        assert!(restarted.elapsed() < Duration::from_secs(20), "not reconnected within 20 s");
    }
    eprintln!("reconnected {:?} after the hub restarted", restarted.elapsed());
    assert_eq!(master.connections(), 2);
    std::thread::sleep(SETTLE + Duration::from_millis(50));
    let f2 = CanFrame::new(0x705, &[0x7F]).unwrap();
    node.send(&f2).unwrap();
    expect_frame(&master, &f2);
    master.send(&f1).unwrap();
    expect_frame(&node, &f1);
}
