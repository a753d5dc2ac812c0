//! `motus` with the KV-01 arm: codec commands, and a simulator process on a real pty
//! driven by `motus kv01` (a session, then a one-shot command that finds "TO" latched).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::{SimProcess, MOTUS};
use std::io::Write;
use std::process::{Command, Output, Stdio};

fn motus(args: &[&str]) -> Output {
    Command::new(MOTUS).args(args).output().unwrap()
}

#[test]
fn decode_encode_and_the_sources_examples() {
    let o = motus(&["decode", "kv01", "E2 07 D0 45 4E FB F0"]);
    assert!(o.status.success());
    let json = String::from_utf8(o.stdout).unwrap();
    assert_eq!(json.trim(), r#"{"direction":"to_module","address":226,"command":"d0","text":"EN"}"#);
    let o = motus(&["encode", "kv01", json.trim()]);
    assert_eq!(String::from_utf8(o.stdout).unwrap().trim(), "E2 07 D0 45 4E FB F0");
    // The source's own example fails the published CRC: strict rejects, lenient warns.
    let o = motus(&["decode", "kv01", "E2 07 D0 45 4E 20 F0"]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8(o.stderr).unwrap();
    assert!(
        err.contains("expected 0xfb, received 0x20") || err.contains("expected 0xFB, received 0x20"),
        "{err}"
    );
    let o = motus(&["decode", "kv01", "E2 06 D1 08 E0 F0", "--crc", "lenient"]);
    assert!(o.status.success());
    assert!(String::from_utf8(o.stderr).unwrap().contains("CRC mismatch accepted"));
    // The host never builds a message with 0xF0 in its data.
    let o = motus(&[
        "encode",
        "kv01",
        r#"{"direction":"to_module","address":226,"command":"d0","text":"V\u00f0"}"#,
    ]);
    assert_eq!(o.status.code(), Some(1));
}

#[test]
fn session_moves_a_joint_and_a_later_command_reports_the_latched_time_out() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("arm");
    let port = link.to_str().unwrap();
    // The modules' safety time-out at 3 s instead of the arm's 700 ms: the session below must
    // not latch it when a loaded host stalls the processes (a liveness margin; the latch
    // itself is what the end of the test checks).
    let (_sim, sim_log) = SimProcess::start_logged(
        &["sim", "kv01", "--link", &format!("pty:{port}"), "--arm", r#"{"cm":{"safety_timeout_ms":3000}}"#],
        "simulating the KV-01 arm",
    );
    let mut session = Command::new(MOTUS)
        .args(["kv01", port, "session", "--json"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    {
        let stdin = session.stdin.as_mut().unwrap();
        writeln!(stdin, "brake 2 off").unwrap();
        writeln!(stdin, "enable 2").unwrap();
        writeln!(stdin, "move 2=25").unwrap();
        writeln!(stdin, "voltages 2").unwrap();
        writeln!(stdin, "wave 2").unwrap();
        writeln!(stdin, "wave 2").unwrap();
    }
    let out = session.wait_with_output().unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    // Failed commands are named, a repeated error is one short line, and the exit status
    // says the session did not do everything it was asked.
    assert!(lines[4].contains("`wave 2`") && lines[4].contains("unrecognized subcommand"), "{text}");
    assert_eq!(lines[5], "error: `wave 2`: the same error as before", "{text}");
    assert_eq!(out.status.code(), Some(1), "{text}");
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(stderr.contains("3 of 6 session commands failed"), "{stderr}");
    assert!(lines[0].contains("refusing to release the brake before the drive is enabled"), "{text}");
    assert!(lines[1].contains("enabled, brake released"), "{text}");
    let joints: serde_json::Value = serde_json::from_str(lines[2]).unwrap();
    let a = joints[1]["angle_deg"].as_f64().unwrap();
    assert!((a - 25.0).abs() <= 0.1, "{a}");
    assert!(lines[3].contains("volts_24v"), "{text}");
    // The session ended: 3 s later every module latches "TO". Waited for in the simulator's
    // log, not by asking: any request meanwhile would renew the modules' communication and
    // prevent the latch (a fixed sleep was too short beside CPU hogs, where the simulator's
    // steps fall behind; the latch's timing is tested on virtual time in motus-kv01's tests).
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    let mut latched = 0;
    while latched < 6 {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        let line = sim_log.recv_timeout(left).expect("every module latches its time-out");
        if line.contains("safety time-out: drive disabled, brake engaged") {
            latched += 1;
        }
    }
    let o = motus(&["kv01", port, "joints"]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8(o.stderr).unwrap();
    assert!(
        err.contains("700 ms safety communication time-out tripped") && err.contains("power-cycle"),
        "{err}"
    );
}
