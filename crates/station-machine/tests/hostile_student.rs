//! The hostile-student suite of issue 18 (acceptance 1), on the real station machine over
//! the small simulated cell (`common/api-test-cell.toml`: gantry x, y, z with student
//! tables; `w` without one). Each refusal test has a student (or a viewer) do the hostile
//! thing through the HTTP API and asserts
//!
//! - (a) the refusal's status and an error message that names what was wrong;
//! - (b) the machine is unchanged: after a settle time every axis is where it was, still,
//!   homed and switched on as it was, no program started, the E-stop as it was
//!   ([`assert_unchanged`]);
//! - (c) an audit entry with the user, the action and its parameters ([`assert_audited`]).
//!
//! What must work, works: a student resets their own E-stop, and runs their own and a
//! published program.
//!
//! Where each class of issue 18's "What was found" is covered (files under
//! `crates/station-machine/tests/` unless a crate is named):
//!
//! 1. Jog without its dead-man: `deadman_api.rs`
//!    (`one_jog_request_stops_by_itself_on_every_device_family`, demo cell, every device
//!    family); a student's renewed jog stops at the student range: here
//!    (`class3_a_student_stays_within_the_student_limits`) and `student_limits_api.rs`.
//! 2. One G-code check stalls the station: `programs_api.rs`
//!    (`a_check_that_would_take_hours_stops_at_its_budget_and_the_station_stays_responsive`:
//!    budget, busy pool, latency, audit) and `crates/cli/tests/cli_stop.rs` (Ctrl-C within
//!    2 s while checks run); a viewer cannot re-trigger a check: here
//!    (`viewers_cannot_check_or_run_programs_nor_command`).
//! 3. Student position limits: here (`class3_a_student_stays_within_the_student_limits`:
//!    move, speed, jog, group go-to); on the demo cell `student_limits_api.rs` (pan-tilt,
//!    and the backend's own refusal behind the lab's).
//! 4. Programs bypass student limits: here
//!    (`class4_a_program_beyond_the_student_limits_is_refused_before_it_runs`);
//!    `programs_api.rs` (`a_program_cannot_take_a_student_beyond_the_limits_and_nothing_moves`:
//!    the machine travel for everyone, inches, a program within the limits runs).
//! 5. Fail-open axes: here
//!    (`class5_an_axis_without_student_limits_is_not_a_students_to_move`);
//!    `student_limits_api.rs` (demo cell, `linear4`).
//! 6. A student undoes someone else's E-stop: here
//!    (`class6_a_student_cannot_reset_an_estop_an_admin_pressed`, and
//!    `a_student_resets_their_own_estop` for what must work); `student_limits_api.rs`;
//!    `web_api.rs` (`no_api_can_make_safe_to_run_true`).
//! 7. Login limiter bypassed by concurrency: `crates/lab/tests/login_burst.rs` (attempts
//!    reserved before hashing, bounded pool, audited), `web_api.rs`
//!    (`login_is_rate_limited`: 429, `Retry-After`, audited), `crates/cli/tests/cli_demo_load.rs`
//!    (200 concurrent logins on `motus demo`, memory).
//! 8. Programs are shared: here
//!    (`class8_students_cannot_see_check_or_run_other_users_programs`); `programs_api.rs`
//!    (`students_see_check_and_run_their_own_and_published_programs_viewers_neither`:
//!    publication, end-of-slot removal).
//! 9. No header-read time-out or connection cap: `web_connections.rs` (every test).
//! 10. Audit gaps: here (`class10_refusals_before_authorisation_are_audited_with_the_user`;
//!     move targets and program demands in the entries throughout;
//!     `malformed_and_oversized_move_bodies_are_refused_and_audited`; checks audited in
//!     `a_student_checks_and_runs_their_own_and_a_published_program`); `web_refusals.rs`
//!     (route misses without a session, bad login bodies, nothing audited twice).
//! 11. Device threads starve under web load: `crates/cli/tests/cli_demo_load.rs`.
//! 12. Recovery gaps: `recovery.rs` (absent arm, KV-01 time-out latch), `chaos_api.rs`
//!     (a simulator killed in motion), `crates/cell/tests/can_recovery.rs` (drive reboot,
//!     hub restart), `crates/cli/tests/cli_station_chaos.rs` (the same with separate
//!     processes), `crates/cli/tests/cli_sim_bus_closed.rs` (simulators exit).
//! 13. WebSocket origin compared with Host: here
//!     (`class13_a_websocket_from_another_origin_is_refused_and_audited`); `web_refusals.rs`
//!     (served and configured origins), `web_ws_openapi.rs`.
//! 14. HMI controls the real cell does not answer: `crates/cli/tests/cli_demo_browser.rs`.
//!
//! Also here: viewers' refusals (`viewers_cannot_check_or_run_programs_nor_command`), a
//! student outside their slot (`a_student_cannot_command_outside_their_slot`), a jog or a
//! move on an axis that is not homed (`a_student_cannot_jog_or_move_an_axis_that_is_not_homed`),
//! oversized, malformed and invalid move bodies
//! (`malformed_and_oversized_move_bodies_are_refused_and_audited`).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::time::{Duration, Instant};

