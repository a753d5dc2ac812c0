//! SocketCAN on `vcan0`: works where the kernel has SocketCAN and the interface is up;
//! elsewhere (our CI machines have no AF_CAN) the error must be a clear `Unavailable`
//! naming the interface.
#![cfg(target_os = "linux")]
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_can::socketcan::SocketCanBus;
use motus_can::{open_bus, CanBus, CanError, CanFrame};
use std::time::Duration;

#[test]
fn vcan0_works_or_fails_clearly() {
    match SocketCanBus::open("vcan0") {
        Ok(a) => {
            // A real kernel: a second socket on the same interface sees our frame.
            let b = open_bus("socketcan://vcan0").unwrap();
            let f = CanFrame::new(0x605, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap();
            a.send(&f).unwrap();
            assert_eq!(b.recv(Duration::from_secs(1)).unwrap().unwrap().frame, f);
            assert!(a.recv(Duration::from_millis(50)).unwrap().is_none(), "no own echo");
        }
        Err(CanError::Unavailable { what, reason }) => {
            assert_eq!(what, "SocketCAN interface \"vcan0\"");
            assert!(!reason.is_empty());
            let msg = CanError::Unavailable { what, reason }.to_string();
            assert!(msg.contains("vcan0") && msg.contains("unavailable"), "{msg}");
        }
        Err(other) => panic!("unexpected error kind: {other:?}"),
    }
}

#[test]
fn missing_interface_is_named() {
    let err = open_bus("socketcan://nosuchcan7").err().expect("no such interface");
    let msg = err.to_string();
    assert!(msg.contains("nosuchcan7"), "{msg}");
}
