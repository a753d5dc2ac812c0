//! The HMI in headless Chromium (tests/browser/test_hmi.py, Playwright) against the real
//! `motus demo`: log in, book a slot, jog an axis and see its position change, run a G-code
//! program and see its progress, E-stop and see every axis stop, load the juggler program
//! that aims the thrower beyond its limit and see the supervisor stop it with its diagnosis
//! (then load the juggling program and reset). Screenshots go to
//! target/screenshots/demo. Fails (does not skip) when python3, Playwright or chromium is
//! missing: CI installs them (scripts/install-oracles.sh).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::{http, MOTUS};
use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

struct Demo(Child);
impl Drop for Demo {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn hmi_on_the_real_demo_in_headless_chromium() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let addr = format!("127.0.0.1:{port}");
    // The release binary when it is built (scripts/test.sh builds it): the whole cell in a
    // debug build, beside Chromium, loads a 2-core host enough to make the juggler late.
    // Beside the debug binary: <target>/debug/motus -> <target>/release/motus.
    let debug = PathBuf::from(MOTUS);
    let release =
        debug.parent().and_then(|d| d.parent()).map(|t| t.join("release/motus")).unwrap_or_default();
    let bin = if release.exists() { release } else { debug };
    println!("demo binary: {}", bin.display());
    let mut child = Command::new(&bin)
        .args(["demo", "--listen", &addr])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let out = child.stdout.take().unwrap();
    let _demo = Demo(child);
    let mut lines = BufReader::new(out).lines();
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut password = None;
    while password.is_none() && Instant::now() < deadline {
        let l = lines.next().expect("demo exited").unwrap();
        password = l.strip_prefix("administrator login: user admin, password ").map(|p| p.trim().to_owned());
    }
    let password = password.unwrap();
    std::thread::spawn(move || for _ in lines {});
    // Home the axes the browser moves (the HMI's own home buttons are tested by hand).
    let (st, head, body) = http(
        &addr,
        "POST",
        "/api/login",
        &[("Content-Type", "application/json")],
        &format!("{{\"user\":\"admin\",\"password\":\"{password}\"}}"),
    );
    assert_eq!(st, 200, "{body}");
    let cookie = head
        .lines()
        .find_map(|l| l.strip_prefix("set-cookie: ").or_else(|| l.strip_prefix("Set-Cookie: ")))
        .unwrap();
    let cookie = cookie.split(';').next().unwrap().to_owned();
    let v: serde_json::Value = serde_json::from_str(&body).unwrap();
    let csrf = v["csrf_token"].as_str().unwrap().to_owned();
    let auth = [("Cookie", cookie.as_str()), ("X-CSRF-Token", csrf.as_str())];
    for axis in ["x", "y", "linear2"] {
        let (st, _, b) = http(&addr, "POST", &format!("/api/axes/{axis}/home"), &auth, "");
        assert_eq!(st, 200, "{axis}: {b}");
    }
    std::thread::sleep(Duration::from_secs(3));
    let shots = root.join("target/screenshots/demo");
    let out = Command::new("python3")
        .arg(root.join("tests/browser/test_hmi.py"))
        .current_dir(&root)
        .env("MOTUS_HMI_URL", format!("http://{addr}"))
        .env("MOTUS_HMI_USER", "admin")
        .env("MOTUS_HMI_PASSWORD", &password)
        .env("MOTUS_HMI_JOG_AXIS", "y")
        .env("MOTUS_HMI_ESTOP_MOVES", "x:0.8,linear2:0.05")
        .env("MOTUS_HMI_UNSAFE_AXIS", "")
        .env("MOTUS_HMI_UNSAFE_PROGRAM", "limit")
        .env("MOTUS_HMI_SAFE_PROGRAM", "juggle")
        .env("MOTUS_HMI_UNSAFE_RULE", "limits_thrower")
        .env("MOTUS_SCREENSHOTS", &shots)
        .env("MOTUS_BROWSER_DEADLINE", "300")
        .output()
        .expect("python3 must be installed");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("{stdout}\n{stderr}");
    assert!(out.status.success(), "browser test on the demo failed:\n{stdout}\n{stderr}");
    assert!(stdout.contains("6 passed, 0 failed"), "{stdout}");
}
