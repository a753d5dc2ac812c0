//! The `motus` binary end to end: codec commands, and a simulator process on a real pty
//! driven through `motus ps1a` and `motus axis`, including a SIGKILL mid-motion.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::{SimProcess, MOTUS};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Duration;

fn motus(args: &[&str], record: &Path) -> Output {
    Command::new(MOTUS).args(args).env("MOTUS_PS1A_PARAMS", record).output().unwrap()
}

fn ok(args: &[&str], record: &Path) -> String {
    let o = motus(args, record);
    assert!(o.status.success(), "motus {args:?} failed: {}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap()
}

fn fails(args: &[&str], record: &Path) -> String {
    let o = motus(args, record);
    assert_eq!(o.status.code(), Some(1), "motus {args:?} should fail");
    String::from_utf8(o.stderr).unwrap()
}

/// Reply margin of every command on the simulator's pty: a liveness time-out, generous enough
/// for processes stalled by a loaded host (300 ms once missed a module beside two CPU hogs and
/// three builds; the 20 ms default is for real lines).
const MARGIN_MS: &str = "1000";

/// `motus ps1a <port> params set` of module `addr` with maximum `max` and the tests'
/// reference speeds.
fn params_set(port: &str, addr: &str, max: &str, record: &Path) {
    let args = [
        "ps1a",
        port,
        "params",
        "set",
        "--addr",
        addr,
        "--max",
        max,
        "--vnrb",
        "200",
        "--vnnb",
        "20",
        "--margin-ms",
        MARGIN_MS,
    ];
    ok(&args, record);
}

fn start_sim(link: &Path, state: &Path, addrs: &str) -> SimProcess {
    let link = format!("pty:{}", link.display());
    let state = state.to_str().unwrap();
    SimProcess::start(
        &["sim", "ps1a", "--link", &link, "--addr", addrs, "--state-file", state],
        "simulating PS1A modules",
    )
}

#[test]
fn decode_encode_round_trip_and_errors() {
    let rec = PathBuf::from("/nonexistent");
    let json = ok(&["decode", "ps1a-cmd", "03 03 04 E8 03 00 F5"], &rec);
    assert_eq!(json.trim(), r#"{"addr":3,"command":"move_absolute","target":1000}"#);
    for hex in [
        "03 00 00 03",
        "01 03 05 18 FC FF 1C",
        "00 0B 01 00 27 00 00 FF FF 00 0A 08 05 08 50",
        "04 01 02 05 0C",
    ] {
        let json = ok(&["decode", "ps1a-cmd", hex], &rec);
        assert_eq!(ok(&["encode", "ps1a-cmd", json.trim()], &rec).trim(), hex);
    }
    let reply = "03 05 21 03 70 11 01 AE";
    let json = ok(&["decode", "ps1a-reply", reply], &rec);
    assert!(json.contains(r#""lbs_flags":["after_reset","in_motion"]"#), "{json}");
    assert_eq!(ok(&["encode", "ps1a-reply", json.trim()], &rec).trim(), reply);
    let err = fails(&["decode", "ps1a-cmd", "03 03 04 E8 03 00 F6"], &rec);
    assert!(err.contains("checksum error: expected 0xF5, received 0xF6"), "{err}");
    let err = fails(&["decode", "ps1a-cmd", "03 00 0B 0E"], &rec);
    assert!(err.contains("unknown command code 11"), "{err}");
    let err = fails(&["decode", "ps1a-reply", "03 05 21"], &rec);
    assert!(err.contains("too short"), "{err}");
    let err = fails(
        &["encode", "ps1a-cmd", r#"{"addr":3,"command":"set_speed","speed":10,"acceleration":11}"#],
        &rec,
    );
    assert!(err.contains("acceleration number 11"), "{err}");
}

#[test]
fn simulator_process_scan_params_home_move_and_limits() {
    let dir = tempfile::tempdir().unwrap();
    let (link, state, rec) =
        (dir.path().join("line"), dir.path().join("state.json"), dir.path().join("rec.json"));
    let _sim = start_sim(&link, &state, "2,5,11");
    let port = link.to_str().unwrap();
    // A scan asks each address once: on a loaded host a module the simulator process
    // answered late is missed, so the scan is asked again (a liveness bound of 3 scans).
    let mut found = Vec::new();
    for attempt in 1..=3 {
        let out = ok(&["ps1a", port, "scan", "--range", "0-11", "--margin-ms", MARGIN_MS, "--json"], &rec);
        found = serde_json::from_str::<serde_json::Value>(&out)
            .unwrap()
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m["addr"].as_u64().unwrap())
            .collect::<Vec<u64>>();
        if found == [2, 5, 11] {
            break;
        }
        eprintln!("scan {attempt} found {found:?}; scanning again");
    }
    assert_eq!(found, vec![2, 5, 11]);

    params_set(port, "5", "40000", &rec);
    let got = ok(&["ps1a", port, "params", "get", "--addr", "5", "--json"], &rec);
    assert!(got.contains(r#""max_position":40000"#), "{got}");

    let uri = format!("ps1a://{port}?addr=5&max=40000&speed=3000&margin_ms={MARGIN_MS}");
    let err = fails(&["axis", &uri, "move-abs", "1000"], &rec);
    assert!(err.contains("not homed"), "{err}");
    ok(&["axis", &uri, "enable"], &rec);
    let out = ok(&["axis", &uri, "home", "--wait", "--json"], &rec);
    let s: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(s["state"]["flags"]["homed"], true);
    let out = ok(&["axis", &uri, "move-abs", "25000", "--wait"], &rec);
    assert!(out.contains("position 25000 units"), "{out}");
    assert!(!out.contains('\r'), "no progress output when piped");
    let out = ok(&["axis", &uri, "move-rel", "-5000", "--wait", "--json"], &rec);
    assert!(out.contains(r#""position_raw":20000"#), "{out}");
    let out = ok(&["axis", &uri, "move-abs", "0.3", "--si", "--wait", "--velocity", "0.2"], &rec);
    assert!(out.contains("position 0.300000 m"), "{out}");
    let err = fails(&["axis", &uri, "move-abs", "40001"], &rec);
    assert!(err.contains("beyond the limit"), "{err}");
    let out = ok(&["axis", &uri, "jog", "+", "--wait"], &rec);
    assert!(out.contains("position 40000 units"), "jog stops at the maximum: {out}");
    let err = fails(&["axis", &format!("ps1a://{port}?addr=5&bogus=1"), "status"], &rec);
    assert!(err.contains("unknown parameter \"bogus\""), "{err}");
}

#[test]
fn killing_the_simulator_mid_motion_is_detected_and_motion_refused_until_homed() {
    let dir = tempfile::tempdir().unwrap();
    let (link, state, rec) =
        (dir.path().join("line"), dir.path().join("state.json"), dir.path().join("rec.json"));
    let sim = start_sim(&link, &state, "1");
    let port = link.to_str().unwrap();
    params_set(port, "1", "900000", &rec);
    let uri = format!("ps1a://{port}?addr=1&max=900000&speed=300&margin_ms={MARGIN_MS}");
    ok(&["axis", &uri, "enable"], &rec);
    ok(&["axis", &uri, "home", "--wait"], &rec);
    // A long move, waited on by another process.
    let waiter = Command::new(MOTUS)
        .args(["axis", &uri, "move-abs", "800000", "--wait", "--timeout", "30"])
        .env("MOTUS_PS1A_PARAMS", &rec)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(700));
    sim.kill();
    std::thread::sleep(Duration::from_millis(300));
    let _sim = start_sim(&link, &state, "1");
    let out = waiter.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "the waiting move must not report success");
    assert!(
        err.contains("reset") || err.contains("communication") || err.contains("no valid reply"),
        "{err}"
    );
    let status = ok(&["axis", &uri, "status", "--json"], &rec);
    let s: serde_json::Value = serde_json::from_str(&status).unwrap();
    assert_eq!(s["state"]["flags"]["homed"], false, "{status}");
    let err = fails(&["axis", &uri, "move-abs", "1000"], &rec);
    assert!(err.contains("not homed"), "{err}");
    ok(&["axis", &uri, "enable"], &rec);
    ok(&["axis", &uri, "home", "--wait"], &rec);
    let out = ok(&["axis", &uri, "move-abs", "1000", "--wait"], &rec);
    assert!(out.contains("position 1000 units"), "{out}");
}
