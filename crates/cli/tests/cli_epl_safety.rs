//! `motus decode/encode epl` and `motus safety check`, through the binary.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::MOTUS;
use std::process::{Command, Output};

fn motus(args: &[&str]) -> Output {
    Command::new(MOTUS).args(args).output().unwrap()
}

fn root() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

#[test]
fn epl_decode_encode_round_trip_and_errors() {
    // SoC: SoC multicast MAC, source MAC, EtherType 0x88AB, type 1, dst 255, src 240,
    // reserved, flags 0x80 (MC), reserved, NetTime (8 bytes), RelativeTime (8 bytes):
    // 36 bytes, unpadded as on a veth (specs/powerlink.md 1).
    let soc = "01111E000001020000000001 88AB 01 FF F0 00 80 00 0000000000000000 0000000000000000";
    let o = motus(&["decode", "epl", soc]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json = String::from_utf8_lossy(&o.stdout).trim().to_string();
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["message"]["type"], "soc");
    assert_eq!((v["src_node"].as_u64(), v["dst_node"].as_u64()), (Some(240), Some(255)));
    let back = motus(&["encode", "epl", &json]);
    let hex: String = String::from_utf8_lossy(&back.stdout).split_whitespace().collect();
    assert_eq!(hex, soc.replace(' ', ""));
    let o = motus(&["decode", "epl", "01111E000001020000000001 0800 01"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("invalid POWERLINK frame"));
}

#[test]
fn safety_check_names_the_first_failing_rule_of_the_example_trace() {
    let r = root();
    let rules = r.join("crates/safety/examples/juggler.toml");
    let trace = r.join("crates/safety/examples/juggler-stop.csv");
    let o =
        motus(&["safety", "check", "--rules", rules.to_str().unwrap(), "--trace", trace.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    let first_stop = out.lines().skip(1).find(|l| l.split(',').nth(1) == Some("0")).expect("the trace stops");
    assert!(first_stop.starts_with("0.0036,") && first_stop.contains("arms_pass"), "{first_stop}");
    // A bad rules file is refused naming the problem.
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "[[axis]]\nname = 'x'\n").unwrap();
    let o = motus(&["safety", "check", "--rules", bad.to_str().unwrap(), "--trace", trace.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("invalid rules file"));
}