use common::web::{wait_for, Env, WebClient, ADMIN_PW, STATION, STUDENT_PW, VIEWER_PW};
use reqwest::{Method, StatusCode};
use serde_json::{json, Value};

/// Generous liveness time-out for motion and program runs on a loaded host (seconds).
const LIVENESS: f64 = 60.0;
/// How long a refused command has to show motion, were it to start any (a move started
/// at 0.01 m/s travels 5 mm in that time: far beyond [`TOLERANCE`]).
const SETTLE: Duration = Duration::from_millis(500);
/// Position tolerance (m): the simulated axes resolve 1 µm.
const TOLERANCE: f64 = 1e-5;

/// What a refusal must not change.
#[derive(Debug, Clone, PartialEq)]
struct Machine {
    /// (axis, position, moving, homed, enabled).
    axes: Vec<(String, f64, bool, bool, bool)>,
    estop: bool,
    /// The program service's state and program.
    program: (Value, Value),
}

async fn machine(c: &WebClient) -> Machine {
    let (st, axes) = c.get("/api/axes").await;
    assert_eq!(st, StatusCode::OK, "{axes}");
    let axes = axes
        .as_array()
        .unwrap()
        .iter()
        .map(|a| {
            (
                a["id"].as_str().unwrap().to_string(),
                a["position"].as_f64().unwrap(),
                a["moving"].as_bool().unwrap(),
                a["homed"].as_bool().unwrap(),
                a["enabled"].as_bool().unwrap(),
            )
        })
        .collect();
    let (st, safety) = c.get("/api/safety").await;
    assert_eq!(st, StatusCode::OK, "{safety}");
    let (st, program) = c.get("/api/programs/status").await;
    assert_eq!(st, StatusCode::OK, "{program}");
    Machine {
        axes,
        estop: safety["estop"].as_bool().unwrap(),
        program: (program["state"].clone(), program["program"].clone()),
    }
}

