//! API tests against the real server on 127.0.0.1:0 (FakeBackend + lab MemoryStore).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::time::Duration;

use common::{wait_for, Env, ADMIN_PW, STUDENT_PW, VIEWER_PW};
use motus_station_web::MachineBackend;
use reqwest::{Method, StatusCode};
use serde_json::{json, Value};

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
    let (st, e) = c.post("/api/axes/x/jog", json!({ "direction": 1, "speed": 0.1 })).await;
    assert_eq!(st, StatusCode::FORBIDDEN, "{e}");
    assert_eq!(e["detail"]["reason"]["reason"], "role_too_low");
    assert_eq!(c.post0("/api/estop").await.0, StatusCode::FORBIDDEN);
    assert_eq!(c.book_now(env.now()).await.0, StatusCode::FORBIDDEN);
    let audit = env.audit();
    assert!(audit.iter().any(|(u, a, k, _)| u == "viewer" && a == "command.axis.jog" && k == "denied"));
    assert!(audit.iter().any(|(u, a, k, _)| u == "viewer" && a == "command.estop" && k == "denied"));
    tokio::time::sleep(Duration::from_millis(100)).await;
    assert_eq!(c.axis("x").await["position"], json!(0.0), "the axis did not move");
}

#[tokio::test]
async fn students_command_only_in_their_own_slot() {
    let env = Env::new();
    let s1 = env.login("student", STUDENT_PW).await;
    let s2 = env.login("student2", STUDENT_PW).await;
    let mv = json!({ "target": 0.2, "speed": 0.1 });
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
        wait_for(5.0, || async { (s1.axis("x").await["position"].as_f64().unwrap() - 0.2).abs() < 1e-6 })
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
    // Above the student speed limit (1.0): refused by lab even though the axis allows it.
    let (st, e) = s1.post("/api/axes/pan/move", json!({ "target": 1.0, "speed": 1.5 })).await;
    assert_eq!(st, StatusCode::FORBIDDEN, "{e}");
    assert_eq!(e["detail"]["reason"]["reason"], "motion_limit");
    // Invalid numbers: 400.
    let (st, _) = s1.post("/api/axes/x/move", json!({ "target": 9.0, "speed": 0.1 })).await;
    assert_eq!(st, StatusCode::BAD_REQUEST);
    let (st, _) = s1.post("/api/axes/x/move", json!({ "target": "a", "speed": 0.1 })).await;
    assert_eq!(st, StatusCode::BAD_REQUEST);
    // After the slot: refused again.
    env.clock.advance(Duration::from_secs(31 * 60));
    let s1 = env.login("student", STUDENT_PW).await;
    let (st, _) = s1.post("/api/axes/x/move", json!({ "target": 0.1, "speed": 0.1 })).await;
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
    let params = json!({ "limits": { "min": -1.0, "max": 1.0, "max_speed": 5.0, "max_acceleration": 50.0 }, "acceleration": 10.0 });
    let (st, _) = s.req(Method::PUT, "/api/axes/x/parameters", Some(params.clone())).await;
    assert_eq!(st, StatusCode::FORBIDDEN);
    let audit = env.audit();
    assert!(audit.iter().any(|(u, a, k, _)| u == "student" && a == "change_safety_config" && k == "denied"));
    assert!(audit
        .iter()
        .any(|(u, a, k, _)| u == "student" && a == "change_axis_parameters" && k == "denied"));
    let fp_before = s.get("/api/safety").await.1["rules_fingerprint"].clone();
    assert_eq!(s.axis("x").await["limits"]["max"], json!(0.5));
    // The admin may.
    let a = env.login("admin", ADMIN_PW).await;
    let (st, r) = a.req(Method::PUT, "/api/safety/rules", Some(rules)).await;
    assert_eq!(st, StatusCode::OK, "{r}");
    assert_ne!(r["fingerprint"], fp_before);
    assert_eq!(a.req(Method::PUT, "/api/axes/x/parameters", Some(params)).await.0, StatusCode::OK);
    assert_eq!(s.axis("x").await["limits"]["max"], json!(1.0));
    let (st, _) = a.req(Method::PUT, "/api/safety/rules", Some(json!({ "toml": "not toml [" }))).await;
    assert_eq!(st, StatusCode::BAD_REQUEST);
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
    // Make the supervisor unsafe: X must be >= 0.1 while it is at 0.
    let (st, _) = a
        .req(
            Method::PUT,
            "/api/safety/rules",
            Some(json!({ "toml": "name = \"t\"\n[[rule]]\nname = \"x_min\"\naxis = \"x\"\nmin = 0.1\n" })),
        )
        .await;
    assert_eq!(st, StatusCode::OK);
    assert!(wait_for(2.0, || async { s.get("/api/safety").await.1["safe_to_run"] == false }).await);
    let safety = s.get("/api/safety").await.1;
    assert!(safety["diagnosis"].as_str().unwrap().contains("x_min"), "{safety}");
    // Reset (student or admin) is refused while unsafe; commands are held.
    let (st, e) = s.post0("/api/reset").await;
    assert_eq!(st, StatusCode::CONFLICT, "{e}");
    assert_eq!(a.post0("/api/reset").await.0, StatusCode::CONFLICT);
    let (st, e) = s.post("/api/axes/y/move", json!({ "target": 0.1, "speed": 0.1 })).await;
    assert_eq!((st, e["error"].as_str().unwrap()), (StatusCode::CONFLICT, "safety_hold"));
    assert_eq!(s.get("/api/safety").await.1["safe_to_run"], false);
    // An alarm was raised by the station for it.
    assert!(
        wait_for(2.0, || async {
            s.get("/api/alarms").await.1["active"]
                .as_array()
                .unwrap()
                .iter()
                .any(|a| a["code"] == "safe_to_run_false")
        })
        .await
    );
}

