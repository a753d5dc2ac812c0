#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! Only an administrator changes the supervisor's rules, through `PUT /api/safety/rules`:
//! the station checks them, writes and signs them (the approval verifies with the cell's
//! key), the fingerprint changes, the supervisor stops and holds the juggler until a reset,
//! and then runs on the new rules. A student is refused (403) and nothing changes; invalid
//! rules and rules for other drives are refused with the reason. Axis parameters likewise:
//! only an admin narrows an axis's limits (never beyond the cell file's), and later
//! commands are checked against them; supervised axes are changed through the rules.

mod common;

use std::time::{Duration, Instant};

use common::{safety, station, wait_safe, Client};
use serde_json::{json, Value};

#[test]
fn an_admin_installs_approved_rules_and_a_student_cannot() {
    let st = station();
    let admin = Client::login(&st.addr, "admin", "admin-password-1");
    let student = Client::login(&st.addr, "student", "student-password-1");
    let before = wait_safe(&admin, Duration::from_secs(20));
    let fp0 = before["rules_fingerprint"].as_str().unwrap().to_owned();
    let rules_file = st.dir.path().join("juggler.toml");
    let text = std::fs::read_to_string(&rules_file).unwrap();

    // A student: 403, nothing changes.
    let (code, v) = student.call("PUT", "/api/safety/rules", json!({ "toml": text }));
    assert_eq!(code, 403, "{v}");
    assert_eq!(std::fs::read_to_string(&rules_file).unwrap(), text);

    // Invalid rules and rules for other drives: 400 with the reason.
    let (code, v) =
        admin.call("PUT", "/api/safety/rules", json!({ "toml": "[supervisor]\ncycle_time = -1\n" }));
    assert_eq!(code, 400, "{v}");
    eprintln!("invalid: {v}");
    let renamed = text.replace("thrower", "catapult");
    let (code, v) = admin.call("PUT", "/api/safety/rules", json!({ "toml": renamed }));
    assert_eq!(code, 400, "{v}");
    assert!(v.to_string().contains("drives"), "{v}");
    assert_eq!(safety(&admin)["rules_fingerprint"], fp0.as_str());

    // An admin tightens the data-age limit (15 -> 14 cycles): new fingerprint, drives held.
    let narrowed = text.replacen("max_sample_age = 15", "max_sample_age = 14", 1);
    assert_ne!(narrowed, text);
    let v = admin.ok("PUT", "/api/safety/rules", json!({ "toml": narrowed }));
    eprintln!("installed: {v}");
    let s = safety(&admin);
    let fp1 = s["rules_fingerprint"].as_str().unwrap().to_owned();
    assert_ne!(fp1, fp0);
    assert!(v.to_string().contains(&fp1), "the answer names the new fingerprint: {v}");
    let t0 = Instant::now();
    while safety(&admin)["held"] != true {
        assert!(t0.elapsed() < Duration::from_secs(5), "{}", safety(&admin));
        std::thread::sleep(Duration::from_millis(50));
    }
    assert_eq!(std::fs::read_to_string(&rules_file).unwrap(), narrowed);
    // The approval on disk verifies with the cell's key against the new rules and the
    // unchanged drive parameters (the one integrity check, as the station's watcher runs it).
    let files = motus_safety::ConfigFiles {
        rules: rules_file.clone(),
        drives: Some(st.dir.path().join("juggler-drives.toml")),
        approval: st.dir.path().join("data/juggler.approved"),
        key: st.dir.path().join("data/admin.key"),
    };
    let set = files.check().unwrap();
    assert_eq!(set.config(), motus_safety::RuleSet::from_toml(&narrowed).unwrap().config());
    // The operator resets: the juggler runs on the new rules.
    std::thread::sleep(Duration::from_millis(1500)); // the next integrity check
    admin.ok("POST", "/api/reset", Value::Null);
    let s = wait_safe(&admin, Duration::from_secs(20));
    assert_eq!(s["rules_fingerprint"], fp1.as_str());
    // Axis parameters: a student is refused; an admin narrows y's travel; a move beyond it
    // is refused; widening beyond the cell file and supervised axes are refused.
    let narrow = json!({ "limits": { "min": 0.0, "max": 0.2, "max_speed": 0.05, "max_acceleration": 1.0 },
                         "acceleration": 0.5 });
    let (code, v) = student.call("PUT", "/api/axes/y/parameters", narrow.clone());
    assert_eq!(code, 403, "{v}");
    let wide = json!({ "limits": { "min": 0.0, "max": 0.9, "max_speed": 0.05, "max_acceleration": 1.0 },
                       "acceleration": 0.5 });
    let (code, v) = admin.call("PUT", "/api/axes/y/parameters", wide);
    assert_eq!(code, 400, "{v}");
    assert!(v.to_string().contains("cell file"), "{v}");
    let (code, v) = admin.call("PUT", "/api/axes/thrower/parameters", narrow.clone());
    assert_eq!(code, 409, "{v}");
    admin.ok("PUT", "/api/axes/y/parameters", narrow);
    assert_eq!(admin.axis("y")["limits"]["max"], 0.2);
    admin.home("y");
    let (code, v) = admin.call("POST", "/api/axes/y/move", json!({ "target": 0.3, "speed": 0.05 }));
    assert_eq!(code, 400, "{v}");
    admin.ok("POST", "/api/axes/y/move", json!({ "target": 0.15, "speed": 0.05 }));

    // The 1 ms trace class is listed with its jitter; the traces export as CSV.
    let tasks = admin.ok("GET", "/api/tasks", Value::Null);
    let fast = tasks.as_array().unwrap().iter().find(|t| t["name"] == "trace-fast").unwrap().clone();
    assert_eq!(fast["period_us"], 1000, "{fast}");
    assert!(fast["cycles"].as_u64().unwrap() > 1000, "{fast}");
    eprintln!("tasks: {tasks}");
    let (code, csv) = admin.call("GET", "/api/samples.csv", Value::Null);
    assert_eq!(code, 200);
    let csv = csv.as_str().unwrap().to_owned();
    let mut lines = csv.lines();
    let header = lines.next().unwrap();
    assert!(header.starts_with("t_s,") && header.contains("y.position [m]"), "{header}");
    let columns = header.split(',').count();
    let rows: Vec<&str> = lines.collect();
    assert!(rows.len() > 10, "{} rows", rows.len());
    assert!(rows
        .iter()
        .all(|r| r.split(',').count() == columns && r.split(',').all(|v| v.parse::<f64>().is_ok())));

    // The juggler's 1 kHz trace: in the HMI's signals (latest value per row) and at full
    // rate in trace.csv.
    let signals = admin.ok("GET", "/api/signals", Value::Null).to_string();
    assert!(signals.contains("trace-fast/thrower-drive.position"), "{signals}");
    let (code, trace) = admin.call("GET", "/api/trace.csv", Value::Null);
    assert_eq!(code, 200);
    let trace = trace.as_str().unwrap().to_owned();
    let header = trace.lines().next().unwrap();
    assert!(header.contains("trace-fast/thrower-drive.position"), "{header}");
    let rows = trace.lines().count() - 1;
    assert!(rows > 1000, "{rows} rows at 1 kHz");
    eprintln!("trace.csv: {rows} rows; {header}");

    // The audit log has the change, by whom, and the student's refusal.
    let audit = admin.ok("GET", "/api/audit", Value::Null).to_string();
    assert!(audit.contains("admin") && audit.contains("student"), "{audit}");
}