/// The machine once every axis stands still (the "before" of a refusal).
async fn still(c: &WebClient) -> Machine {
    let t0 = Instant::now();
    loop {
        let m = machine(c).await;
        if m.axes.iter().all(|a| !a.2) {
            return m;
        }
        assert!(t0.elapsed().as_secs_f64() < LIVENESS, "axes do not stand still: {m:?}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// (b): every axis is where it was in `before`, still, homed and switched on as it was; the
/// E-stop and the program service are as they were.
#[track_caller]
fn check_unchanged(before: &Machine, after: &Machine, what: &str) {
    assert_eq!(before.axes.len(), after.axes.len(), "{what}");
    for (b, a) in before.axes.iter().zip(&after.axes) {
        assert_eq!(a.0, b.0, "{what}");
        assert!((a.1 - b.1).abs() <= TOLERANCE, "{what}: axis {} moved from {} to {}", a.0, b.1, a.1);
        assert!(!a.2, "{what}: axis {} is moving", a.0);
        assert_eq!(a.3, b.3, "{what}: axis {} homed changed", a.0);
        assert_eq!(a.4, b.4, "{what}: axis {} enabled changed (a drive switched on)", a.0);
    }
    assert_eq!(after.estop, before.estop, "{what}: the E-stop changed");
    assert_eq!(after.program, before.program, "{what}: the program service changed");
}

async fn assert_unchanged(c: &WebClient, before: &Machine, what: &str) {
    tokio::time::sleep(SETTLE).await;
    let after = machine(c).await;
    check_unchanged(before, &after, what);
}

/// (c): an audit entry of `user` with `action`, whose target contains every `target` part
/// (the command's parameters), of outcome `kind`, whose message contains every `message`
/// part.
#[track_caller]
fn assert_audited(env: &Env, user: &str, action: &str, target: &[&str], kind: &str, message: &[&str]) {
    let entries = env.audit_of(user, action);
    assert!(
        entries.iter().any(|(t, k, m)| k == kind
            && target.iter().all(|p| t.contains(p))
            && message.iter().all(|p| m.contains(p))),
        "no {kind} {action} of {user} with {target:?} / {message:?} in {entries:#?}"
    );
}

/// The error's message: `detail.message` (a lab refusal) or `detail` (every other).
fn detail(v: &Value) -> String {
    match &v["detail"] {
        Value::String(s) => s.clone(),
        d => d["message"].as_str().map_or_else(|| d.to_string(), str::to_string),
    }
}

/// (a): `c` does `method path body`, refused with `status`; its message contains every
/// `message` part. Returns the answer.
async fn refused(
    c: &WebClient,
    method: Method,
    path: &str,
    body: Option<Value>,
    status: StatusCode,
    message: &[&str],
) -> Value {
    let (st, v) = c.req(method.clone(), path, body).await;
    assert_eq!(st, status, "{method} {path}: {v}");
    let d = detail(&v);
    assert!(message.iter().all(|p| d.contains(p)), "{method} {path}: {d:?} does not name {message:?}");
    v
}

/// A target prefix of this station's audit entries: `station/what`.
fn on(what: &str) -> String {
    format!("{STATION}/{what}")
}

#[tokio::test]
async fn class3_a_student_stays_within_the_student_limits() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    assert_eq!(s.book_now(env.now()).await.0, StatusCode::OK);

    // A jog renewed for as long as the student likes stops at the student range (z: 0.14 m;
    // the machine's is 0.15), not at the machine's.
    let t0 = Instant::now();
    let mut at_range: Option<Instant> = None;
    let mut highest = f64::MIN;
    loop {
        let (st, v) = s.post("/api/axes/z/jog", json!({ "direction": 1, "speed": 0.04 })).await;
        assert_eq!(st, StatusCode::OK, "{v}");
        let z = s.position("z").await;
        highest = highest.max(z);
        if z > 0.14 - TOLERANCE
            && at_range.get_or_insert_with(Instant::now).elapsed() > Duration::from_secs(1)
        {
            break;
        }
        assert!(t0.elapsed().as_secs_f64() < LIVENESS, "the jog did not reach the student range: {z}");
        tokio::time::sleep(Duration::from_millis(150)).await;
    }
    let before = still(&s).await;
    highest = highest.max(s.position("z").await);
    assert!(highest <= 0.14 + TOLERANCE, "the jog passed the student range: {highest}");

    // Beyond the student range (0.55 m), within the machine's (0.6 m).
    let v = refused(
        &s,
        Method::POST,
        "/api/axes/x/move",
        Some(json!({ "target": 0.58, "speed": 0.05 })),
        StatusCode::FORBIDDEN,
        &["x: position 0.58 is outside the student range [0, 0.55]"],
    )
    .await;
    assert_eq!(v["detail"]["reason"]["reason"], "position_limit", "{v}");
    // Beyond the student speed (0.08 m/s; the machine's is 0.1), on a move and on a jog.
    let v = refused(
        &s,
        Method::POST,
        "/api/axes/x/move",
        Some(json!({ "target": 0.1, "speed": 0.09 })),
        StatusCode::FORBIDDEN,
        &["x:", "0.09 exceeds the student limit 0.08"],
    )
    .await;
    assert_eq!(v["detail"]["reason"]["reason"], "motion_limit", "{v}");
    refused(
        &s,
        Method::POST,
        "/api/axes/y/jog",
        Some(json!({ "direction": 1, "speed": 0.09 })),
        StatusCode::FORBIDDEN,
        &["y:", "0.09 exceeds the student limit 0.08"],
    )
    .await;
    // A group go-to with one member beyond its student range (y: 0.38 m): the whole command.
    refused(
        &s,
        Method::POST,
        "/api/groups/cnc",
        Some(json!({ "action": "go_to", "targets": [0.03, 0.39, 0.01] })),
        StatusCode::FORBIDDEN,
        &["y: position 0.39 is outside the student range [0, 0.38]"],
    )
    .await;
    assert_unchanged(&s, &before, "refused student moves").await;

    let move_ = "command.axis.move";
    assert_audited(&env, "student", move_, &[&on("x move to=0.58 speed=0.05")], "denied", &["[0, 0.55]"]);
    assert_audited(&env, "student", move_, &[&on("x move to=0.1 speed=0.09")], "denied", &["0.08"]);
    assert_audited(&env, "student", "command.axis.jog", &[&on("y jog speed=0.09")], "denied", &["0.08"]);
    assert_audited(&env, "student", move_, &[&on("y move to=0.39")], "denied", &["[0, 0.38]"]);
}

#[tokio::test]
async fn class4_a_program_beyond_the_student_limits_is_refused_before_it_runs() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    assert_eq!(s.book_now(env.now()).await.0, StatusCode::OK);
    // X 500 mm is inside the student range, F1000000 (16.7 m/s) far beyond 0.08 m/s; Z 145
    // mm is inside the machine's travel (0.15 m), beyond the student range (0.14 m).
    for (name, text) in
        [("fast.ngc", "G21 G90\nG1 X500 F1000000\nM2\n"), ("deep.ngc", "G21 G90\nG1 Z145 F600\nM2\n")]
    {
        let (st, r) = s.post("/api/programs", json!({ "name": name, "text": text })).await;
        assert_eq!(st, StatusCode::OK, "{r}");
        assert_eq!(r["check"]["errors"], json!([]), "{name}: within the machine: {r}");
    }
    let before = still(&s).await;
    let v = refused(
        &s,
        Method::POST,
        "/api/programs/fast.ngc/run",
        None,
        StatusCode::FORBIDDEN,
        &["x:", "exceeds the student limit 0.08"],
    )
    .await;
    assert_eq!(v["detail"]["reason"]["reason"], "motion_limit", "{v}");
    let v = refused(
        &s,
        Method::POST,
        "/api/programs/deep.ngc/run",
        None,
        StatusCode::FORBIDDEN,
        &["z:", "0.145", "student range [0, 0.14]"],
    )
    .await;
    assert_eq!(v["detail"]["reason"]["reason"], "position_limit", "{v}");
    assert_unchanged(&s, &before, "refused programs").await;
    assert_eq!(before.program.0, "idle", "no program ran: {before:?}");

    let run = "command.run_program";
    assert_audited(&env, "student", run, &["(fast.ngc) demands: x [0.5, 0.5] v 16.6"], "denied", &["0.08"]);
    assert_audited(
        &env,
        "student",
        run,
        &["(deep.ngc) demands: ", "z [0.145, 0.145]"],
        "denied",
        &["[0, 0.14]"],
    );
}

#[tokio::test]
async fn class5_an_axis_without_student_limits_is_not_a_students_to_move() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    assert_eq!(s.book_now(env.now()).await.0, StatusCode::OK);
    let before = still(&s).await;
    let why = "no student limits";
    refused(
        &s,
        Method::POST,
        "/api/axes/w/move",
        Some(json!({ "target": 0.01, "speed": 0.01 })),
        StatusCode::FORBIDDEN,
        &["w:", why],
    )
    .await;
    refused(
        &s,
        Method::POST,
        "/api/axes/w/jog",
        Some(json!({ "direction": 1, "speed": 0.01 })),
        StatusCode::FORBIDDEN,
        &["w:", why],
    )
    .await;
    refused(&s, Method::POST, "/api/axes/w/home", None, StatusCode::FORBIDDEN, &["axis w", why]).await;
    assert_unchanged(&s, &before, "refused commands on w").await;
    assert_audited(
        &env,
        "student",
        "command.axis.move",
        &[&on("w move to=0.01 speed=0.01")],
        "denied",
        &[why],
    );
    assert_audited(&env, "student", "command.axis.jog", &[&on("w jog speed=0.01")], "denied", &[why]);
    assert_audited(&env, "student", "command.axis.home", &[&on("w home")], "denied", &[why]);

    // The administrator moves it (so the refusals above were about the student).
    let a = env.login("admin", ADMIN_PW).await;
    let (st, v) = a.post("/api/axes/w/move", json!({ "target": 0.01, "speed": 0.01 })).await;
    assert_eq!(st, StatusCode::OK, "{v}");
    assert!(wait_for(LIVENESS, || async { (a.position("w").await - 0.01).abs() < TOLERANCE }).await);
}

