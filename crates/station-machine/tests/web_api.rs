//! The web API on the real station machine (small simulated cell, lab `MemoryStore`, an
//! injectable clock): login, sessions, the limiter, CSRF, roles, slots, student limits,
//! safety, programs, slot cleanup, users and audit, groups, scene, signals and the camera.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::time::Duration;

use common::web::{wait_for, Env, ADMIN_PW, STUDENT_PW, VIEWER_PW};
use motus_station_web::MachineBackend;
use reqwest::{Method, StatusCode};
use serde_json::{json, Value};

/// Generous liveness time-out for motion on a loaded host (seconds).
const MOTION: f64 = 30.0;

#[tokio::test]
async fn login_cookie_session_and_logout() {
    let env = Env::new();
    let c = env.client();
    // Wrong password: 401, audited as a denied login.
    let r = c
        .raw(
            Method::POST,
            "/api/login",
            Some(json!({ "user": "student", "password": "nope-nope-nope" })),
            None,
        )
        .await;
    assert_eq!(r.status(), StatusCode::UNAUTHORIZED);
    let body: Value = r.json().await.unwrap();
    assert_eq!(body["error"], "bad_credentials");
    // Right password: cookie with the required attributes (Secure configured off).
    let r = c
        .raw(Method::POST, "/api/login", Some(json!({ "user": "student", "password": STUDENT_PW })), None)
        .await;
    assert_eq!(r.status(), StatusCode::OK);
    let sc = r.headers()[reqwest::header::SET_COOKIE].to_str().unwrap().to_string();
    assert!(sc.starts_with("motus_session="), "{sc}");
    assert!(sc.contains("HttpOnly") && sc.contains("SameSite=Strict") && !sc.contains("Secure"), "{sc}");
    let body: Value = r.json().await.unwrap();
    assert_eq!(body["role"], "student");
    assert_eq!(body["csrf_token"].as_str().unwrap().len(), 64);

    let mut c = env.client();
    c.login("student", STUDENT_PW).await;
    let (st, s) = c.get("/api/session").await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(s["user"], "student");
    assert_eq!(s["csrf_token"], json!(c.csrf.clone().unwrap()));
    assert_eq!(s["can_command"], false, "no slot yet");
    let (st, _) = c.post0("/api/logout").await;
    assert_eq!(st, StatusCode::OK);
    let (st, e) = c.get("/api/session").await;
    assert_eq!(st, StatusCode::UNAUTHORIZED);
    assert_eq!(e["error"], "not_logged_in");
    // Not logged in at all: 401 on every API route.
    let (st, _) = env.client().get("/api/axes").await;
    assert_eq!(st, StatusCode::UNAUTHORIZED);
    let audit = env.audit();
    assert!(audit.iter().any(|(u, a, k, _)| u == "student" && a == "login" && k == "denied"));
    assert!(audit.iter().any(|(u, a, k, _)| u == "student" && a == "logout" && k == "ok"));
}

#[tokio::test]
async fn sessions_expire_idle_and_absolute() {
    let env = Env::with(|c| {
        c.sessions.idle_timeout_secs = 60;
        c.sessions.absolute_timeout_secs = 300;
        c.sessions.touch_interval_secs = 1;
    });
    let c = env.login("student", STUDENT_PW).await;
    env.clock.advance(Duration::from_secs(59));
    assert_eq!(c.get("/api/session").await.0, StatusCode::OK, "59 s idle: still valid (and touched)");
    env.clock.advance(Duration::from_secs(61));
    let (st, e) = c.get("/api/session").await;
    assert_eq!(st, StatusCode::UNAUTHORIZED, "61 s idle: expired");
    assert!(e["detail"].as_str().unwrap().contains("expired"), "{e}");

    // Absolute expiry even when active: 5 x 59 s = 295 s fine, 354 s not.
    let c = env.login("student", STUDENT_PW).await;
    for _ in 0..5 {
        env.clock.advance(Duration::from_secs(59));
        assert_eq!(c.get("/api/axes").await.0, StatusCode::OK);
    }
    env.clock.advance(Duration::from_secs(59));
    assert_eq!(c.get("/api/axes").await.0, StatusCode::UNAUTHORIZED);
}

