//! `motus decode|encode nfv2` and `motus sim nfv2` end to end.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::{SimProcess, MOTUS};
use std::process::{Command, Output};

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

/// Reply margin of the commands on the simulator's pty: a liveness time-out, generous enough
/// for processes stalled by a loaded host (the 20 ms default is for real lines). The head
/// commands also wait 5 s of silence (not 500 ms) before a communication fault.
const MARGIN_MS: &str = "1000";

/// `motus pantilt --margin-ms 1000 --silence-ms 5000 <port> <args>`.
fn pantilt(port: &str, args: &[&str]) -> Output {
    let mut all = vec!["pantilt", "--margin-ms", MARGIN_MS, "--silence-ms", "5000", port];
    all.extend_from_slice(args);
    motus(&all)
}

#[test]
fn pantilt_home_goto_track_where_and_raw_frames() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("line");
    let port = link.to_str().unwrap();
    let _sim = SimProcess::start(
        &["sim", "nfv2", "--link", &format!("pty:{port}"), "--addr", "1,2", "--baud-pacing"],
        "simulating 1209A controllers",
    );
    let o = pantilt(port, &["goto", "30", "-10"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not homed"));
    let o = pantilt(port, &["home"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = pantilt(port, &["goto", "30", "-10", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(
        (v["pan_deg"].as_f64().unwrap() - 30.0).abs() < 0.05
            && (v["tilt_deg"].as_f64().unwrap() + 10.0).abs() < 0.05
    );
    let track = dir.path().join("track.txt");
    std::fs::write(&track, "# t pan tilt\n0 30 -10\n1 35 -5\n2 20 -5\n").unwrap();
    let o = pantilt(port, &["track", track.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!((v["pan_deg"].as_f64().unwrap() - 20.0).abs() < 0.05, "{v}");
    // The head stands at the track's end: "where" answers there (held-up samples of an
    // axis standing still are used, whatever the load on the host).
    // On a loaded host the head may still settle when the track returns, and "where" refuses
    // samples held up while it moved: asked again (a liveness bound of 10 tries), it answers.
    let mut o = pantilt(port, &["where", "0.1", "--json"]);
    for _ in 0..10 {
        if o.status.success() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(300));
        o = pantilt(port, &["where", "0.1", "--json"]);
    }
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(
        (v["pan_deg"].as_f64().unwrap() - 20.0).abs() < 0.05
            && (v["tilt_deg"].as_f64().unwrap() + 5.0).abs() < 0.05,
        "{v}"
    );
    let o = motus(&[
        "nfv2",
        "--margin-ms",
        MARGIN_MS,
        port,
        "raw",
        r#"{"address":2,"commands":[{"kind":"query","code":"read_drives_position"}]}"#,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["address"], 2);
    let o = motus(&["axis", &format!("nfv2://{port}?addr=1&margin_ms={MARGIN_MS}"), "status", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
