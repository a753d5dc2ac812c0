#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! The omni robot's go-to on the real station (demo cell, three simulated CiA 402 wheel
//! drives): a go-to from the map takes the simulated robot (its true pose, not the station's
//! estimate) to the target; a target off the map or a malformed one is refused and moves
//! nothing; a student in their slot drives the robot within the wheels' student limits.

mod common;

use std::time::{Duration, Instant};

use common::Client;
use serde_json::{json, Value};

fn pose(c: &Client) -> [f64; 3] {
    let s = c.ok("GET", "/api/scene", Value::Null);
    let p = &s["robot"]["pose"];
    [p[0].as_f64().unwrap(), p[1].as_f64().unwrap(), p[2].as_f64().unwrap()]
}

fn wheels_still(c: &Client) -> bool {
    ["wheel1", "wheel2", "wheel3"].iter().all(|w| c.axis(w)["moving"] == false)
}

/// Goes to `(x, y)` (keeping the heading) and waits until the robot stands within 2 cm of it.
fn go_to(c: &Client, x: f64, y: f64) -> Duration {
    let t0 = Instant::now();
    let (code, v) =
        c.call_connected("POST", "/api/groups/omni", json!({ "action": "go_to", "targets": [x, y] }));
    assert_eq!(code, 200, "go-to ({x}, {y}): {v}");
    loop {
        std::thread::sleep(Duration::from_millis(100));
        let p = pose(c);
        if (p[0] - x).hypot(p[1] - y) < 0.02 && wheels_still(c) {
            return t0.elapsed();
        }
        assert!(t0.elapsed() < Duration::from_secs(60), "the robot did not reach ({x}, {y}): {p:?}");
    }
}

fn now_ms() -> i64 {
    i64::try_from(std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_millis())
        .unwrap()
}

#[test]
fn the_robot_goes_to_points_of_the_map_and_refuses_targets_off_it() {
    let _ = tracing_subscriber::fmt().with_env_filter("info").with_test_writer().try_init();
    let st = common::station();
    let admin = Client::login(&st.addr, "admin", "admin-password-1");
    let student = Client::login(&st.addr, "student", "student-password-1");
    for w in ["wheel1", "wheel2", "wheel3"] {
        admin.wait_axis(w, Duration::from_secs(60), "connected", |a| a["fault"].is_null());
    }
    let groups = admin.ok("GET", "/api/groups", Value::Null);
    let omni = groups.as_array().unwrap().iter().find(|g| g["id"] == "omni").expect("omni group");
    assert_eq!(omni["kind"], "robot");

    let start = pose(&admin);
    let took = go_to(&admin, start[0] + 0.4, start[1] - 0.3);
    let p = pose(&admin);
    eprintln!("admin go-to: {took:?}, at {p:?}");
    assert!((p[2] - start[2]).abs() < 0.02, "the heading changed: {start:?} -> {p:?}");
    let scene = admin.ok("GET", "/api/scene", Value::Null);
    assert!(!scene["robot"]["path"].as_array().unwrap().is_empty(), "no path drawn");

    // With a heading: the robot turns as well.
    let (code, v) = admin.call_connected(
        "POST",
        "/api/groups/omni",
        json!({ "action": "go_to", "targets": [0.0, 0.0, 0.5] }),
    );
    assert_eq!(code, 200, "{v}");
    let t0 = Instant::now();
    loop {
        std::thread::sleep(Duration::from_millis(100));
        let p = pose(&admin);
        if p[0].hypot(p[1]) < 0.02 && (p[2] - 0.5).abs() < 0.02 && wheels_still(&admin) {
            break;
        }
        assert!(t0.elapsed() < Duration::from_secs(60), "the robot did not reach (0, 0, 0.5): {p:?}");
    }

    // Off the map, not finite, or the wrong number of values: refused, nothing moves.
    let before = pose(&admin);
    for (targets, why) in [
        (json!([5.0, 0.0]), "outside the robot's area"),
        (json!([0.1]), "the robot takes [x, y]"),
        (json!([0.1, 0.2, 0.3, 0.4]), "the robot takes [x, y]"),
    ] {
        let (code, v) =
            admin.call("POST", "/api/groups/omni", json!({ "action": "go_to", "targets": targets }));
        assert_eq!(code, 400, "{targets}: {v}");
        assert!(v.to_string().contains(why), "{targets}: {v}");
    }
    std::thread::sleep(Duration::from_millis(300));
    let after = pose(&admin);
    assert!((after[0] - before[0]).hypot(after[1] - before[1]) < 1e-3, "moved: {before:?} -> {after:?}");
    assert!(wheels_still(&admin));

    // A student without a slot: refused. In their slot: the robot goes where they click.
    let (code, v) =
        student.call("POST", "/api/groups/omni", json!({ "action": "go_to", "targets": [0.2, 0.2] }));
    assert_eq!(code, 403, "{v}");
    let now = now_ms();
    student.ok("POST", "/api/reservations", json!({ "start": now - 1000, "end": now + 30 * 60 * 1000 }));
    let took = go_to(&student, -0.3, 0.25);
    eprintln!("student go-to: {took:?}");
}
