//! The HMI in headless Chromium (tests/browser/test_hmi.py, Playwright) against the real
//! `motus demo`: the script starts the demo on a free port, reads the administrator password
//! it prints, and clicks every control of the HMI (login, group panels from the cell's own
//! group ids, home, jog with its dead-man, move, stop, robot map, pan-tilt target, arm joints,
//! program run/hold/resume/stop, E-stop, alarm ack, reset, juggler programs, audit, a student's
//! booking and commands, logout), checking each effect through the JSON API or on the page.
//! Screenshots and the demo's log go to target/screenshots/demo. Fails (does not skip) when
//! python3, Playwright or chromium is missing: CI installs them (scripts/install-oracles.sh).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::MOTUS;
use std::path::PathBuf;
use std::process::Command;

#[test]
fn hmi_on_the_real_demo_in_headless_chromium() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    // The release binary (scripts/test.sh builds it first): the whole cell in a debug build,
    // beside Chromium, loads a 2-core host enough to make the juggler late.
    // Beside the debug binary: <target>/debug/motus -> <target>/release/motus.
    let debug = PathBuf::from(MOTUS);
    let release =
        debug.parent().and_then(|d| d.parent()).map(|t| t.join("release/motus")).unwrap_or_default();
    let bin = if release.exists() {
        release
    } else {
        println!(
            "warning: {} missing (cargo build --release -p motus); using the debug build",
            release.display()
        );
        debug
    };
    println!("demo binary: {}", bin.display());
    let shots = root.join("target/screenshots/demo");
    let out = Command::new("python3")
        .arg(root.join("tests/browser/test_hmi.py"))
        .current_dir(&root)
        .env("MOTUS_BIN", &bin)
        .env_remove("MOTUS_HMI_URL")
        .env("MOTUS_SCREENSHOTS", &shots)
        .env("MOTUS_BROWSER_DEADLINE", "600")
        .output()
        .expect("python3 must be installed");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("{stdout}\n{stderr}");
    assert!(out.status.success(), "browser test on the demo failed:\n{stdout}\n{stderr}");
    // "N passed, 0 failed": every control of the HMI, none skipped.
    let summary = stdout.lines().rev().find(|l| l.contains(" passed, ")).unwrap_or_default();
    let passed: usize = summary.split(' ').next().and_then(|n| n.parse().ok()).unwrap_or(0);
    assert!(passed > 0 && summary.trim_end().ends_with(" passed, 0 failed"), "{stdout}");
}