#[tokio::test]
async fn class6_a_student_cannot_reset_an_estop_an_admin_pressed() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    let a = env.login("admin", ADMIN_PW).await;
    assert_eq!(s.book_now(env.now()).await.0, StatusCode::OK);
    // The student presses first, the administrator a moment later: the stop is the
    // administrator's now.
    assert_eq!(s.post0("/api/estop").await.0, StatusCode::OK);
    assert_eq!(a.post0("/api/estop").await.0, StatusCode::OK);
    let before = still(&s).await;
    assert!(before.estop);
    refused(
        &s,
        Method::POST,
        "/api/reset",
        None,
        StatusCode::FORBIDDEN,
        &["pressed by admin (admin)", "only an administrator can reset it"],
    )
    .await;
    // The slot holder cannot move past it either.
    refused(
        &s,
        Method::POST,
        "/api/axes/x/move",
        Some(json!({ "target": 0.05, "speed": 0.05 })),
        StatusCode::CONFLICT,
        &["emergency stop active"],
    )
    .await;
    assert_unchanged(&s, &before, "a student's reset of an admin's E-stop").await;
    assert_audited(&env, "student", "command.reset_fault", &[STATION], "denied", &["only an administrator"]);
    assert_audited(
        &env,
        "student",
        "command.axis.move",
        &[&on("x move to=0.05")],
        "error",
        &["emergency stop"],
    );
    // The administrator resets it.
    assert_eq!(a.post0("/api/reset").await.0, StatusCode::OK);
    assert!(!machine(&s).await.estop);
}

