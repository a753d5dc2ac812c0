//! WebSocket frame rate and access, and the OpenAPI document against the router, on the real
//! station machine (small simulated cell).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::collections::BTreeSet;
use std::time::{Duration, Instant};

use common::web::{Env, ADMIN_PW, VIEWER_PW};
use futures_util::StreamExt;
use reqwest::{Method, StatusCode};
use serde_json::Value;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::Message;

fn ws_request(env: &Env, cookie: Option<&str>) -> tokio_tungstenite::tungstenite::handshake::client::Request {
    let url = format!("ws://{}/api/ws", env.handle.addr());
    let mut req = url.into_client_request().unwrap();
    if let Some(c) = cookie {
        req.headers_mut().insert("Cookie", c.parse().unwrap());
    }
    req
}

#[tokio::test]
async fn websocket_frames_arrive_at_about_20_hz_for_logged_in_users_only() {
    let env = Env::new();
    // Not logged in: the upgrade is refused with 401.
    let err = tokio_tungstenite::connect_async(ws_request(&env, None)).await.unwrap_err();
    match err {
        tokio_tungstenite::tungstenite::Error::Http(r) => assert_eq!(r.status(), StatusCode::UNAUTHORIZED),
        other => panic!("{other}"),
    }
    let c = env.login("viewer", VIEWER_PW).await;
    // Another origin (cross-site WebSocket hijacking): 403 even with the cookie.
    let mut evil = ws_request(&env, c.cookie.as_deref());
    evil.headers_mut().insert("Origin", "http://evil.invalid".parse().unwrap());
    match tokio_tungstenite::connect_async(evil).await.unwrap_err() {
        tokio_tungstenite::tungstenite::Error::Http(r) => assert_eq!(r.status(), StatusCode::FORBIDDEN),
        other => panic!("{other}"),
    }
    let (mut ws, _) = tokio_tungstenite::connect_async(ws_request(&env, c.cookie.as_deref())).await.unwrap();
    let first: Value = match ws.next().await.unwrap().unwrap() {
        Message::Text(t) => serde_json::from_str(&t).unwrap(),
        m => panic!("{m:?}"),
    };
    assert_eq!(first["type"], "hello");
    assert!(first["signals"].as_array().unwrap().len() >= 2);
    // Count state frames for 2 s: 20 Hz gives 40 (a wide margin: a loaded host delays
    // frames, and the rate is what is checked, not the timer's precision).
    let start = Instant::now();
    let mut n = 0;
    let mut seqs = Vec::new();
    let mut samples = 0;
    while start.elapsed() < Duration::from_secs(2) {
        let remaining = Duration::from_secs(2).saturating_sub(start.elapsed());
        let Ok(Some(Ok(Message::Text(t)))) = tokio::time::timeout(remaining, ws.next()).await else {
            continue;
        };
        let f: Value = serde_json::from_str(&t).unwrap();
        assert_eq!(f["type"], "state");
        assert!(f["axes"].as_array().unwrap().len() >= 3);
        assert!(f["safety"]["safe_to_run"].is_boolean());
        seqs.push(f["seq"].as_u64().unwrap());
        samples += f["samples"].as_array().unwrap().len();
        n += 1;
    }
    assert!((25..=48).contains(&n), "{n} frames in 2 s");
    assert!(seqs.windows(2).all(|w| w[1] > w[0]));
    // The station's samples (one per poll of the axes) arrive through the frames: at least
    // one every other frame.
    assert!(samples >= n / 2, "{samples} samples in {n} frames");
    // Logging out closes the stream with a logout frame.
    assert_eq!(c.post0("/api/logout").await.0, StatusCode::OK);
    let mut saw_logout = false;
    let end = Instant::now() + Duration::from_secs(3);
    while Instant::now() < end {
        match tokio::time::timeout(Duration::from_secs(3), ws.next()).await {
            Ok(Some(Ok(Message::Text(t)))) => {
                if serde_json::from_str::<Value>(&t).unwrap()["type"] == "logout" {
                    saw_logout = true;
                }
            }
            Ok(Some(Ok(_))) => {}
            _ => break,
        }
    }
    assert!(saw_logout);
}

