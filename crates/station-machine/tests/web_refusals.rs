//! Refusals the handlers never see: the WebSocket's origin check, bodies the extractors
//! reject, unknown routes and methods. Each is refused before anything reaches the machine,
//! and audited once with the session's user (`anonymous` without one). On the real station
//! machine (small simulated cell).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::web::{Env, ADMIN_PW, STUDENT_PW, VIEWER_PW};
use motus_lab::AuditQuery;
use reqwest::{Method, StatusCode};
use serde_json::{json, Value};
use tokio_tungstenite::tungstenite::client::IntoClientRequest;

/// Audit entries of `action` (newest first) as (user, target, outcome kind, message).
fn audited(env: &Env, action: &str) -> Vec<(String, String, String, String)> {
    env.lab
        .audit()
        .query(&AuditQuery { action_prefix: Some(action.into()), limit: 1000, ..AuditQuery::default() })
        .unwrap()
        .into_iter()
        .filter(|r| r.entry.action == action)
        .map(|r| {
            (
                r.entry.user,
                r.entry.target,
                r.entry.outcome.kind().to_string(),
                r.entry.outcome.message().to_string(),
            )
        })
        .collect()
}

/// The `request` entries for `target`.
fn requests(env: &Env, target: &str) -> Vec<(String, String, String)> {
    audited(env, "request")
        .into_iter()
        .filter(|(_, t, _, _)| t == target)
        .map(|(u, _, k, m)| (u, k, m))
        .collect()
}

/// A WebSocket upgrade with `Origin` and `Host`; the refusal's status, or 101.
async fn upgrade(env: &Env, cookie: &str, origin: &str, host: &str) -> StatusCode {
    let mut req = format!("ws://{}/api/ws", env.handle.addr()).into_client_request().unwrap();
    req.headers_mut().insert("Cookie", cookie.parse().unwrap());
    req.headers_mut().insert("Origin", origin.parse().unwrap());
    req.headers_mut().insert("Host", host.parse().unwrap());
    match tokio_tungstenite::connect_async(req).await {
        Ok(_) => StatusCode::SWITCHING_PROTOCOLS,
        Err(tokio_tungstenite::tungstenite::Error::Http(r)) => r.status(),
        Err(other) => panic!("{other}"),
    }
}

#[tokio::test]
async fn websocket_origins_are_checked_against_the_served_origins_not_the_host_header() {
    let env = Env::new();
    let c = env.login("viewer", VIEWER_PW).await;
    let cookie = c.cookie.clone().unwrap();
    let port = env.handle.addr().port();
    // A page elsewhere (here a rebound DNS name: its Host matches its Origin): refused.
    let evil = format!("evil.example:{port}");
    assert_eq!(upgrade(&env, &cookie, &format!("http://{evil}"), &evil).await, StatusCode::FORBIDDEN);
    let denied = audited(&env, "websocket");
    assert_eq!(denied.len(), 1, "{denied:?}");
    assert_eq!(denied[0].0, "viewer");
    assert_eq!(denied[0].2, "denied");
    assert!(denied[0].3.contains("evil.example"), "{denied:?}");
    // The served origins (the listen address, and localhost on loopback).
    let here = format!("127.0.0.1:{port}");
    assert_eq!(
        upgrade(&env, &cookie, &format!("http://{here}"), &here).await,
        StatusCode::SWITCHING_PROTOCOLS
    );
    let local = format!("localhost:{port}");
    assert_eq!(
        upgrade(&env, &cookie, &format!("http://{local}"), &local).await,
        StatusCode::SWITCHING_PROTOCOLS
    );
    assert_eq!(
        upgrade(&env, &cookie, &format!("http://127.0.0.1:{}", port.wrapping_add(1)), &here).await,
        StatusCode::FORBIDDEN,
        "another port is another origin"
    );
}

#[tokio::test]
async fn configured_websocket_origins_replace_the_served_ones() {
    let env = Env::with_web(|_| {}, |w| w.allowed_origins = vec!["https://lab.example.org".into()]);
    let c = env.login("viewer", VIEWER_PW).await;
    let cookie = c.cookie.clone().unwrap();
    let here = env.handle.addr().to_string();
    assert_eq!(
        upgrade(&env, &cookie, "https://lab.example.org", "lab.example.org").await,
        StatusCode::SWITCHING_PROTOCOLS
    );
    assert_eq!(upgrade(&env, &cookie, &format!("http://{here}"), &here).await, StatusCode::FORBIDDEN);
}