#[tokio::test]
async fn class8_students_cannot_see_check_or_run_other_users_programs() {
    let env = Env::new();
    let a = env.login("admin", ADMIN_PW).await;
    let s = env.login("student", STUDENT_PW).await;
    let s2 = env.login("student2", STUDENT_PW).await;
    let text = json!("G21 G90\nG1 X20 Y10 F1200\nG1 X0 Y0\nM2\n");
    let (st, r) = a.post("/api/programs", json!({ "name": "secret.ngc", "text": text })).await;
    assert_eq!(st, StatusCode::OK, "{r}");
    assert_eq!(s.book_now(env.now()).await.0, StatusCode::OK);
    let (st, r) = s.post("/api/programs", json!({ "name": "mine.ngc", "text": text })).await;
    assert_eq!(st, StatusCode::OK, "{r}");
    // Listing: each sees their own only.
    let names = |v: Value| -> Vec<String> {
        v.as_array().unwrap().iter().map(|p| p["name"].as_str().unwrap().to_string()).collect()
    };
    assert_eq!(names(s.get("/api/programs").await.1), ["mine.ngc"]);
    assert!(names(s2.get("/api/programs").await.1).is_empty());
    let before = still(&s).await;
    // Another user's program is not found (whether it exists is not told).
    for what in ["check", "run"] {
        let path = format!("/api/programs/mine.ngc/{what}");
        refused(&s2, Method::POST, &path, None, StatusCode::NOT_FOUND, &["no program \"mine.ngc\""]).await;
        let path = format!("/api/programs/secret.ngc/{what}");
        refused(&s, Method::POST, &path, None, StatusCode::NOT_FOUND, &["no program \"secret.ngc\""]).await;
    }
    assert_unchanged(&s, &before, "other users' programs").await;
    for action in ["command.check_program", "command.run_program"] {
        assert_audited(&env, "student2", action, &["(mine.ngc)"], "denied", &["404", "no program"]);
        assert_audited(&env, "student", action, &["(secret.ngc)"], "denied", &["404", "no program"]);
    }
}

#[tokio::test]
async fn class10_refusals_before_authorisation_are_audited_with_the_user() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    assert_eq!(s.book_now(env.now()).await.0, StatusCode::OK);
    let before = still(&s).await;
    let go = json!({ "action": "go_to", "targets": [0.1, 0.1, 0.0] });
    let mv = json!({ "target": 0.01, "speed": 0.05 });
    refused(&s, Method::POST, "/api/axes/nope/move", Some(mv), StatusCode::NOT_FOUND, &["no axis \"nope\""])
        .await;
    refused(&s, Method::POST, "/api/groups/robot", Some(go), StatusCode::NOT_FOUND, &["no group \"robot\""])
        .await;
    refused(&s, Method::POST, "/api/programs/nope.ngc/run", None, StatusCode::NOT_FOUND, &["no program"])
        .await;
    refused(&s, Method::POST, "/api/nowhere", None, StatusCode::NOT_FOUND, &[]).await;
    assert_unchanged(&s, &before, "refusals before authorisation").await;
    assert_audited(&env, "student", "request", &["POST /api/axes/nope/move"], "error", &["404", "no axis"]);
    assert_audited(&env, "student", "request", &["POST /api/groups/robot"], "error", &["404", "no group"]);
    assert_audited(&env, "student", "request", &["POST /api/nowhere"], "error", &["404"]);
    assert_audited(&env, "student", "command.run_program", &["(nope.ngc)"], "denied", &["404", "no program"]);
}

#[tokio::test]
async fn class13_a_websocket_from_another_origin_is_refused_and_audited() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    assert_eq!(s.book_now(env.now()).await.0, StatusCode::OK);
    let before = still(&s).await;
    let cookie = s.cookie.clone().unwrap();
    // A page elsewhere under a rebound DNS name: its Host matches its Origin.
    let evil = format!("evil.example:{}", env.handle.addr().port());
    assert_eq!(env.ws_upgrade(&cookie, &format!("http://{evil}"), &evil).await, StatusCode::FORBIDDEN);
    assert_unchanged(&s, &before, "a WebSocket from another origin").await;
    assert_audited(&env, "student", "websocket", &[], "denied", &["evil.example", "not allowed"]);
    // The station's own page is served.
    let here = env.handle.addr().to_string();
    assert_eq!(
        env.ws_upgrade(&cookie, &format!("http://{here}"), &here).await,
        StatusCode::SWITCHING_PROTOCOLS
    );
}