/// `(METHOD, /path/{param})` of every `.route(...)` in station-web's src/server.rs.
fn routes_in_router_source() -> BTreeSet<(String, String)> {
    let src = include_str!("../../station-web/src/server.rs");
    // One `.route(...)` call per entry, whether rustfmt kept it on one line or split it.
    let joined: String = src.lines().map(str::trim).collect::<Vec<_>>().join(" ");
    let calls: Vec<String> =
        joined.split(".route(").skip(1).map(|c| format!(".route({}", c.trim_start())).collect();
    let mut out = BTreeSet::new();
    for line in calls.iter().map(String::as_str).filter(|l| l.starts_with(".route(\"")) {
        let path = line.split('"').nth(1).unwrap();
        let path: String = path
            .split('/')
            .map(|seg| match seg.strip_prefix(':') {
                Some(p) => format!("{{{p}}}"),
                None => seg.to_string(),
            })
            .collect::<Vec<_>>()
            .join("/");
        let rest = line.split_once(',').unwrap().1;
        for m in ["get", "post", "put", "delete", "patch"] {
            if rest.contains(&format!(" {m}(")) || rest.contains(&format!(".{m}(")) {
                out.insert((m.to_string(), path.clone()));
            }
        }
    }
    out
}

#[tokio::test]
async fn openapi_lists_every_route_and_every_listed_route_is_served() {
    let routes = routes_in_router_source();
    assert!(routes.len() >= 40, "{}", routes.len());
    let env = Env::new();
    let a = env.login("admin", ADMIN_PW).await;
    let (st, doc) = env.client().get("/api/openapi.json").await;
    assert_eq!(st, StatusCode::OK, "public");
    assert_eq!(doc["openapi"], "3.0.3");
    let mut documented = BTreeSet::new();
    for (path, item) in doc["paths"].as_object().unwrap() {
        for method in item.as_object().unwrap().keys() {
            documented.insert((method.clone(), path.clone()));
        }
    }
    assert_eq!(routes, documented, "router vs OpenAPI");
    // Every documented operation is routed: never 404 (no route) or 405 (wrong method).
    // Path parameters get a value that exists where it matters little ("x", "1", "student2").
    for (method, path) in &documented {
        if path == "/api/ws" {
            continue;
        }
        let concrete = path.replace("{id}", "1").replace("{user}", "student2").replace("{name}", "nobody");
        let m = Method::from_bytes(method.to_uppercase().as_bytes()).unwrap();
        let body = if m == Method::GET || m == Method::DELETE { None } else { Some(serde_json::json!({})) };
        let r = a.raw(m, &concrete, body, a.csrf.as_deref()).await;
        assert_ne!(r.status(), StatusCode::METHOD_NOT_ALLOWED, "{method} {path}");
        if r.status() == StatusCode::NOT_FOUND {
            let e: Value = r.json().await.unwrap();
            assert_ne!(e["detail"], "no such route", "{method} {path}");
        }
    }
    // Every schema reference resolves.
    let text = doc.to_string();
    for part in text.split("#/components/schemas/").skip(1) {
        let name = part.split('"').next().unwrap();
        assert!(doc["components"]["schemas"].get(name).is_some(), "{name}");
    }
}

#[tokio::test]
async fn hmi_assets_are_served_from_the_binary() {
    let env = Env::new();
    let c = env.client();
    let r = c.raw(Method::GET, "/", None, None).await;
    assert_eq!(r.status(), StatusCode::OK);
    assert!(r.headers()["content-type"].to_str().unwrap().starts_with("text/html"));
    let html = r.text().await.unwrap();
    for id in [
        "estop-btn",
        "login-form",
        "axes-rows",
        "plot",
        "program-run",
        "robot-map",
        "diagnosis",
        "scene",
        "audit-rows",
    ] {
        assert!(html.contains(&format!("id=\"{id}\"")), "{id}");
    }
    assert!(!html.contains("http://") && !html.contains("https://"), "no external resources");
    let js = c.raw(Method::GET, "/app.js", None, None).await.text().await.unwrap();
    assert!(js.contains("X-CSRF-Token") && js.contains("/api/ws"));
    let css = c.raw(Method::GET, "/style.css", None, None).await;
    assert!(css.headers()["content-type"].to_str().unwrap().starts_with("text/css"));
}
