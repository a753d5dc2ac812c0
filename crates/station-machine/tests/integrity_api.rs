#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! The demo station supervises the juggler's drive parameters with its rules: the demo cell
//! names the drive-parameter file, the demo's approval covers it, and the station's
//! integrity watcher (the one `motus safety run` starts) re-checks it. A changed drive
//! parameter on disk makes the juggler unsafe with a diagnosis naming the drive and the
//! parameter, stops its drives and refuses moves of its axes with that reason; restoring the
//! file lets an operator reset and the juggler runs again.

mod common;

use std::time::Duration;

use common::{safety, station, wait_safe, wait_safety, Client};
use serde_json::{json, Value};

#[test]
fn a_changed_juggler_drive_parameter_blocks_the_juggler_and_is_named() {
    let st = station();
    let admin = Client::login(&st.addr, "admin", "admin-password-1");
    let before = wait_safe(&admin, Duration::from_secs(30));

    // The cell names the drive parameters and the approval covers them: the fingerprint shown
    // is that of the rules and the drives, as the one integrity check computes it.
    let sup = supervisor_of(&st);
    let drives_file = sup.drives.clone().expect("the demo cell names the juggler's drive parameters");
    assert_eq!(drives_file, st.dir.path().join("juggler-drives.toml"));
    let (_, snapshot) = motus_safety::config_files::read_snapshot(&sup.rules, Some(&drives_file)).unwrap();
    assert_eq!(before["rules_fingerprint"], snapshot.fingerprint().to_string().as_str());
    let files = motus_safety::ConfigFiles {
        rules: sup.rules.clone(),
        drives: Some(drives_file.clone()),
        approval: sup.approval.clone().unwrap(),
        key: sup.key.clone().unwrap(),
    };
    files.check().unwrap();

    // Someone lowers the thrower's quick-stop deceleration on disk (no approval).
    let original = std::fs::read_to_string(&drives_file).unwrap();
    let mut drives = motus_safety::config_files::read_drives(&drives_file).unwrap();
    let thrower = drives.iter_mut().find(|d| d.axis == "thrower").unwrap();
    let a_stop = thrower.a_stop;
    thrower.a_stop = a_stop * 0.75;
    motus_safety::config_files::write_drives(&drives_file, &drives).unwrap();
    let change = format!("drive[thrower].a_stop: {a_stop:?} -> {:?}", a_stop * 0.75);

    // Within the watcher's period (1 s; generous liveness time-out): not safe, named.
    let s = wait_safety(&admin, Duration::from_secs(30), "blocked by the drive change", |s| {
        s["safe_to_run"] == false
            && s["diagnosis"].as_str().is_some_and(|d| d.contains("drive[thrower].a_stop"))
    });
    eprintln!("blocked: {}", s["diagnosis"]);
    assert!(s["diagnosis"].as_str().unwrap().contains(&change), "{s}");
    assert_eq!(s["held"], true, "{s}");

    // The juggler's drives are stopped (the safety lease is revoked) ...
    admin.wait_axis("thrower", Duration::from_secs(30), "stopped by the revoked lease", |a| {
        a["moving"] == false && a["fault"].as_str().is_some_and(|f| f.contains("safety lease"))
    });
    // ... and a move of a juggler axis is refused with the reason.
    for axis in ["thrower", "arm_left"] {
        let a = admin.axis(axis);
        let (code, v) = admin.call(
            "POST",
            &format!("/api/axes/{axis}/move"),
            json!({ "target": a["position"], "speed": a["default_speed"] }),
        );
        assert_eq!(code, 409, "{axis}: {v}");
        assert_eq!(v["error"], "safety_hold", "{axis}: {v}");
        assert!(v.to_string().contains("drive[thrower].a_stop"), "{axis}: {v}");
    }
    // An operator's reset does not release it while the change stands.
    admin.ok("POST", "/api/reset", Value::Null);
    // The next integrity check, applied after the reset (one mailbox, in order).
    let checks = safety(&admin)["integrity_checks"].as_u64().unwrap();
    let s = wait_safety(&admin, Duration::from_secs(30), "checked again", |s| {
        s["integrity_checks"].as_u64().unwrap() > checks
    });
    assert_eq!(s["safe_to_run"], false, "{s}");
    assert!(s["diagnosis"].as_str().unwrap().contains("drive[thrower].a_stop"), "{s}");

    // Restored: the integrity check passes again, the operator resets, the juggler runs.
    std::fs::write(&drives_file, original).unwrap();
    files.check().unwrap();
    // The diagnosis says why SafeToRun fell last: it may keep the integrity message until a
    // new decision; SafeToRun (after a reset when held) is what shows the integrity is back.
    wait_safety(&admin, Duration::from_secs(30), "integrity restored", |s| {
        s["safe_to_run"] == true
            || s["held"] == true
            || !s["diagnosis"].as_str().is_some_and(|d| d.contains("configuration changed"))
    });
    let s = wait_safe(&admin, Duration::from_secs(30));
    assert_eq!(s["rules_fingerprint"], before["rules_fingerprint"]);
    // Safe: no diagnosis (the blocked one is not shown beside SafeToRun).
    assert!(s["diagnosis"].is_null(), "{s}");
    admin.wait_axis("thrower", Duration::from_secs(30), "juggling again", |a| {
        a["moving"] == true && a["fault"].is_null()
    });
}

/// The demo cell's `[supervisor]` table, as the station loaded it.
fn supervisor_of(st: &common::Station) -> motus_station::config::Supervisor {
    let cell = motus_station::config::load(&st.dir.path().join("demo-cell.toml")).unwrap();
    cell.supervisor.unwrap()
}