#[tokio::test]
async fn viewers_cannot_check_or_run_programs_nor_command() {
    let env = Env::new();
    let a = env.login("admin", ADMIN_PW).await;
    let v = env.login("viewer", VIEWER_PW).await;
    let text = json!("G21 G90\nG1 X20 Y10 F1200\nG1 X0 Y0\nM2\n");
    let (st, r) = a.post("/api/programs", json!({ "name": "public.ngc", "text": text })).await;
    assert_eq!(st, StatusCode::OK, "{r}");
    assert_eq!(a.post0("/api/programs/public.ngc/publish").await.0, StatusCode::OK);
    // The viewer sees the published program ...
    assert_eq!(v.get("/api/programs").await.1[0]["name"], "public.ngc");
    let before = still(&v).await;
    // ... and can neither check nor run it, nor command the machine.
    let programs = "viewers cannot check or run programs";
    refused(&v, Method::POST, "/api/programs/public.ngc/check", None, StatusCode::FORBIDDEN, &[programs])
        .await;
    refused(&v, Method::POST, "/api/programs/public.ngc/run", None, StatusCode::FORBIDDEN, &[programs]).await;
    let role = "role viewer may not do this";
    let mv = json!({ "target": 0.05, "speed": 0.05 });
    refused(&v, Method::POST, "/api/axes/x/move", Some(mv), StatusCode::FORBIDDEN, &[role]).await;
    refused(&v, Method::POST, "/api/axes/x/home", None, StatusCode::FORBIDDEN, &[role]).await;
    let go = json!({ "action": "go_to", "targets": [0.03, 0.02, 0.01] });
    refused(&v, Method::POST, "/api/groups/cnc", Some(go), StatusCode::FORBIDDEN, &[role]).await;
    let upload = json!({ "name": "mine.ngc", "text": text });
    refused(&v, Method::POST, "/api/programs", Some(upload), StatusCode::FORBIDDEN, &[role]).await;
    refused(&v, Method::POST, "/api/reset", None, StatusCode::FORBIDDEN, &[role]).await;
    assert_unchanged(&v, &before, "a viewer's commands").await;
    assert_audited(&env, "viewer", "command.check_program", &["(public.ngc)"], "denied", &[programs]);
    assert_audited(&env, "viewer", "command.run_program", &["(public.ngc)"], "denied", &[programs]);
    assert_audited(
        &env,
        "viewer",
        "command.axis.move",
        &[&on("x move to=0.05 speed=0.05")],
        "denied",
        &[role],
    );
    assert_audited(&env, "viewer", "command.axis.home", &[&on("x home")], "denied", &[role]);
    assert_audited(&env, "viewer", "command.axis.move", &[&on("x move to=0.03")], "denied", &[role]);
    assert_audited(&env, "viewer", "command.upload", &[&on("mine.ngc")], "denied", &[role]);
    assert_audited(&env, "viewer", "command.reset_fault", &[STATION], "denied", &[role]);
}

#[tokio::test]
async fn a_student_cannot_command_outside_their_slot() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    let s2 = env.login("student2", STUDENT_PW).await;
    let before = still(&s).await;
    // No slot at all.
    let mv = json!({ "target": 0.05, "speed": 0.05 });
    let none = "no reservation of yours";
    refused(&s, Method::POST, "/api/axes/x/move", Some(mv.clone()), StatusCode::FORBIDDEN, &[none]).await;
    assert_unchanged(&s, &before, "a move without a slot").await;
    assert_audited(
        &env,
        "student",
        "command.axis.move",
        &[&on("x move to=0.05 speed=0.05")],
        "denied",
        &[none],
    );

    // In someone else's slot, with that student's E-stop pressed.
    let (st, r) = s2.book_now(env.now()).await;
    assert_eq!(st, StatusCode::OK, "{r}");
    let slot = r["id"].as_i64().unwrap();
    assert_eq!(s2.post0("/api/estop").await.0, StatusCode::OK);
    let before = still(&s).await;
    let theirs = "reserved by student2 now";
    let jog = json!({ "direction": 1, "speed": 0.01 });
    let go = json!({ "action": "go_to", "targets": [0.03, 0.02, 0.01] });
    let upload = json!({ "name": "mine.ngc", "text": "G0 X10\n" });
    refused(&s, Method::POST, "/api/axes/x/move", Some(mv), StatusCode::FORBIDDEN, &[theirs]).await;
    refused(&s, Method::POST, "/api/axes/y/jog", Some(jog), StatusCode::FORBIDDEN, &[theirs]).await;
    refused(&s, Method::POST, "/api/axes/z/home", None, StatusCode::FORBIDDEN, &[theirs]).await;
    refused(&s, Method::POST, "/api/groups/cnc", Some(go), StatusCode::FORBIDDEN, &[theirs]).await;
    refused(&s, Method::POST, "/api/programs", Some(upload), StatusCode::FORBIDDEN, &[theirs]).await;
    refused(&s, Method::POST, "/api/reset", None, StatusCode::FORBIDDEN, &[theirs]).await;
    // Nor can the student end the other's slot.
    let cancel = format!("/api/reservations/{slot}");
    refused(&s, Method::DELETE, &cancel, None, StatusCode::FORBIDDEN, &["belongs to student2"]).await;
    assert_unchanged(&s, &before, "commands in someone else's slot").await;
    assert!(before.estop, "student2's E-stop stands");
    let denied =
        |action: &str, target: &str| assert_audited(&env, "student", action, &[target], "denied", &[theirs]);
    denied("command.axis.move", &on("x move to=0.05 speed=0.05"));
    denied("command.axis.jog", &on("y jog speed=0.01"));
    denied("command.axis.home", &on("z home"));
    denied("command.axis.move", &on("x move to=0.03"));
    denied("command.upload", &on("mine.ngc"));
    denied("command.reset_fault", STATION);
    assert_audited(
        &env,
        "student",
        "cancel_reservation",
        &["of student2"],
        "denied",
        &["belongs to student2"],
    );
    // The slot is still student2's, who resets their own stop.
    assert_eq!(s2.post0("/api/reset").await.0, StatusCode::OK);
}