#[tokio::test]
async fn login_is_rate_limited() {
    let env = Env::with(|c| {
        c.limiter.user_max_failures = 3;
        c.limiter.lockout_secs = 60;
    });
    let mut c = env.client();
    for _ in 0..3 {
        assert_eq!(c.login("student", "wrong-password-x").await.0, StatusCode::UNAUTHORIZED);
    }
    // Locked: even the right password is refused, with Retry-After.
    let r = c
        .raw(Method::POST, "/api/login", Some(json!({ "user": "student", "password": STUDENT_PW })), None)
        .await;
    assert_eq!(r.status(), StatusCode::TOO_MANY_REQUESTS);
    let retry: u64 = r.headers()[reqwest::header::RETRY_AFTER].to_str().unwrap().parse().unwrap();
    assert!((1..=60).contains(&retry), "{retry}");
    let body: Value = r.json().await.unwrap();
    assert_eq!(body["error"], "rate_limited");
    env.clock.advance(Duration::from_secs(61));
    assert_eq!(c.login("student", STUDENT_PW).await.0, StatusCode::OK);
    assert!(env.audit().iter().any(|(_, a, k, m)| a == "login" && k == "denied" && m.contains("too many")));
}

#[tokio::test]
async fn csrf_token_is_required_on_mutations() {
    let env = Env::new();
    let c = env.login("admin", ADMIN_PW).await;
    let r = c.raw(Method::POST, "/api/estop", None, None).await;
    assert_eq!(r.status(), StatusCode::FORBIDDEN);
    assert_eq!(r.json::<Value>().await.unwrap()["error"], "csrf");
    let r = c.raw(Method::POST, "/api/estop", None, Some("0000")).await;
    assert_eq!(r.status(), StatusCode::FORBIDDEN);
    assert!(!env.backend.safety().estop, "nothing happened");
    assert_eq!(c.post0("/api/estop").await.0, StatusCode::OK);
    assert!(env.backend.safety().estop);
    let denied =
        env.audit().into_iter().filter(|(u, a, k, _)| u == "admin" && a == "csrf" && k == "denied").count();
    assert_eq!(denied, 2);
}

#[tokio::test]
async fn viewer_cannot_command_and_is_audited() {
    let env = Env::new();
    let c = env.login("viewer", VIEWER_PW).await;
    assert_eq!(c.get("/api/axes").await.0, StatusCode::OK, "viewers see");
    let (st, e) = c.post("/api/axes/x/jog", json!({ "direction": 1, "speed": 0.01 })).await;
    assert_eq!(st, StatusCode::FORBIDDEN, "{e}");
    assert_eq!(e["detail"]["reason"]["reason"], "role_too_low");
    assert_eq!(c.post0("/api/estop").await.0, StatusCode::FORBIDDEN);
    assert_eq!(c.book_now(env.now()).await.0, StatusCode::FORBIDDEN);
    let audit = env.audit();
    assert!(audit.iter().any(|(u, a, k, _)| u == "viewer" && a == "command.axis.jog" && k == "denied"));
    assert!(audit.iter().any(|(u, a, k, _)| u == "viewer" && a == "command.estop" && k == "denied"));
    tokio::time::sleep(Duration::from_millis(300)).await;
    let x = c.axis("x").await;
    assert!(
        x["position"].as_f64().unwrap().abs() < 1e-5 && x["moving"] == false,
        "the axis did not move: {x}"
    );
    assert!(!env.backend.safety().estop);
}

