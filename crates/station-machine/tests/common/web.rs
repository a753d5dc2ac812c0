//! The web API on the real station machine over a small simulated cell
//! (`api-test-cell.toml`: `sim-axis` devices only, so it starts at once): an [`Env`] with an
//! injectable clock, a lab `MemoryStore` with cheap hashes and the users admin, student,
//! student2 and viewer, and an async HTTP client that keeps the session cookie and the CSRF
//! token.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, dead_code)]

use std::sync::Arc;
use std::time::Duration;

use motus_lab::{HashParams, Lab, LabConfig, MemoryStore, Role, Store, UnixMs};
use motus_station_machine::{StationMachine, StationOptions};
use motus_station_web::{
    start, AxisAction, Caller, Clock, MachineBackend, OffsetClock, WebConfig, WebHandle,
};
use reqwest::{Method, StatusCode};
use serde_json::Value;

/// The small cell (x, y, z: a gantry with student tables; w: no student table).
pub const API_TEST_CELL: &str = include_str!("api-test-cell.toml");
pub const STATION: &str = "Motus API test cell";
pub const ADMIN_PW: &str = "admin-password-1";
pub const STUDENT_PW: &str = "student-password-1";
pub const VIEWER_PW: &str = "viewer-password-1";

pub struct Env {
    pub handle: WebHandle,
    pub clock: Arc<OffsetClock>,
    pub backend: Arc<StationMachine>,
    pub lab: Arc<Lab>,
    pub dir: tempfile::TempDir,
}

/// Writes the small cell into `dir`; its path.
pub fn write_api_test_cell(dir: &std::path::Path) -> std::path::PathBuf {
    std::fs::create_dir_all(dir.join("data")).unwrap();
    let path = dir.join("api-test-cell.toml");
    std::fs::write(&path, API_TEST_CELL).unwrap();
    path
}

impl Env {
    pub fn new() -> Env {
        Self::with(|_| {})
    }

    pub fn with(tweak: impl FnOnce(&mut LabConfig)) -> Env {
        Self::with_web(tweak, |_| {})
    }

    /// [`Env::with`], and `web` adjusts the server's settings.
    pub fn with_web(tweak: impl FnOnce(&mut LabConfig), web: impl FnOnce(&mut WebConfig)) -> Env {
        Self::with_options(tweak, web, |_| {})
    }

    /// [`Env::with_web`], and `station` adjusts the machine's options.
    pub fn with_options(
        tweak: impl FnOnce(&mut LabConfig),
        web: impl FnOnce(&mut WebConfig),
        station: impl FnOnce(&mut StationOptions),
    ) -> Env {
        Self::build(tweak, web, station, true)
    }

    /// [`Env::new`], but the axes are left as the station starts them: not homed.
    pub fn unhomed() -> Env {
        Self::build(|_| {}, |_| {}, |_| {}, false)
    }

    /// [`Env::new`] on the test cell as `edit` changes its text.
    pub fn with_cell(edit: impl FnOnce(String) -> String) -> Env {
        Self::build_on(edit, |_| {}, |_| {}, |_| {}, true)
    }

    fn build(
        tweak: impl FnOnce(&mut LabConfig),
        web: impl FnOnce(&mut WebConfig),
        station: impl FnOnce(&mut StationOptions),
        home: bool,
    ) -> Env {
        Self::build_on(|t| t, tweak, web, station, home)
    }

