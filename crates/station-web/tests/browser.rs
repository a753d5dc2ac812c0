//! Runs the Playwright browser test (tests/browser/test_hmi.py at the workspace root)
//! against the `fake_station` example. Fails (does not skip) when python3, Playwright or
//! /usr/bin/chromium is missing: CI installs them (see tests/browser/README.md).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::path::PathBuf;
use std::process::Command;

#[test]
fn hmi_in_headless_chromium() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let script = root.join("tests/browser/test_hmi.py");
    assert!(script.exists(), "{} missing", script.display());
    let mut cmd = Command::new("python3");
    cmd.arg(&script).current_dir(&root);
    // target/<profile>/deps/browser-* -> target/<profile>/examples/fake_station
    let exe = std::env::current_exe().unwrap();
    if let Some(profile_dir) = exe.parent().and_then(|d| d.parent()) {
        let fake = profile_dir.join("examples").join("fake_station");
        if fake.exists() && std::env::var_os("MOTUS_FAKE_STATION").is_none() {
            cmd.env("MOTUS_FAKE_STATION", fake);
        }
    }
    let out = cmd.output().expect("python3 must be installed");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("{stdout}\n{stderr}");
    assert!(out.status.success(), "browser test failed:\n{stdout}\n{stderr}");
    assert!(stdout.contains("6 passed, 0 failed"), "{stdout}");
}