#[tokio::test]
async fn students_command_only_in_their_own_slot() {
    let env = Env::new();
    let s1 = env.login("student", STUDENT_PW).await;
    let s2 = env.login("student2", STUDENT_PW).await;
    let mv = json!({ "target": 0.05, "speed": 0.05 });
    // Outside any slot.
    let (st, e) = s1.post("/api/axes/x/move", mv.clone()).await;
    assert_eq!(st, StatusCode::FORBIDDEN, "{e}");
    assert_eq!(e["detail"]["reason"]["reason"], "not_slot_holder");
    // Book and command.
    let (st, r) = s1.book_now(env.now()).await;
    assert_eq!(st, StatusCode::OK, "{r}");
    assert_eq!(s1.get("/api/session").await.1["can_command"], true);
    let (st, e) = s1.post("/api/axes/x/move", mv.clone()).await;
    assert_eq!(st, StatusCode::OK, "{e}");
    assert!(
        wait_for(MOTION, || async {
            let a = s1.axis("x").await;
            (a["position"].as_f64().unwrap() - 0.05).abs() < 1e-5 && a["moving"] == false
        })
        .await
    );
    // Someone else's slot: refused, naming the holder; booking over it: 409.
    let (st, e) = s2.post("/api/axes/y/move", mv.clone()).await;
    assert_eq!(st, StatusCode::FORBIDDEN);
    assert_eq!(e["detail"]["reason"]["holder"], "student");
    let (st, e) = s2.book_now(env.now()).await;
    assert_eq!(st, StatusCode::CONFLICT, "{e}");
    assert_eq!(e["error"], "slot_conflict");
    // A student cannot book for someone else.
    let (st, _) = s2
        .post(
            "/api/reservations",
            json!({ "start": env.now().0 + 3_600_000, "end": env.now().0 + 5_400_000, "user": "student" }),
        )
        .await;
    assert_eq!(st, StatusCode::FORBIDDEN);
    // Above the student speed limit (0.08 m/s; the axis allows 0.1): refused by the lab.
    let (st, e) = s1.post("/api/axes/x/move", json!({ "target": 0.1, "speed": 0.09 })).await;
    assert_eq!(st, StatusCode::FORBIDDEN, "{e}");
    assert_eq!(e["detail"]["reason"]["reason"], "motion_limit");
    // Beyond the student range (0.55 m; the axis reaches 0.6): refused too.
    let (st, e) = s1.post("/api/axes/x/move", json!({ "target": 0.58, "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::FORBIDDEN, "{e}");
    // An axis without a student table: not a student's to move (fail closed).
    let (st, e) = s1.post("/api/axes/w/move", json!({ "target": 0.01, "speed": 0.01 })).await;
    assert_eq!(st, StatusCode::FORBIDDEN, "{e}");
    // Invalid numbers: 400.
    let (st, e) = s1.post("/api/axes/x/move", json!({ "target": 9.0, "speed": 0.05 })).await;
    assert!(st == StatusCode::BAD_REQUEST || st == StatusCode::FORBIDDEN, "{st} {e}");
    let (st, _) = s1.post("/api/axes/x/move", json!({ "target": "a", "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::BAD_REQUEST);
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert!((s1.position("x").await - 0.05).abs() < 1e-5, "refused moves moved nothing");
    assert!(s1.position("w").await.abs() < 1e-5);
    // After the slot: refused again.
    env.clock.advance(Duration::from_secs(31 * 60));
    let s1 = env.login("student", STUDENT_PW).await;
    let (st, _) = s1.post("/api/axes/x/move", json!({ "target": 0.01, "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::FORBIDDEN);
    let audit = env.audit();
    assert!(audit.iter().any(|(u, a, k, _)| u == "student" && a == "command.axis.move" && k == "ok"));
    assert!(audit.iter().any(|(u, a, k, m)| u == "student2"
        && a == "command.axis.move"
        && k == "denied"
        && m.contains("reserved by student")));
}

#[tokio::test]
async fn students_cannot_change_safety_or_axis_parameters() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    s.book_now(env.now()).await;
    let rules = json!({ "toml": "name = \"open\"\n" });
    let (st, e) = s.req(Method::PUT, "/api/safety/rules", Some(rules.clone())).await;
    assert_eq!(st, StatusCode::FORBIDDEN, "{e}");
    let params = json!({ "limits": { "min": 0.0, "max": 0.5, "max_speed": 0.1, "max_acceleration": 1.0 }, "acceleration": 1.0 });
    let (st, _) = s.req(Method::PUT, "/api/axes/x/parameters", Some(params.clone())).await;
    assert_eq!(st, StatusCode::FORBIDDEN);
    let audit = env.audit();
    assert!(audit.iter().any(|(u, a, k, _)| u == "student" && a == "change_safety_config" && k == "denied"));
    assert!(audit
        .iter()
        .any(|(u, a, k, _)| u == "student" && a == "change_axis_parameters" && k == "denied"));
    assert_eq!(s.axis("x").await["limits"]["max"], json!(0.6));
    // The admin may narrow an axis's limits (never widen them beyond the cell file's).
    let a = env.login("admin", ADMIN_PW).await;
    let (st, r) = a.req(Method::PUT, "/api/axes/x/parameters", Some(params)).await;
    assert_eq!(st, StatusCode::OK, "{r}");
    assert_eq!(s.axis("x").await["limits"]["max"], json!(0.5));
    let wide = json!({ "limits": { "min": 0.0, "max": 0.7, "max_speed": 0.1, "max_acceleration": 1.0 }, "acceleration": 1.0 });
    let (st, r) = a.req(Method::PUT, "/api/axes/x/parameters", Some(wide)).await;
    assert!(st.is_client_error(), "{st} {r}");
    assert_eq!(s.axis("x").await["limits"]["max"], json!(0.5));
    // Rules that do not parse: 400 (the cell's supervisor rules are tested on the demo cell,
    // rules_api.rs).
    let (st, _) = a.req(Method::PUT, "/api/safety/rules", Some(json!({ "toml": "not toml [" }))).await;
    assert!(st.is_client_error(), "{st}");
}

#[tokio::test]
async fn no_api_can_make_safe_to_run_true() {
    let env = Env::new();
    let a = env.login("admin", ADMIN_PW).await;
    let s = env.login("student", STUDENT_PW).await;
    s.book_now(env.now()).await;
    // No write method on /api/safety.
    for m in [Method::PUT, Method::POST, Method::PATCH, Method::DELETE] {
        let (st, _) = s.req(m.clone(), "/api/safety", Some(json!({ "safe_to_run": true }))).await;
        assert_eq!(st, StatusCode::METHOD_NOT_ALLOWED, "{m}");
    }
    // The OpenAPI document has no operation whose request mentions safe_to_run.
    let (_, doc) = s.get("/api/openapi.json").await;
    for (path, item) in doc["paths"].as_object().unwrap() {
        for (method, op) in item.as_object().unwrap() {
            let body = op.get("requestBody").map(Value::to_string).unwrap_or_default();
            let schema = match body.split("schemas/").nth(1) {
                Some(rest) => doc["components"]["schemas"][rest.split('"').next().unwrap()].to_string(),
                None => String::new(),
            };
            assert!(!body.contains("safe_to_run") && !schema.contains("safe_to_run"), "{method} {path}");
        }
    }
    // An admin's E-stop makes the machine unsafe; the slot holder then tries every documented
    // operation (but logout) with bodies that ask for SafeToRun: the machine stays stopped.
    assert_eq!(a.post0("/api/estop").await.0, StatusCode::OK);
    let safety = s.get("/api/safety").await.1;
    assert_eq!((safety["safe_to_run"].clone(), safety["estop"].clone()), (json!(false), json!(true)));
    for (path, item) in doc["paths"].as_object().unwrap() {
        if path == "/api/ws" || path == "/api/logout" || path == "/api/login" {
            continue;
        }
        let concrete = path.replace("{id}", "x").replace("{user}", "student").replace("{name}", "student");
        for method in item.as_object().unwrap().keys() {
            let m = Method::from_bytes(method.to_uppercase().as_bytes()).unwrap();
            if m == Method::GET {
                continue;
            }
            for body in [
                json!({ "safe_to_run": true }),
                json!({ "safe_to_run": true, "estop": false, "held": false }),
                json!({ "toml": "safe_to_run = true\n" }),
            ] {
                let (st, _) = s.req(m.clone(), &concrete, Some(body)).await;
                assert_ne!(st, StatusCode::INTERNAL_SERVER_ERROR, "{method} {path}");
                let safety = a.get("/api/safety").await.1;
                assert_eq!(safety["safe_to_run"], false, "{method} {path} made the machine safe: {safety}");
            }
        }
    }
    // A student may not reset an admin's E-stop (409/403, not safe); the admin may.
    let (st, e) = s.post0("/api/reset").await;
    assert!(st.is_client_error(), "{st} {e}");
    assert_eq!(a.get("/api/safety").await.1["safe_to_run"], false);
    let (st, e) = s.post("/api/axes/y/move", json!({ "target": 0.01, "speed": 0.05 })).await;
    assert_eq!((st, e["error"].as_str().unwrap()), (StatusCode::CONFLICT, "estop"), "{e}");
    assert_eq!(a.post0("/api/reset").await.0, StatusCode::OK);
    assert!(wait_for(MOTION, || async { a.get("/api/safety").await.1["safe_to_run"] == true }).await);
}

#[tokio::test]
async fn estop_stops_every_axis_and_holds_commands() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    s.book_now(env.now()).await;
    // E-stop during motion on several axes: every axis stops.
    for (id, t, v) in [("x", 0.5, 0.08), ("y", 0.35, 0.08), ("z", 0.12, 0.04)] {
        let (st, e) = s.post(&format!("/api/axes/{id}/move"), json!({ "target": t, "speed": v })).await;
        assert_eq!(st, StatusCode::OK, "{id} {e}");
    }
    assert!(
        wait_for(MOTION, || async {
            let (_, axes) = s.get("/api/axes").await;
            axes.as_array().unwrap().iter().filter(|a| a["moving"] == true).count() == 3
        })
        .await,
        "three axes moving"
    );
    assert_eq!(s.post0("/api/estop").await.0, StatusCode::OK);
    assert!(
        wait_for(MOTION, || async {
            let (_, axes) = s.get("/api/axes").await;
            axes.as_array().unwrap().iter().all(|a| a["moving"] == false && a["velocity"] == json!(0.0))
        })
        .await
    );
    let stopped: Vec<f64> = futures_util::future::join_all(["x", "y", "z"].map(|id| s.position(id))).await;
    assert!(stopped[0] < 0.5 && stopped[1] < 0.35 && stopped[2] < 0.12, "stopped short: {stopped:?}");
    let (st, e) = s.post("/api/axes/y/move", json!({ "target": 0.0, "speed": 0.05 })).await;
    assert_eq!((st, e["error"].as_str().unwrap()), (StatusCode::CONFLICT, "estop"));
    tokio::time::sleep(Duration::from_millis(300)).await;
    let still: Vec<f64> = futures_util::future::join_all(["x", "y", "z"].map(|id| s.position(id))).await;
    assert_eq!(stopped, still, "nothing moves while the E-stop holds");
    // E-stop is allowed to a student without a slot too.
    let s2 = env.login("student2", STUDENT_PW).await;
    assert_eq!(s2.post0("/api/estop").await.0, StatusCode::OK);
    // The student's own E-stop is theirs to reset (student2's too: not a teacher's).
    assert_eq!(s.post0("/api/reset").await.0, StatusCode::OK);
}

#[tokio::test]
async fn program_upload_check_run_progress() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    let text = "G21 G90\nG1 X50 Y20 F2400\nG1 X100\nQ7\nG1 X0 Y0\nM30\n";
    let (st, e) = s.post("/api/programs", json!({ "name": "bad.ngc", "text": text })).await;
    assert_eq!(st, StatusCode::FORBIDDEN, "upload needs the slot: {e}");
    s.book_now(env.now()).await;
    let (st, r) = s.post("/api/programs", json!({ "name": "bad.ngc", "text": text })).await;
    assert_eq!(st, StatusCode::OK, "{r}");
    assert_eq!(r["check"]["errors"][0]["line"], 4, "{r}");
    let bad = r["program"]["id"].as_str().unwrap().to_string();
    let (st, e) = s.post0(&format!("/api/programs/{bad}/run")).await;
    assert_eq!(st, StatusCode::BAD_REQUEST, "{e}");
    let good = text.replace("Q7\n", "");
    let (_, r) = s.post("/api/programs", json!({ "name": "good.ngc", "text": good })).await;
    assert_eq!(r["check"]["errors"], json!([]), "{r}");
    let id = r["program"]["id"].as_str().unwrap().to_string();
    let (st, e) = s.post0(&format!("/api/programs/{id}/run")).await;
    assert_eq!(st, StatusCode::OK, "{e}");
    // The station's program service runs it to the end on the gantry's axes.
    assert!(
        wait_for(120.0, || async { s.get("/api/programs/status").await.1["state"] == "done" }).await,
        "{}",
        s.get("/api/programs/status").await.1
    );
    let st = s.get("/api/programs/status").await.1;
    assert_eq!(st["progress"], json!(1.0), "{st}");
    assert_eq!(st["program"], "good.ngc", "{st}");
    for path in ["/api/programs/hold", "/api/programs/resume", "/api/programs/stop"] {
        let (code, e) = s.post0(path).await;
        assert!(code == StatusCode::OK || code == StatusCode::CONFLICT, "{path}: {code} {e}");
    }
    // A viewer can neither check nor run it.
    let v = env.login("viewer", VIEWER_PW).await;
    assert_eq!(v.post0(&format!("/api/programs/{id}/run")).await.0, StatusCode::FORBIDDEN);
    // Lab knows the file (it is removed at the end of the slot).
    assert_eq!(env.lab.programs().list(Some(common::web::STATION), Some("student")).unwrap().len(), 2);
}

#[tokio::test]
async fn admin_ends_a_session_and_the_slot_is_cleaned() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    s.book_now(env.now()).await;
    let (st, _) = s.post("/api/programs", json!({ "name": "mine.ngc", "text": "G0 X10\n" })).await;
    assert_eq!(st, StatusCode::OK);
    let (st, e) = s.post("/api/axes/y/move", json!({ "target": 0.05, "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::OK, "{e}");
    assert!(wait_for(MOTION, || async { s.position("y").await > 0.01 }).await);
    // A student cannot end sessions.
    assert_eq!(s.post0("/api/sessions/student2/end").await.0, StatusCode::FORBIDDEN);
    let a = env.login("admin", ADMIN_PW).await;
    let (st, r) = a.post0("/api/sessions/student/end").await;
    assert_eq!(st, StatusCode::OK, "{r}");
    assert_eq!(r["sessions"], 1);
    assert_eq!(r["slots"].as_array().unwrap().len(), 1);
    assert_eq!(s.get("/api/axes").await.0, StatusCode::UNAUTHORIZED, "logged out");
    // Cleanup: programs gone, axes homed to 0, lab metadata gone, audited.
    assert!(wait_for(MOTION, || async { a.get("/api/programs").await.1 == json!([]) }).await);
    assert!(
        wait_for(MOTION, || async {
            let y = a.axis("y").await;
            y["position"].as_f64().unwrap().abs() < 1e-5 && y["moving"] == false
        })
        .await
    );
    assert!(env.lab.programs().list(Some(common::web::STATION), Some("student")).unwrap().is_empty());
    assert!(env.audit().iter().any(|(u, a, k, _)| u == "station" && a == "cleanup" && k == "ok"));
    assert!(env.audit().iter().any(|(u, a, k, _)| u == "admin" && a == "end_session" && k == "ok"));
    // The student logs in again: no slot, read-only.
    let s = env.login("student", STUDENT_PW).await;
    assert_eq!(
        s.post("/api/axes/y/move", json!({ "target": 0.01, "speed": 0.05 })).await.0,
        StatusCode::FORBIDDEN
    );
}

#[tokio::test]
async fn users_and_audit_are_admin_only() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    assert_eq!(s.get("/api/users").await.0, StatusCode::FORBIDDEN);
    assert_eq!(s.get("/api/audit").await.0, StatusCode::FORBIDDEN);
    let (st, _) =
        s.post("/api/users", json!({ "name": "eve", "password": "eve-password-1", "role": "admin" })).await;
    assert_eq!(st, StatusCode::FORBIDDEN);
    let a = env.login("admin", ADMIN_PW).await;
    let (st, u) =
        a.post("/api/users", json!({ "name": "bob", "password": "bob-password-1", "role": "viewer" })).await;
    assert_eq!(st, StatusCode::OK, "{u}");
    assert_eq!(u["role"], "viewer");
    assert!(u.get("password_hash").is_none());
    let (_, list) = a.get("/api/users").await;
    assert_eq!(list.as_array().unwrap().len(), 5);
    let (st, _) =
        a.post("/api/users", json!({ "name": "bob", "password": "bob-password-1", "role": "viewer" })).await;
    assert_eq!(st, StatusCode::CONFLICT);
    assert_eq!(a.req(Method::DELETE, "/api/users/bob", None).await.0, StatusCode::OK);
    let (st, log) = a.get("/api/audit?action_prefix=manage_users&limit=10").await;
    assert_eq!(st, StatusCode::OK);
    let actions: Vec<&str> =
        log.as_array().unwrap().iter().map(|r| r["entry"]["action"].as_str().unwrap()).collect();
    // Newest first: delete, add (ok), add (error: exists), and the student's two denials.
    assert_eq!(
        actions,
        vec!["manage_users.delete", "manage_users.add", "manage_users.add", "manage_users", "manage_users"]
    );
    assert_eq!(log[1]["entry"]["outcome"]["result"], "error");
    assert_eq!(log[2]["entry"]["outcome"]["result"], "ok");
    assert_eq!(log[3]["entry"]["outcome"]["result"], "denied");
}

#[tokio::test]
async fn groups_scene_signals_camera() {
    let env = Env::with_options(
        |_| {},
        |_| {},
        |o| o.camera_url = Some("http://camera.invalid/stream.mjpg".into()),
    );
    let a = env.login("admin", ADMIN_PW).await;
    assert_eq!(a.get("/api/camera").await.1["url"], "http://camera.invalid/stream.mjpg");
    let (st, groups) = a.get("/api/groups").await;
    assert_eq!(st, StatusCode::OK);
    assert!(groups.as_array().unwrap().iter().any(|g| g["id"] == "cnc" || g["name"] == "cnc"), "{groups}");
    let (st, e) =
        a.post("/api/groups/cnc", json!({ "action": "go_to", "targets": [0.02, 0.01, 0.005] })).await;
    assert_eq!(st, StatusCode::OK, "{e}");
    assert!(
        wait_for(MOTION, || async {
            (a.position("x").await - 0.02).abs() < 1e-5
                && (a.position("y").await - 0.01).abs() < 1e-5
                && (a.position("z").await - 0.005).abs() < 1e-5
        })
        .await
    );
    let (st, e) = a.post("/api/groups/cnc", json!({ "action": "go_to", "targets": [0.01] })).await;
    assert_eq!(st, StatusCode::BAD_REQUEST, "wrong arity: {e}");
    assert_eq!(a.get("/api/scene").await.0, StatusCode::OK);
    let (_, sig) = a.get("/api/signals").await;
    assert_eq!(sig[0]["id"], "x.position", "{sig}");
    let (_, b) = a.get("/api/samples?cursor=0").await;
    let cursor = b["cursor"].as_u64().unwrap();
    assert!(
        wait_for(MOTION, || async {
            let b2 = a.get(&format!("/api/samples?cursor={cursor}")).await.1;
            !b2["samples"].as_array().unwrap().is_empty() && b2["cursor"].as_u64().unwrap() > cursor
        })
        .await,
        "new samples arrive"
    );
    // Students: group moves in their slot only (each member axis authorised).
    let v = env.login("viewer", VIEWER_PW).await;
    let go = json!({ "action": "go_to", "targets": [0.03, 0.02, 0.01] });
    assert_eq!(v.post("/api/groups/cnc", go.clone()).await.0, StatusCode::FORBIDDEN);
    let s = env.login("student", STUDENT_PW).await;
    assert_eq!(s.post("/api/groups/cnc", go.clone()).await.0, StatusCode::FORBIDDEN);
    s.book_now(env.now()).await;
    let (st, e) = s.post("/api/groups/cnc", go).await;
    assert_eq!(st, StatusCode::OK, "{e}");
    assert!(wait_for(MOTION, || async { (s.position("y").await - 0.02).abs() < 1e-5 }).await);
    // Beyond the student range (y: 0.38): refused, nothing moves.
    let far = json!({ "action": "go_to", "targets": [0.03, 0.39, 0.01] });
    assert_eq!(s.post("/api/groups/cnc", far).await.0, StatusCode::FORBIDDEN);
    assert!(env.audit().iter().any(|(u, a, k, _)| u == "student" && a.starts_with("command.") && k == "ok"));
    assert_eq!(a.get("/api/nowhere").await.0, StatusCode::NOT_FOUND);
    assert_eq!(a.get("/api/nowhere").await.1["error"], "not_found");
}