#[tokio::test]
async fn a_student_cannot_jog_or_move_an_axis_that_is_not_homed() {
    let env = Env::unhomed();
    let s = env.login("student", STUDENT_PW).await;
    assert_eq!(s.book_now(env.now()).await.0, StatusCode::OK);
    let before = still(&s).await;
    assert!(before.axes.iter().all(|a| !a.3), "not homed: {before:?}");
    // The student range cannot be kept without a position reference.
    let jog = json!({ "direction": 1, "speed": 0.02 });
    refused(
        &s,
        Method::POST,
        "/api/axes/x/jog",
        Some(jog),
        StatusCode::CONFLICT,
        &["axis x is not homed", "home it first"],
    )
    .await;
    let mv = json!({ "target": 0.1, "speed": 0.05 });
    refused(&s, Method::POST, "/api/axes/y/move", Some(mv), StatusCode::CONFLICT, &["axis y is not homed"])
        .await;
    assert_unchanged(&s, &before, "commands on axes that are not homed").await;
    assert_audited(&env, "student", "command.axis.jog", &[&on("x jog speed=0.02")], "error", &["not homed"]);
    assert_audited(
        &env,
        "student",
        "command.axis.move",
        &[&on("y move to=0.1 speed=0.05")],
        "error",
        &["not homed"],
    );
    // What the student may do: home it, then jog.
    assert_eq!(s.post0("/api/axes/x/home").await.0, StatusCode::OK);
    assert!(wait_for(LIVENESS, || async { s.axis("x").await["homed"] == true }).await, "x homed");
    let (st, v) = s.post("/api/axes/x/jog", json!({ "direction": 1, "speed": 0.02 })).await;
    assert_eq!(st, StatusCode::OK, "{v}");
}