    fn build_on(
        edit: impl FnOnce(String) -> String,
        tweak: impl FnOnce(&mut LabConfig),
        web: impl FnOnce(&mut WebConfig),
        station: impl FnOnce(&mut StationOptions),
        home: bool,
    ) -> Env {
        let dir = tempfile::tempdir().unwrap();
        let cell_file = write_api_test_cell(dir.path());
        std::fs::write(&cell_file, edit(API_TEST_CELL.to_string())).unwrap();
        let cell = motus_station::config::load(&cell_file).unwrap_or_else(|e| panic!("{e}"));
        let mut cfg = motus_station_machine::lab_config(&cell, false);
        // Cheap hashes: the tests log in often (the cost is not under test here).
        cfg.password.hash = HashParams { memory_kib: 64, iterations: 1, parallelism: 1 };
        tweak(&mut cfg);
        let store: Arc<dyn Store> = Arc::new(MemoryStore::new());
        let lab = Arc::new(Lab::new(store, cfg));
        let clock = Arc::new(OffsetClock::new());
        let now = clock.now();
        for (n, pw, r) in [
            ("admin", ADMIN_PW, Role::Admin),
            ("student", STUDENT_PW, Role::Student),
            ("student2", STUDENT_PW, Role::Student),
            ("viewer", VIEWER_PW, Role::Viewer),
        ] {
            lab.users().add(n, pw, r, now).unwrap();
        }
        let sink = motus_station_machine::alarms::LabAlarmSink::start(Arc::clone(&lab)).unwrap();
        let mut options = StationOptions { alarm_sink: Some(sink), ..StationOptions::default() };
        station(&mut options);
        let backend =
            Arc::new(StationMachine::start_file(&cell_file, options).unwrap_or_else(|e| panic!("{e}")));
        if home {
            home_all(&backend);
        }
        let mut config = WebConfig {
            listen: "127.0.0.1:0".parse().unwrap(),
            station: STATION.into(),
            ws_rate_hz: 20.0,
            cleanup_interval: Duration::from_millis(100),
            clock: Arc::clone(&clock) as Arc<dyn Clock>,
            ..WebConfig::default()
        };
        web(&mut config);
        let handle = start(config, Arc::clone(&backend) as _, Arc::clone(&lab)).unwrap();
        Env { handle, clock, backend, lab, dir }
    }

    pub fn client(&self) -> WebClient {
        WebClient { http: reqwest::Client::new(), base: self.handle.url(), cookie: None, csrf: None }
    }

    pub async fn login(&self, user: &str, pw: &str) -> WebClient {
        let mut c = self.client();
        let (st, body) = c.login(user, pw).await;
        assert_eq!(st, StatusCode::OK, "{body}");
        c
    }

    pub fn now(&self) -> UnixMs {
        self.clock.now()
    }

    /// Audit entries of `user` whose action is exactly `action` (newest first) as (target,
    /// outcome kind, message).
    pub fn audit_of(&self, user: &str, action: &str) -> Vec<(String, String, String)> {
        self.lab
            .audit()
            .query(&motus_lab::AuditQuery {
                user: Some(user.into()),
                action_prefix: Some(action.into()),
                limit: 1000,
                ..Default::default()
            })
            .unwrap()
            .into_iter()
            .filter(|r| r.entry.action == action)
            .map(|r| {
                (r.entry.target, r.entry.outcome.kind().to_string(), r.entry.outcome.message().to_string())
            })
            .collect()
    }

    /// A WebSocket upgrade of `/api/ws` with the session `cookie`, `Origin` and `Host`: the
    /// refusal's status, or 101 when it is accepted.
    pub async fn ws_upgrade(&self, cookie: &str, origin: &str, host: &str) -> StatusCode {
        use tokio_tungstenite::tungstenite::client::IntoClientRequest;
        let mut req = format!("ws://{}/api/ws", self.handle.addr()).into_client_request().unwrap();
        req.headers_mut().insert("Cookie", cookie.parse().unwrap());
        req.headers_mut().insert("Origin", origin.parse().unwrap());
        req.headers_mut().insert("Host", host.parse().unwrap());
        match tokio_tungstenite::connect_async(req).await {
            Ok(_) => StatusCode::SWITCHING_PROTOCOLS,
            Err(tokio_tungstenite::tungstenite::Error::Http(r)) => r.status(),
            Err(other) => panic!("{other}"),
        }
    }

    /// Audit entries (newest first) as (user, action, outcome kind, message).
    pub fn audit(&self) -> Vec<(String, String, String, String)> {
        self.lab
            .audit()
            .query(&motus_lab::AuditQuery { limit: 1000, ..Default::default() })
            .unwrap()
            .into_iter()
            .map(|r| {
                (
                    r.entry.user,
                    r.entry.action,
                    r.entry.outcome.kind().to_string(),
                    r.entry.outcome.message().to_string(),
                )
            })
            .collect()
    }
}