#[tokio::test]
async fn unsafe_move_is_stopped_with_a_diagnosis_and_estop_stops_all() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    s.book_now(env.now()).await;
    // Default rule: x <= 0.4. A move to 0.45 is stopped by the supervisor before 0.4.
    assert_eq!(s.post("/api/axes/x/move", json!({ "target": 0.45, "speed": 0.2 })).await.0, StatusCode::OK);
    assert!(wait_for(5.0, || async { s.get("/api/safety").await.1["held"] == true }).await);
    assert!(wait_for(2.0, || async { s.axis("x").await["moving"] == false }).await);
    let x = s.axis("x").await["position"].as_f64().unwrap();
    assert!(x <= 0.4 && x > 0.3, "{x}");
    let safety = s.get("/api/safety").await.1;
    assert!(safety["diagnosis"].as_str().unwrap().contains("x_max"), "{safety}");
    assert_eq!(s.post0("/api/reset").await.0, StatusCode::OK, "safe again once stopped");
    // E-stop during motion on several axes: every axis stops.
    for (id, t, v) in [("y", 0.3, 0.2), ("pan", 2.0, 1.0), ("j1", 2.0, 0.9)] {
        let (st, e) = s.post(&format!("/api/axes/{id}/move"), json!({ "target": t, "speed": v })).await;
        assert_eq!(st, StatusCode::OK, "{id} {e}");
    }
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert_eq!(s.post0("/api/estop").await.0, StatusCode::OK);
    assert!(
        wait_for(3.0, || async {
            let (_, axes) = s.get("/api/axes").await;
            axes.as_array().unwrap().iter().all(|a| a["moving"] == false && a["velocity"] == json!(0.0))
        })
        .await
    );
    let (st, e) = s.post("/api/axes/y/move", json!({ "target": 0.0, "speed": 0.1 })).await;
    assert_eq!((st, e["error"].as_str().unwrap()), (StatusCode::CONFLICT, "estop"));
    // E-stop is allowed to a student without a slot too.
    let s2 = env.login("student2", STUDENT_PW).await;
    assert_eq!(s2.post0("/api/estop").await.0, StatusCode::OK);
}

#[tokio::test]
async fn program_upload_check_run_progress() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    let text = "G21 G90\nG1 X50 Y20 F6000\nG1 X100\nQ7\nG0 X0 Y0\nM30\n";
    let (st, e) = s.post("/api/programs", json!({ "name": "bad.ngc", "text": text })).await;
    assert_eq!(st, StatusCode::FORBIDDEN, "upload needs the slot: {e}");
    s.book_now(env.now()).await;
    let (st, r) = s.post("/api/programs", json!({ "name": "bad.ngc", "text": text })).await;
    assert_eq!(st, StatusCode::OK, "{r}");
    assert_eq!(r["check"]["errors"][0]["line"], 4);
    assert_eq!(r["check"]["errors"][0]["col"], 1);
    let bad = r["program"]["id"].as_str().unwrap().to_string();
    let (st, e) = s.post0(&format!("/api/programs/{bad}/run")).await;
    assert_eq!(st, StatusCode::BAD_REQUEST, "{e}");
    let good = text.replace("Q7\n", "");
    let (_, r) = s.post("/api/programs", json!({ "name": "good.ngc", "text": good })).await;
    assert_eq!(r["check"]["errors"], json!([]));
    let id = r["program"]["id"].as_str().unwrap().to_string();
    assert_eq!(s.post0(&format!("/api/programs/{id}/run")).await.0, StatusCode::OK);
    assert!(
        wait_for(3.0, || async {
            let st = s.get("/api/programs/status").await.1;
            st["state"] == "running" && st["line"].as_u64().unwrap() >= 2
        })
        .await
    );
    assert_eq!(s.post0("/api/programs/hold").await.0, StatusCode::OK);
    assert_eq!(s.get("/api/programs/status").await.1["state"], "held");
    assert_eq!(s.post0("/api/programs/resume").await.0, StatusCode::OK);
    assert!(wait_for(10.0, || async { s.get("/api/programs/status").await.1["state"] == "done" }).await);
    let st = s.get("/api/programs/status").await.1;
    assert_eq!(st["progress"], json!(1.0));
    // Lab knows the file (it is removed at the end of the slot).
    assert_eq!(env.lab.programs().list(Some(common::STATION), Some("student")).unwrap().len(), 2);
}

