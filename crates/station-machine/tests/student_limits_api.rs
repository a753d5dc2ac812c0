#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! A student in their slot on the real station (demo cell): jogs stop at the student range
//! however long they are renewed; moves and group go-tos beyond it are refused (403,
//! audited) and move nothing, by the lab and again by the backend; an axis without student
//! limits (`linear4`) cannot be moved or homed by a student, an admin moves it; an E-stop an
//! admin pressed is not a student's to reset, their own is.

mod common;

use std::time::{Duration, Instant};

use common::Client;
use motus_lab::Role;
use motus_station_web::{AxisAction, BackendError, Caller, GroupAction, MachineBackend};
use serde_json::{json, Value};

fn position(c: &Client, id: &str) -> f64 {
    c.axis(id)["position"].as_f64().unwrap()
}

/// A POST that must succeed: retried while the device reconnects, and after a lost reply
/// (a machine failure: the loaded host starves the serial simulators now and then).
fn ok(c: &Client, path: &str, body: Value) -> Value {
    let mut attempt = 0;
    loop {
        attempt += 1;
        let (code, v) = c.call_connected("POST", path, body.clone());
        if code == 500 && attempt < 5 {
            eprintln!("POST {path}: {v}: again");
            std::thread::sleep(Duration::from_millis(500));
            continue;
        }
        assert_eq!(code, 200, "POST {path}: {v}");
        return v;
    }
}

fn now_ms() -> i64 {
    i64::try_from(std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_millis())
        .unwrap()
}

fn audit_has(admin: &Client, user: &str, action: &str, outcome: &str, target: &str) -> bool {
    let v = admin.ok("GET", &format!("/api/audit?user={user}&limit=500"), Value::Null);
    v.as_array().unwrap().iter().any(|r| {
        let e = &r["entry"];
        e["action"] == action
            && e["outcome"]["result"] == outcome
            && e["target"].as_str().unwrap_or("").contains(target)
    })
}

/// Waits until `id` stands still (position unchanged for 0.5 s).
fn settle(c: &Client, id: &str) -> f64 {
    let t0 = Instant::now();
    let mut last = position(c, id);
    let mut since = Instant::now();
    loop {
        std::thread::sleep(Duration::from_millis(50));
        let p = position(c, id);
        if (p - last).abs() > 1e-4 {
            last = p;
            since = Instant::now();
        } else if since.elapsed() > Duration::from_millis(500) {
            return p;
        }
        assert!(t0.elapsed() < Duration::from_secs(20), "{id} does not settle");
    }
}