#[tokio::test]
async fn malformed_and_oversized_move_bodies_are_refused_and_audited() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    assert_eq!(s.book_now(env.now()).await.0, StatusCode::OK);
    let before = still(&s).await;
    let send = |body: String, content_type: &'static str| {
        // A client per request: the server closes the connection of a refused large body.
        reqwest::Client::new()
            .post(format!("{}/api/axes/x/move", s.base))
            .header("Cookie", s.cookie.clone().unwrap())
            .header("X-CSRF-Token", s.csrf.clone().unwrap())
            .header("Content-Type", content_type)
            .body(body)
            .send()
    };
    let json_ = "application/json";
    let cases: Vec<(String, &str, &str)> = vec![
        (r#"{"target": 0.01, "speed""#.into(), json_, "parse the request body as JSON"),
        (r#"{"target": 0.01, "speed": 0.05}"#.into(), "text/plain", "Content-Type: application/json"),
        (r#"{"target": 0.01, "speed": 0.05, "pad": 1}"#.into(), json_, "unknown field `pad`"),
        (r#"{"target": "0.01", "speed": 0.05}"#.into(), json_, "invalid type"),
        (r#"{"target": 0.01}"#.into(), json_, "missing field `speed`"),
        (r#"{"target": 1e400, "speed": 0.05}"#.into(), json_, "number out of range"),
        (
            format!(r#"{{"target": 0.01, "speed": 0.05, "pad": "{}"}}"#, "x".repeat(3 << 20)),
            json_,
            "length limit",
        ),
    ];
    for (body, content_type, why) in &cases {
        let r = send(body.clone(), content_type).await.unwrap();
        assert_eq!(r.status(), StatusCode::BAD_REQUEST, "{why}");
        let v: Value = r.json().await.unwrap();
        assert_eq!(v["error"], "invalid", "{v}");
        assert!(detail(&v).contains(why), "{why}: {v}");
    }
    // Well-formed, but the numbers are not a motion.
    let neg = json!({ "target": 0.01, "speed": -0.05 });
    refused(&s, Method::POST, "/api/axes/x/move", Some(neg), StatusCode::BAD_REQUEST, &["speed", "-0.05"])
        .await;
    let half = json!({ "direction": 0.5, "speed": 0.01 });
    refused(&s, Method::POST, "/api/axes/x/jog", Some(half), StatusCode::BAD_REQUEST, &["direction", "0.5"])
        .await;
    assert_unchanged(&s, &before, "bad bodies").await;
    let entries: Vec<_> = env
        .audit_of("student", "request")
        .into_iter()
        .filter(|(t, _, _)| t == "POST /api/axes/x/move")
        .collect();
    assert_eq!(entries.len(), cases.len(), "{entries:#?}");
    for (_, _, why) in &cases {
        assert!(
            entries.iter().any(|(_, k, m)| k == "error" && m.starts_with("400 invalid") && m.contains(why)),
            "{why}: {entries:#?}"
        );
    }
    assert_audited(
        &env,
        "student",
        "command.axis.move",
        &[&on("x move to=0.01 speed=-0.05")],
        "error",
        &["speed"],
    );
    assert_audited(&env, "student", "command.axis.jog", &[&on("x jog speed=0.01")], "error", &["direction"]);
}

#[tokio::test]
async fn a_student_resets_their_own_estop() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    let s2 = env.login("student2", STUDENT_PW).await;
    assert_eq!(s.book_now(env.now()).await.0, StatusCode::OK);
    // In motion, the student presses the E-stop: the axis stops, the stop is the student's.
    let (st, v) = s.post("/api/axes/x/move", json!({ "target": 0.5, "speed": 0.08 })).await;
    assert_eq!(st, StatusCode::OK, "{v}");
    assert!(wait_for(LIVENESS, || async { s.axis("x").await["moving"] == true }).await, "x moves");
    assert_eq!(s.post0("/api/estop").await.0, StatusCode::OK);
    let stopped = still(&s).await;
    assert!(stopped.estop);
    let (_, safety) = s.get("/api/safety").await;
    assert!(
        safety["diagnosis"].as_str().unwrap().contains("emergency stop by student (student)"),
        "{safety}"
    );
    let (st, v) = s.post0("/api/reset").await;
    assert_eq!(st, StatusCode::OK, "{v}");
    assert!(!machine(&s).await.estop);
    assert_audited(&env, "student", "command.estop", &[STATION], "ok", &[]);
    assert_audited(&env, "student", "command.reset_fault", &[STATION], "ok", &[]);
    // Another student's stop during the slot: the slot holder resets it (the machine stays
    // remotely recoverable).
    assert_eq!(s2.post0("/api/estop").await.0, StatusCode::OK);
    assert!(machine(&s).await.estop);
    assert_eq!(s.post0("/api/reset").await.0, StatusCode::OK);
    // And commands again.
    let (st, v) = s.post("/api/axes/x/move", json!({ "target": 0.05, "speed": 0.08 })).await;
    assert_eq!(st, StatusCode::OK, "{v}");
    assert!(
        wait_for(LIVENESS, || async {
            let x = s.axis("x").await;
            (x["position"].as_f64().unwrap() - 0.05).abs() < TOLERANCE && x["moving"] == false
        })
        .await,
        "x back at 0.05"
    );
}

#[tokio::test]
async fn a_student_checks_and_runs_their_own_and_a_published_program() {
    let env = Env::new();
    let a = env.login("admin", ADMIN_PW).await;
    let s = env.login("student", STUDENT_PW).await;
    let text = json!("G21 G90\nG1 X20 Y10 F1200\nG1 X0 Y0\nM2\n");
    let (st, r) = a.post("/api/programs", json!({ "name": "public.ngc", "text": text })).await;
    assert_eq!(st, StatusCode::OK, "{r}");
    assert_eq!(a.post0("/api/programs/public.ngc/publish").await.0, StatusCode::OK);
    assert_eq!(s.book_now(env.now()).await.0, StatusCode::OK);
    let (st, r) = s.post("/api/programs", json!({ "name": "mine.ngc", "text": text })).await;
    assert_eq!(st, StatusCode::OK, "{r}");
    for id in ["mine.ngc", "public.ngc"] {
        let (st, check) = s.post0(&format!("/api/programs/{id}/check")).await;
        assert_eq!(st, StatusCode::OK, "{check}");
        assert_eq!(check["errors"], json!([]), "{check}");
        assert_audited(
            &env,
            "student",
            "command.check_program",
            &[&format!("({id}) demands: x [0, 0.02]")],
            "ok",
            &[],
        );
        let (st, v) = s.post0(&format!("/api/programs/{id}/run")).await;
        assert_eq!(st, StatusCode::OK, "{id}: {v}");
        // It starts (and, the path being short, ends).
        assert!(
            wait_for(LIVENESS, || async {
                let p = s.get("/api/programs/status").await.1;
                p["program"] == id && (p["state"] == "running" || p["state"] == "done")
            })
            .await,
            "{id}: {}",
            s.get("/api/programs/status").await.1
        );
        assert!(
            wait_for(LIVENESS, || async { s.get("/api/programs/status").await.1["state"] == "done" }).await,
            "{id}: {}",
            s.get("/api/programs/status").await.1
        );
        assert_audited(
            &env,
            "student",
            "command.run_program",
            &[&format!("({id}) demands: x [0, 0.02]")],
            "ok",
            &[],
        );
    }
}