/// Homes every axis of the cell (as the console would at start-up: the simulated axes start
/// at 0, not homed) and waits until each is homed and still (up to 30 s).
pub fn home_all(m: &StationMachine) {
    let console = Caller::new("console", Role::Admin);
    let end = std::time::Instant::now() + Duration::from_secs(30);
    for a in m.axes() {
        loop {
            match m.command(&console, &a.id, AxisAction::Home) {
                Ok(()) => break,
                Err(e) => {
                    assert!(std::time::Instant::now() < end, "home {}: {e}", a.id);
                    std::thread::sleep(Duration::from_millis(50));
                }
            }
        }
    }
    loop {
        if m.axes().iter().all(|a| a.homed && !a.moving) {
            return;
        }
        assert!(std::time::Instant::now() < end, "not homed: {:?}", m.axes());
        std::thread::sleep(Duration::from_millis(20));
    }
}

pub struct WebClient {
    pub http: reqwest::Client,
    pub base: String,
    pub cookie: Option<String>,
    pub csrf: Option<String>,
}

impl WebClient {
    pub async fn login(&mut self, user: &str, pw: &str) -> (StatusCode, Value) {
        let r = self
            .http
            .post(format!("{}/api/login", self.base))
            .json(&serde_json::json!({ "user": user, "password": pw }))
            .send()
            .await
            .unwrap();
        let st = r.status();
        if let Some(sc) = r.headers().get(reqwest::header::SET_COOKIE) {
            let sc = sc.to_str().unwrap().to_string();
            self.cookie = Some(sc.split(';').next().unwrap().to_string());
        }
        let body: Value = r.json().await.unwrap_or(Value::Null);
        if st == StatusCode::OK {
            self.csrf = body["csrf_token"].as_str().map(str::to_string);
        }
        (st, body)
    }

    pub async fn raw(
        &self,
        method: Method,
        path: &str,
        body: Option<Value>,
        csrf: Option<&str>,
    ) -> reqwest::Response {
        let mut rb = self.http.request(method, format!("{}{}", self.base, path));
        if let Some(c) = &self.cookie {
            rb = rb.header(reqwest::header::COOKIE, c);
        }
        if let Some(t) = csrf {
            rb = rb.header("X-CSRF-Token", t);
        }
        if let Some(b) = body {
            rb = rb.json(&b);
        }
        rb.send().await.unwrap()
    }

    pub async fn req(&self, method: Method, path: &str, body: Option<Value>) -> (StatusCode, Value) {
        let csrf = self.csrf.clone();
        let r = self.raw(method, path, body, csrf.as_deref()).await;
        let st = r.status();
        (st, r.json().await.unwrap_or(Value::Null))
    }

    pub async fn get(&self, path: &str) -> (StatusCode, Value) {
        self.req(Method::GET, path, None).await
    }

    pub async fn post(&self, path: &str, body: Value) -> (StatusCode, Value) {
        self.req(Method::POST, path, Some(body)).await
    }

    pub async fn post0(&self, path: &str) -> (StatusCode, Value) {
        self.req(Method::POST, path, None).await
    }

    pub async fn axis(&self, id: &str) -> Value {
        let (st, axes) = self.get("/api/axes").await;
        assert_eq!(st, StatusCode::OK);
        axes.as_array().unwrap().iter().find(|a| a["id"] == id).unwrap().clone()
    }

    pub async fn position(&self, id: &str) -> f64 {
        self.axis(id).await["position"].as_f64().unwrap()
    }

    /// Books `[now, now + 30 min)` for the logged-in user.
    pub async fn book_now(&self, now: UnixMs) -> (StatusCode, Value) {
        self.post("/api/reservations", serde_json::json!({ "start": now.0, "end": now.0 + 30 * 60 * 1000 }))
            .await
    }
}

/// Polls `f` every 20 ms until it is true or `secs` elapse.
pub async fn wait_for<F, Fut>(secs: f64, mut f: F) -> bool
where
    F: FnMut() -> Fut,
    Fut: std::future::Future<Output = bool>,
{
    let end = std::time::Instant::now() + Duration::from_secs_f64(secs);
    while std::time::Instant::now() < end {
        if f().await {
            return true;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    false
}
