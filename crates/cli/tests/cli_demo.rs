//! `motus demo`: the whole simulated cell with the station, through its HTTP API (the HMI's
//! browser test on the same demo is cli_demo_browser.rs).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::{http, MOTUS};
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

struct Demo(Child);
impl Drop for Demo {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn json(body: &str) -> serde_json::Value {
    serde_json::from_str(body).unwrap_or_else(|e| panic!("{e}: {body}"))
}

#[test]
fn demo_serves_the_whole_cell_moves_axes_runs_a_program_and_stops_everything() {
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let addr = format!("127.0.0.1:{port}");
    let mut child = Command::new(MOTUS)
        .args(["demo", "--listen", &addr])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let out = child.stdout.take().unwrap();
    let demo = Demo(child);
    let mut lines = BufReader::new(out).lines();
    let mut password = None;
    let deadline = Instant::now() + Duration::from_secs(60);
    while password.is_none() && Instant::now() < deadline {
        let l = lines.next().expect("demo exited").unwrap();
        if let Some(p) = l.strip_prefix("administrator login: user admin, password ") {
            password = Some(p.trim().to_owned());
        }
    }
    let password = password.expect("the admin password is printed once");
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
    let csrf = json(&body)["csrf_token"].as_str().unwrap().to_owned();
    let auth =
        [("Cookie", cookie.as_str()), ("X-CSRF-Token", csrf.as_str()), ("Content-Type", "application/json")];
    let axes = |a: &[(&str, &str)]| json(&http(&addr, "GET", "/api/axes", a, "").2);
    let v = axes(&auth);
    let ids: Vec<&str> = v.as_array().unwrap().iter().map(|a| a["id"].as_str().unwrap()).collect();
    for id in ["wheel1", "pan", "tilt", "joint1", "linear1", "thrower", "x", "y", "z"] {
        assert!(ids.contains(&id), "{id} missing from {ids:?}");
    }
    // Home and move a PS1A module and the gantry's axes (programs run on a homed gantry);
    // read the positions back.
    for (axis, target, speed) in
        [("linear1", 0.02, 0.01), ("x", 0.1, 0.1), ("y", 0.01, 0.1), ("z", 0.01, 0.05)]
    {
        // The station serves before every device has connected (absent devices are alarmed and
        // connected when they answer): a device still connecting refuses motion with 409.
        let end = Instant::now() + Duration::from_secs(60);
        let (st, b) = loop {
            let (st, _, b) = http(&addr, "POST", &format!("/api/axes/{axis}/home"), &auth, "");
            if st == 409 && b.contains("not connected yet") && Instant::now() < end {
                std::thread::sleep(Duration::from_millis(200));
                continue;
            }
            break (st, b);
        };
        assert_eq!(st, 200, "{axis} home: {b}");
        let end = Instant::now() + Duration::from_secs(20);
        loop {
            let (st, _, b) = http(
                &addr,
                "POST",
                &format!("/api/axes/{axis}/move"),
                &auth,
                &format!("{{\"target\":{target},\"speed\":{speed}}}"),
            );
            if st == 200 {
                break;
            }
            assert!(Instant::now() < end, "{axis} move: {st} {b}");
            std::thread::sleep(Duration::from_millis(200));
        }
    }
    let end = Instant::now() + Duration::from_secs(30);
    loop {
        let v = axes(&auth);
        let pos = |id: &str| {
            v.as_array().unwrap().iter().find(|a| a["id"] == id).unwrap()["position"].as_f64().unwrap()
        };
        if (pos("linear1") - 0.02).abs() < 1e-4 && (pos("x") - 0.1).abs() < 1e-4 {
            break;
        }
        assert!(Instant::now() < end, "positions {} {}", pos("linear1"), pos("x"));
        std::thread::sleep(Duration::from_millis(200));
    }
    // A G-code program with progress.
    let prog = "G21 G90 F1200\\nG1 X40 Y10\\nG1 X0 Y0\\nM2\\n";
    let (st, _, b) =
        http(&addr, "POST", "/api/programs", &auth, &format!("{{\"name\":\"t.ngc\",\"text\":\"{prog}\"}}"));
    assert_eq!(st, 200, "{b}");
    let id = json(&b)["program"]["id"].as_str().unwrap().to_owned();
    let (st, _, b) = http(&addr, "POST", &format!("/api/programs/{id}/run"), &auth, "");
    assert_eq!(st, 200, "{b}");
    let mut saw_running = false;
    let end = Instant::now() + Duration::from_secs(30);
    loop {
        let s = json(&http(&addr, "GET", "/api/programs/status", &auth, "").2);
        saw_running |= s["state"] == "running" && s["progress"].as_f64().unwrap() > 0.0;
        if s["state"] == "done" {
            assert_eq!(s["progress"].as_f64(), Some(1.0));
            break;
        }
        assert!(Instant::now() < end, "{s}");
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(saw_running, "progress was visible while running");
    // Emergency stop during motion: every axis comes to rest, motion commands are refused.
    http(&addr, "POST", "/api/axes/linear1/move", &auth, "{\"target\":0.5,\"speed\":0.01}");
    http(&addr, "POST", "/api/axes/x/move", &auth, "{\"target\":0.9,\"speed\":0.05}");
    std::thread::sleep(Duration::from_millis(300));
    let (st, _, b) = http(&addr, "POST", "/api/estop", &auth, "");
    assert_eq!(st, 200, "{b}");
    let end = Instant::now() + Duration::from_secs(10);
    loop {
        let v = axes(&auth);
        let moving: Vec<&str> = v
            .as_array()
            .unwrap()
            .iter()
            .filter(|a| a["moving"].as_bool() == Some(true) && a["group"] != "juggler")
            .map(|a| a["id"].as_str().unwrap())
            .collect();
        if moving.is_empty() {
            break;
        }
        assert!(Instant::now() < end, "still moving after E-stop: {moving:?}");
        std::thread::sleep(Duration::from_millis(100));
    }
    let safety = json(&http(&addr, "GET", "/api/safety", &auth, "").2);
    assert_eq!(safety["estop"], true, "{safety}");
    let (st, _, _) = http(&addr, "POST", "/api/axes/x/move", &auth, "{\"target\":0.2,\"speed\":0.05}");
    assert_eq!(st, 409, "motion refused while E-stopped");
    // Ctrl-C (SIGINT): the demo stops its station, simulators and threads, and exits 0.
    let mut demo = demo;
    let pid = demo.0.id().to_string();
    assert!(Command::new("kill").args(["-INT", &pid]).status().unwrap().success());
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = demo.0.try_wait().unwrap() {
            break s;
        }
        assert!(t0.elapsed() < Duration::from_secs(20), "the demo did not stop on Ctrl-C");
        std::thread::sleep(Duration::from_millis(100));
    };
    eprintln!("demo stopped {:?} after Ctrl-C: {status:?}", t0.elapsed());
    assert!(status.success(), "{status:?}");
    assert!(std::net::TcpStream::connect(&addr).is_err(), "the HMI port is released");
}
