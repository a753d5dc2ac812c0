//! `motus decode|encode nfv2` and `motus sim nfv2` end to end.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::process::{Command, Output};

const MOTUS: &str = env!("CARGO_BIN_EXE_motus");

fn motus(args: &[&str]) -> Output {
    Command::new(MOTUS).args(args).output().unwrap()
}

#[test]
fn nfv2_decode_encode_round_trip_and_errors() {
    // A packed pan-tilt frame: set position -5000, query position and status
    // (CRC-8 poly 0xD8 over address..last byte = 0xF0, from the codec's reference vectors).
    let hex = "23 0E F1 01 13 04 78 EC FF FF 1A 00 1F 00 F0";
    let o = motus(&["decode", "nfv2", hex]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json = String::from_utf8(o.stdout).unwrap();
    assert!(json.contains(r#""code":"set_drives_position","values":[-5000]"#), "{json}");
    let o = motus(&["encode", "nfv2", json.trim()]);
    assert_eq!(String::from_utf8(o.stdout).unwrap().trim(), hex);
    let o = motus(&["decode", "nfv2", "23 0E F1 01 13 04 78 EC FF FF 1A 00 1F 00 F1"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8(o.stderr).unwrap().contains("CRC"));
    let o = motus(&["decode", "nfv2", hex, "--revision", "1999"]);
    assert_eq!(o.status.code(), Some(1));
}