#[tokio::test]
async fn admin_ends_a_session_and_the_slot_is_cleaned() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    s.book_now(env.now()).await;
    let (st, _) = s.post("/api/programs", json!({ "name": "mine.ngc", "text": "G0 X10\n" })).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(s.post("/api/axes/y/move", json!({ "target": 0.2, "speed": 0.2 })).await.0, StatusCode::OK);
    // A student cannot end sessions.
    assert_eq!(s.post0("/api/sessions/student2/end").await.0, StatusCode::FORBIDDEN);
    let a = env.login("admin", ADMIN_PW).await;
    let (st, r) = a.post0("/api/sessions/student/end").await;
    assert_eq!(st, StatusCode::OK, "{r}");
    assert_eq!(r["sessions"], 1);
    assert_eq!(r["slots"].as_array().unwrap().len(), 1);
    assert_eq!(s.get("/api/axes").await.0, StatusCode::UNAUTHORIZED, "logged out");
    // Cleanup: programs gone, axes homed to 0, lab metadata gone, audited.
    assert!(wait_for(5.0, || async { a.get("/api/programs").await.1 == json!([]) }).await);
    assert!(wait_for(5.0, || async { a.axis("y").await["position"].as_f64().unwrap().abs() < 1e-6 }).await);
    assert!(env.lab.programs().list(Some(common::STATION), Some("student")).unwrap().is_empty());
    assert!(env.audit().iter().any(|(u, a, k, _)| u == "station" && a == "cleanup" && k == "ok"));
    assert!(env.audit().iter().any(|(u, a, k, _)| u == "admin" && a == "end_session" && k == "ok"));
    // The student logs in again: no slot, read-only.
    let s = env.login("student", STUDENT_PW).await;
    assert_eq!(
        s.post("/api/axes/y/move", json!({ "target": 0.1, "speed": 0.1 })).await.0,
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
    let env = Env::new();
    env.backend.set_camera_url(Some("http://camera.invalid/stream.mjpg".into()));
    let a = env.login("admin", ADMIN_PW).await;
    assert_eq!(a.get("/api/camera").await.1["url"], "http://camera.invalid/stream.mjpg");
    let (st, e) =
        a.post("/api/groups/robot", json!({ "action": "go_to", "targets": [0.3, -0.2, 0.5] })).await;
    assert_eq!(st, StatusCode::OK, "{e}");
    assert!(
        wait_for(5.0, || async {
            let sc = a.get("/api/scene").await.1;
            let p = &sc["robot"]["pose"];
            (p[0].as_f64().unwrap() - 0.3).abs() < 1e-6 && (p[1].as_f64().unwrap() + 0.2).abs() < 1e-6
        })
        .await
    );
    let sc = a.get("/api/scene").await.1;
    assert!(sc["robot"]["path"].as_array().unwrap().len() > 10);
    assert_eq!(
        a.post("/api/groups/pan_tilt", json!({ "action": "go_to", "targets": [1.0] })).await.0,
        StatusCode::BAD_REQUEST
    );
    let (_, sig) = a.get("/api/signals").await;
    assert_eq!(sig[0]["id"], "x.position");
    let (_, b) = a.get("/api/samples?cursor=0").await;
    assert!(!b["samples"].as_array().unwrap().is_empty());
    let cursor = b["cursor"].as_u64().unwrap();
    tokio::time::sleep(Duration::from_millis(100)).await;
    let (_, b2) = a.get(&format!("/api/samples?cursor={cursor}")).await;
    let n = b2["samples"].as_array().unwrap().len();
    // 100 ms at a 10 ms tick: about 10 new samples.
    assert!((5..=20).contains(&n), "{n}");
    // Students: group moves in their slot only (each member axis authorised).
    let v = env.login("viewer", VIEWER_PW).await;
    let go = json!({ "action": "go_to", "targets": [0.5, 0.2] });
    assert_eq!(v.post("/api/groups/pan_tilt", go.clone()).await.0, StatusCode::FORBIDDEN);
    let s = env.login("student", STUDENT_PW).await;
    assert_eq!(s.post("/api/groups/pan_tilt", go.clone()).await.0, StatusCode::FORBIDDEN);
    s.book_now(env.now()).await;
    let (st, e) = s.post("/api/groups/pan_tilt", go).await;
    assert_eq!(st, StatusCode::OK, "{e}");
    assert!(
        wait_for(5.0, || async { (s.axis("tilt").await["position"].as_f64().unwrap() - 0.2).abs() < 1e-6 })
            .await
    );
    assert!(env.audit().iter().any(|(u, a, k, _)| u == "student" && a == "command.axis.move" && k == "ok"));
    assert_eq!(a.get("/api/nowhere").await.0, StatusCode::NOT_FOUND);
    assert_eq!(a.get("/api/nowhere").await.1["error"], "not_found");
}