#[tokio::test]
async fn bodies_rejected_by_the_extractors_are_audited_with_the_user() {
    let env = Env::new();
    let s = env.login("student", STUDENT_PW).await;
    s.book_now(env.now()).await;
    let csrf = s.csrf.clone().unwrap();
    let send = |body: reqwest::Body, content_type: Option<&'static str>| {
        let mut rb = s
            .http
            .post(format!("{}/api/axes/x/move", s.base))
            .header("Cookie", s.cookie.clone().unwrap())
            .header("X-CSRF-Token", csrf.clone())
            .body(body);
        if let Some(ct) = content_type {
            rb = rb.header("Content-Type", ct);
        }
        rb.send()
    };
    // Bad JSON, no JSON content type, too large (axum's 2 MB default limit).
    let r = send(r#"{"target": 0.01, "speed""#.into(), Some("application/json")).await.unwrap();
    assert_eq!(r.status(), StatusCode::BAD_REQUEST);
    let r = send(r#"{"target": 0.01, "speed": 0.05}"#.into(), Some("text/plain")).await.unwrap();
    assert_eq!(r.status(), StatusCode::BAD_REQUEST);
    let x = s.axis("x").await;
    assert!(x["position"].as_f64().unwrap().abs() < 1e-5 && x["moving"] == false, "nothing moved: {x}");
    // Last on this connection: the server does not read the rest of a refused large body
    // and closes the connection after its answer.
    let big = format!(r#"{{"target": 0.01, "speed": 0.05, "pad": "{}"}}"#, "x".repeat(3 << 20));
    let r = send(big.into(), Some("application/json")).await.unwrap();
    assert!(r.status().is_client_error(), "{}", r.status());
    let entries = requests(&env, "POST /api/axes/x/move");
    assert_eq!(entries.len(), 3, "{entries:?}");
    assert!(
        entries.iter().all(|(u, k, m)| u == "student" && k == "error" && m.starts_with("400")),
        "{entries:?}"
    );
    assert!(entries.iter().any(|(_, _, m)| m.contains("Content-Type")), "{entries:?}");
    assert!(entries.iter().any(|(_, _, m)| m.contains("length limit")), "{entries:?}");
    // A bad login body: audited as anonymous (lab audits the login's own refusals).
    let r = env.client().raw(Method::POST, "/api/login", Some(json!({ "user": "student" })), None).await;
    assert_eq!(r.status(), StatusCode::BAD_REQUEST);
    let login = requests(&env, "POST /api/login");
    assert_eq!(login.len(), 1, "{login:?}");
    assert_eq!((login[0].0.as_str(), login[0].1.as_str()), ("anonymous", "error"));
    let mut c = env.client();
    assert_eq!(c.login("student", "wrong-password-x").await.0, StatusCode::UNAUTHORIZED);
    assert_eq!(requests(&env, "POST /api/login").len(), 1, "a wrong password is lab's `login` entry only");
}

#[tokio::test]
async fn api_route_misses_need_a_session_and_are_audited() {
    let env = Env::new();
    let anon = env.client();
    // Without a session the API's shape is not shown: 401 for unknown routes and methods.
    let (st, e) = anon.get("/api/nowhere").await;
    assert_eq!((st, e["error"].clone()), (StatusCode::UNAUTHORIZED, json!("not_logged_in")));
    assert_eq!(anon.get("/api/estop").await.0, StatusCode::UNAUTHORIZED, "wrong method");
    assert_eq!(anon.post0("/api/nowhere").await.0, StatusCode::UNAUTHORIZED);
    assert!(requests(&env, "GET /api/nowhere").is_empty(), "anonymous reads are not audited");
    assert_eq!(
        requests(&env, "POST /api/nowhere"),
        [("anonymous".to_string(), "denied".to_string(), "401 not_logged_in: log in first".to_string())]
    );
    // Outside the API, pages stay public: 404.
    assert_eq!(anon.get("/nowhere").await.0, StatusCode::NOT_FOUND);
    // With a session: 404 / 405, audited with the user.
    let a = env.login("admin", ADMIN_PW).await;
    let (st, e) = a.get("/api/nowhere").await;
    assert_eq!((st, e["error"].clone()), (StatusCode::NOT_FOUND, json!("not_found")));
    assert_eq!(a.get("/api/estop").await.0, StatusCode::METHOD_NOT_ALLOWED);
    assert_eq!(a.post0("/api/nowhere").await.0, StatusCode::NOT_FOUND);
    let get = requests(&env, "GET /api/nowhere");
    assert_eq!(get.len(), 1, "{get:?}");
    assert_eq!((get[0].0.as_str(), get[0].1.as_str()), ("admin", "error"));
    assert!(get[0].2.starts_with("404 not_found"), "{get:?}");
    assert_eq!(requests(&env, "GET /api/estop").len(), 1);
    assert!(requests(&env, "POST /api/nowhere").iter().any(|(u, _, m)| u == "admin" && m.starts_with("404")));
}

#[tokio::test]
async fn refusals_audited_by_their_handler_are_not_audited_twice() {
    let env = Env::new();
    let v = env.login("viewer", VIEWER_PW).await;
    assert_eq!(v.post0("/api/estop").await.0, StatusCode::FORBIDDEN);
    let a = env.login("admin", ADMIN_PW).await;
    let r = a.raw(Method::POST, "/api/estop", None, None).await;
    assert_eq!(r.status(), StatusCode::FORBIDDEN, "no CSRF token");
    assert_eq!(r.json::<Value>().await.unwrap()["error"], "csrf");
    // Authorised, but refused by the machine (beyond the axis limit): audited by the command.
    let (st, _) = a.post("/api/axes/x/move", json!({ "target": 9.0, "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::BAD_REQUEST);
    assert!(audited(&env, "command.estop").iter().any(|(u, _, k, _)| u == "viewer" && k == "denied"));
    assert!(audited(&env, "csrf").iter().any(|(u, _, k, _)| u == "admin" && k == "denied"));
    assert!(audited(&env, "command.axis.move").iter().any(|(u, _, k, _)| u == "admin" && k == "error"));
    assert!(
        requests(&env, "POST /api/estop").is_empty() && requests(&env, "POST /api/axes/x/move").is_empty(),
        "{:?}",
        audited(&env, "request")
    );
    // Refused before the command (no such axis): audited once, by the middleware.
    let (st, _) = a.post("/api/axes/nope/move", json!({ "target": 0.01, "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::NOT_FOUND);
    let nope = requests(&env, "POST /api/axes/nope/move");
    assert_eq!(nope.len(), 1, "{nope:?}");
    assert!(nope[0].2.contains("no axis"), "{nope:?}");
}