#[test]
fn a_student_stays_within_the_student_limits_and_cannot_reset_an_admins_estop() {
    let _ = tracing_subscriber::fmt().with_env_filter("info").with_test_writer().try_init();
    let st = common::station();
    let admin = Client::login(&st.addr, "admin", "admin-password-1");
    let student = Client::login(&st.addr, "student", "student-password-1");
    // The station connects its devices in the background: wait for the ones used here.
    for id in ["pan", "tilt", "linear2", "linear4"] {
        admin.wait_axis(id, Duration::from_secs(60), "connected", |a| a["fault"].is_null());
    }
    for id in ["pan", "tilt", "linear4"] {
        admin.home(id);
    }
    let now = now_ms();
    student.ok("POST", "/api/reservations", json!({ "start": now - 1000, "end": now + 30 * 60 * 1000 }));

    // (b) A student's jog stops at the student range (tilt: +-1.0) however long it is
    // renewed; the machine's limit (1.2) is not reached.
    // Renewed until it has stood at the range for a second (a loaded host may drop the
    // device for a moment: the station stops it, reconnects, and the renewals go on).
    let t0 = Instant::now();
    let mut highest = f64::MIN;
    let mut at_range: Option<Instant> = None;
    loop {
        let (code, v) =
            student.call_connected("POST", "/api/axes/tilt/jog", json!({ "direction": 1.0, "speed": 1.0 }));
        if code == 409 && v["detail"].as_str().unwrap_or("").contains("not homed") {
            eprintln!("tilt lost its reference (device reconnected): home it again");
            admin.home("tilt");
            continue;
        }
        assert_eq!(code, 200, "student jog on tilt: {v}");
        let p = position(&student, "tilt");
        highest = highest.max(p);
        if p > 0.95 && at_range.get_or_insert_with(Instant::now).elapsed() > Duration::from_secs(1) {
            break;
        }
        assert!(t0.elapsed() < Duration::from_secs(60), "the jog did not reach the student range: {p}");
        std::thread::sleep(Duration::from_millis(150));
    }
    let tilt = settle(&student, "tilt");
    highest = highest.max(tilt);
    eprintln!("student jog on tilt renewed for {:?}: highest {highest}, rests at {tilt}", t0.elapsed());
    assert!(highest <= 1.0 + 0.01, "passed the student range: {highest}");
    assert!(tilt > 0.95, "the jog did not reach the student range: {tilt}");
    // A jog on an axis that is not homed: refused (the range cannot be kept), nothing moves.
    let l2 = position(&admin, "linear2");
    let (code, v) =
        student.call_connected("POST", "/api/axes/linear2/jog", json!({ "direction": 1.0, "speed": 0.01 }));
    eprintln!("student jog on unhomed linear2: {code} {v}");
    assert_eq!(code, 409, "{v}");
    assert!(v["detail"].as_str().unwrap().contains("not homed"), "{v}");
    assert_eq!(position(&admin, "linear2"), l2);

    // (c) A move beyond the student range: 403 (the lab), audited, tilt does not move.
    let (code, v) =
        student.call_connected("POST", "/api/axes/tilt/move", json!({ "target": 1.15, "speed": 0.5 }));
    eprintln!("student move tilt -> 1.15: {code} {v}");
    assert_eq!(code, 403, "{v}");
    std::thread::sleep(Duration::from_millis(300));
    assert!((position(&admin, "tilt") - tilt).abs() < 2e-3);
    assert!(audit_has(&admin, "student", "command.axis.move", "denied", "tilt"));
    // The group go-to: a member beyond its student range refuses the whole command.
    let pan = position(&admin, "pan");
    let (code, v) = student.call_connected(
        "POST",
        "/api/groups/head",
        json!({ "action": "go_to", "targets": [0.5, 1.15] }),
    );
    eprintln!("student head go-to [0.5, 1.15]: {code} {v}");
    assert_eq!(code, 403, "{v}");
    std::thread::sleep(Duration::from_millis(300));
    assert!((position(&admin, "pan") - pan).abs() < 2e-3, "pan moved");
    assert!((position(&admin, "tilt") - tilt).abs() < 2e-3, "tilt moved");
    // The backend refuses the same on its own (defence in depth), and moves nothing.
    let as_student = Caller::new("student", Role::Student);
    let e = st
        .machine
        .command(&as_student, "tilt", AxisAction::Move { target: 1.15, speed: 0.5, acceleration: None })
        .unwrap_err();
    eprintln!("backend, student move tilt -> 1.15: {e}");
    assert!(matches!(e, BackendError::Forbidden(_)), "{e:?}");
    let e = st
        .machine
        .command(&as_student, "tilt", AxisAction::Move { target: 0.5, speed: 2.5, acceleration: None })
        .unwrap_err();
    assert!(matches!(e, BackendError::Forbidden(_)), "{e:?}");
    let e = st
        .machine
        .group_command(&as_student, "head", GroupAction::GoTo { targets: vec![0.5, 1.15] })
        .unwrap_err();
    assert!(matches!(e, BackendError::Forbidden(_)), "{e:?}");
    std::thread::sleep(Duration::from_millis(300));
    assert!((position(&admin, "pan") - pan).abs() < 2e-3, "pan moved");
    assert!((position(&admin, "tilt") - tilt).abs() < 2e-3, "tilt moved");
    // Within the range: the go-to works.
    ok(&student, "/api/groups/head", json!({ "action": "go_to", "targets": [0.3, -0.4] }));
    student.wait_axis("tilt", Duration::from_secs(15), "at -0.4", |a| {
        (a["position"].as_f64().unwrap() + 0.4).abs() < 5e-3 && a["moving"] == false
    });

    // (d) linear4 has no student table: the student can neither move nor home it (403; the
    // home is refused by the backend), the admin can.
    let l4 = position(&admin, "linear4");
    let (code, v) =
        student.call_connected("POST", "/api/axes/linear4/move", json!({ "target": 0.02, "speed": 0.01 }));
    eprintln!("student move linear4: {code} {v}");
    assert_eq!(code, 403, "{v}");
    let (code, v) =
        student.call_connected("POST", "/api/axes/linear4/jog", json!({ "direction": 1.0, "speed": 0.01 }));
    assert_eq!(code, 403, "{v}");
    let (code, v) = student.call_connected("POST", "/api/axes/linear4/home", Value::Null);
    eprintln!("student home linear4: {code} {v}");
    assert_eq!(code, 403, "{v}");
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(position(&admin, "linear4"), l4);
    assert!(audit_has(&admin, "student", "command.axis.move", "denied", "linear4"));
    ok(&admin, "/api/axes/linear4/move", json!({ "target": 0.02, "speed": 0.02 }));
    admin.wait_axis("linear4", Duration::from_secs(20), "at 0.02", |a| {
        (a["position"].as_f64().unwrap() - 0.02).abs() < 2e-5 && a["moving"] == false
    });

    // (e) An E-stop by the admin: the student's reset is refused (403, naming who pressed
    // it); the admin's works. The student's own E-stop: the student resets it.
    admin.ok("POST", "/api/estop", Value::Null);
    let s = admin.ok("GET", "/api/safety", Value::Null);
    eprintln!("safety after the admin's E-stop: {}", s["diagnosis"]);
    assert_eq!(s["estop"], true);
    assert!(s["diagnosis"].as_str().unwrap().contains("emergency stop by admin (admin)"), "{s}");
    let (code, v) = student.call_connected("POST", "/api/reset", Value::Null);
    eprintln!("student reset of the admin's E-stop: {code} {v}");
    assert_eq!(code, 403, "{v}");
    let detail = v["detail"].as_str().unwrap();
    assert!(detail.contains("admin (admin)") && detail.contains("only an administrator"), "{v}");
    assert_eq!(admin.ok("GET", "/api/safety", Value::Null)["estop"], true);
    let (code, v) =
        student.call_connected("POST", "/api/axes/pan/move", json!({ "target": 0.0, "speed": 0.5 }));
    assert_eq!(code, 409, "still E-stopped: {v}");
    admin.ok("POST", "/api/reset", Value::Null);
    assert_eq!(admin.ok("GET", "/api/safety", Value::Null)["estop"], false);

    student.ok("POST", "/api/estop", Value::Null);
    let s = student.ok("GET", "/api/safety", Value::Null);
    assert!(s["diagnosis"].as_str().unwrap().contains("emergency stop by student (student)"), "{s}");
    student.ok("POST", "/api/reset", Value::Null);
    assert_eq!(student.ok("GET", "/api/safety", Value::Null)["estop"], false);
    // Back in business: the student moves within the range.
    ok(&student, "/api/axes/tilt/move", json!({ "target": 0.2, "speed": 0.5 }));
    student.wait_axis("tilt", Duration::from_secs(15), "at 0.2", |a| {
        (a["position"].as_f64().unwrap() - 0.2).abs() < 5e-3 && a["moving"] == false
    });
}
