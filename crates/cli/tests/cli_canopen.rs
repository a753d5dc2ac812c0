//! `motus decode canopen` / `motus encode canopen` and the CANopen commands, through the binary.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::MOTUS;
use std::process::{Command, Output};

fn motus(args: &[&str]) -> Output {
    Command::new(MOTUS).args(args).output().unwrap()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).trim().to_string()
}

#[test]
fn decode_names_service_node_and_content_and_encode_inverts_it() {
    // 0x5C3 = 0x580 + 67: SDO response of node 67. 43 = expedited upload, 4 bytes;
    // 64 60 00 = 0x6064 sub 0; E8 03 00 00 = 1000 little-endian.
    let o = motus(&["decode", "canopen", "5C3#43646000E8030000"]);
    assert!(o.status.success());
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["text"], "SDO upload response 0x6064:00 = 1000 (node 67)");
    // The seed's synchronous RPDO2 to node 2: controlword 0x005F, target 0x0855 = 2133.
    let o = motus(&["decode", "canopen", "302#5F00550800000"]);
    assert!(!o.status.success(), "odd number of hex digits must be refused");
    let cases = [
        ("000#0102", "NMT start (node 2)"),
        ("080#", "SYNC"),
        ("702#05", "heartbeat operational (node 2)"),
        ("302#5F0055080000", "RPDO2 [5F 00 55 08 00 00] (node 2)"),
    ];
    for (frame, text) in cases {
        let o = motus(&["decode", "canopen", frame]);
        assert!(o.status.success(), "{frame}: {}", String::from_utf8_lossy(&o.stderr));
        let json = stdout(&o);
        let v: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert_eq!(v["text"], text, "{frame}");
        let back = motus(&["encode", "canopen", &json]);
        assert!(back.status.success());
        assert_eq!(stdout(&back), frame);
    }
    let o = motus(&["decode", "canopen", "zz#00"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("invalid CAN frame"));
}
