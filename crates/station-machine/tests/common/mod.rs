//! The station's HTTP API from a test: a raw HTTP/1.1 client and a logged-in session.
#![allow(dead_code, clippy::unwrap_used, clippy::indexing_slicing)]

pub mod web;

use std::io::{Read, Write};
use std::time::{Duration, Instant};

use serde_json::{json, Value};

pub struct Client {
    pub addr: String,
    pub cookie: String,
    pub csrf: String,
}

pub fn http(
    addr: &str,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &str,
) -> (u16, String, String) {
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    let mut req = format!(
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\nContent-Type: application/json\r\nContent-Length: {}\r\n",
        body.len()
    );
    for (k, v) in headers {
        req.push_str(&format!("{k}: {v}\r\n"));
    }
    req.push_str("\r\n");
    req.push_str(body);
    s.write_all(req.as_bytes()).unwrap();
    let mut resp = String::new();
    s.read_to_string(&mut resp).unwrap();
    let (head, body) = resp.split_once("\r\n\r\n").unwrap_or((&resp, ""));
    let status = head.split_whitespace().nth(1).unwrap().parse().unwrap();
    (status, head.to_owned(), body.to_owned())
}

impl Client {
    pub fn login(addr: &str, user: &str, password: &str) -> Self {
        let body = json!({ "user": user, "password": password }).to_string();
        let (st, head, body) = http(addr, "POST", "/api/login", &[], &body);
        assert_eq!(st, 200, "{body}");
        let cookie = head
            .lines()
            .find_map(|l| l.strip_prefix("set-cookie: ").or_else(|| l.strip_prefix("Set-Cookie: ")))
            .unwrap()
            .split(';')
            .next()
            .unwrap()
            .to_owned();
        let csrf = serde_json::from_str::<Value>(&body).unwrap()["csrf_token"].as_str().unwrap().to_owned();
        Client { addr: addr.to_owned(), cookie, csrf }
    }

    pub fn call(&self, method: &str, path: &str, body: Value) -> (u16, Value) {
        let headers = [("Cookie", self.cookie.as_str()), ("X-CSRF-Token", self.csrf.as_str())];
        let text = if body.is_null() { String::new() } else { body.to_string() };
        let (st, _, b) = http(&self.addr, method, path, &headers, &text);
        (st, serde_json::from_str(&b).unwrap_or(Value::String(b)))
    }

    pub fn ok(&self, method: &str, path: &str, body: Value) -> Value {
        let (st, v) = self.call(method, path, body);
        assert_eq!(st, 200, "{method} {path}: {v}");
        v
    }

    pub fn axis(&self, id: &str) -> Value {
        let axes = self.ok("GET", "/api/axes", Value::Null);
        axes.as_array().unwrap().iter().find(|a| a["id"] == id).unwrap().clone()
    }

    pub fn wait_axis(&self, id: &str, timeout: Duration, what: &str, done: impl Fn(&Value) -> bool) -> Value {
        let t0 = Instant::now();
        loop {
            let a = self.axis(id);
            if done(&a) {
                return a;
            }
            assert!(t0.elapsed() < timeout, "{id}: not {what} within {timeout:?}: {a}");
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// The active alarm (raised, and not both cleared and acknowledged) of `source`.
    pub fn active_alarm(&self, code: &str, source: &str) -> Option<Value> {
        let v = self.ok("GET", "/api/alarms", Value::Null);
        v["active"].as_array().unwrap().iter().find(|a| a["code"] == code && a["source"] == source).cloned()
    }

    pub fn move_to(&self, id: &str, target: f64) {
        let a = self.axis(id);
        self.ok(
            "POST",
            &format!("/api/axes/{id}/move"),
            json!({ "target": target, "speed": a["default_speed"] }),
        );
    }
}

/// The demo cell's station with its HTTP API on a free loopback port, an admin
/// (`admin` / `admin-password-1`) and a student (`student` / `student-password-1`).
pub struct Station {
    pub dir: tempfile::TempDir,
    pub machine: std::sync::Arc<motus_station_machine::StationMachine>,
    pub web: motus_station_web::WebHandle,
    pub addr: String,
}

pub fn station() -> Station {
    use motus_lab::{Lab, LabConfig, MemoryStore, Role, UnixMs};
    use std::sync::Arc;
    // As a machine runs: SCHED_FIFO for the device, cyclic and simulator threads where
    // permitted (root: CI), else nice levels; the suite runs beside other work (issue 19).
    motus_realtime::set_policy(motus_realtime::RealtimePolicy::Auto);
    let dir = tempfile::tempdir().unwrap();
    let cell_file = motus_station_machine::demo::write_demo_cell(dir.path(), "127.0.0.1:0").unwrap();
    let cell = motus_station::config::load(&cell_file).unwrap_or_else(|e| panic!("{e}"));
    let mut lab_config: LabConfig = motus_station_machine::lab_config(&cell, false);
    // Cheap hashes: tests log in often (the cost is not under test here).
    lab_config.password.hash = motus_lab::HashParams { memory_kib: 64, iterations: 1, parallelism: 1 };
    let lab = Arc::new(Lab::new(Arc::new(MemoryStore::new()), lab_config));
    let now = UnixMs::from(std::time::SystemTime::now());
    lab.users().add("admin", "admin-password-1", Role::Admin, now).unwrap();
    lab.users().add("student", "student-password-1", Role::Student, now).unwrap();
    let sink = motus_station_machine::alarms::LabAlarmSink::start(Arc::clone(&lab)).unwrap();
    let options = motus_station_machine::StationOptions { alarm_sink: Some(sink), ..Default::default() };
    let machine = Arc::new(
        motus_station_machine::StationMachine::start_file(&cell_file, options)
            .unwrap_or_else(|e| panic!("{e}")),
    );
    let config = motus_station_web::WebConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        station: "Motus demo cell".into(),
        ..motus_station_web::WebConfig::default()
    };
    let web = motus_station_web::start(config, machine.clone(), lab).unwrap();
    let addr = web.addr().to_string();
    Station { dir, machine, web, addr }
}

/// True for a refusal that only says the device is (re)connecting (a loaded host drops a
/// serial reply now and then; the station reconnects by itself).
pub fn reconnecting(code: u16, v: &Value) -> bool {
    let d = v["detail"].as_str().unwrap_or("");
    code == 409 && (d.contains("reconnecting") || d.contains("not connected"))
}

impl Client {
    /// `call`, retried while the axis's device is reconnecting (up to 60 s); any other
    /// answer is returned.
    pub fn call_connected(&self, method: &str, path: &str, body: Value) -> (u16, Value) {
        let t0 = Instant::now();
        loop {
            let (code, v) = self.call(method, path, body.clone());
            if !reconnecting(code, &v) || t0.elapsed() > Duration::from_secs(60) {
                return (code, v);
            }
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    /// Homes `id` and waits until it is homed and still; homes again when the device was
    /// lost meanwhile (up to 5 times).
    pub fn home(&self, id: &str) {
        for attempt in 1..=5 {
            self.wait_axis(id, Duration::from_secs(60), "connected", |a| a["fault"].is_null());
            let (code, v) = self.call_connected("POST", &format!("/api/axes/{id}/home"), Value::Null);
            assert_eq!(code, 200, "home {id}: {v}");
            let t0 = Instant::now();
            loop {
                let a = self.axis(id);
                if a["homed"] == true && a["moving"] == false && a["fault"].is_null() {
                    return;
                }
                if a["fault"].is_string() || t0.elapsed() > Duration::from_secs(60) {
                    eprintln!("home {id} (attempt {attempt}) disturbed: {a}");
                    break;
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        }
        panic!("{id}: not homed after 5 attempts");
    }
}

/// `GET /api/safety`.
pub fn safety(c: &Client) -> Value {
    c.ok("GET", "/api/safety", Value::Null)
}

/// Polls `GET /api/safety` until `done` holds.
pub fn wait_safety(c: &Client, timeout: Duration, what: &str, done: impl Fn(&Value) -> bool) -> Value {
    let t0 = Instant::now();
    loop {
        let s = safety(c);
        if done(&s) {
            return s;
        }
        assert!(t0.elapsed() < timeout, "not {what} within {timeout:?}: {s}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Waits for SafeToRun, resetting (as an operator) when the juggler is held: on a loaded
/// non-real-time host a late cycle lets the 9 ms lease expire now and then.
pub fn wait_safe(c: &Client, timeout: Duration) -> Value {
    let t0 = Instant::now();
    let mut last_reset = Instant::now();
    loop {
        let s = safety(c);
        if s["safe_to_run"] == true {
            return s;
        }
        assert!(t0.elapsed() < timeout, "not SafeToRun: {s}");
        if s["held"] == true && last_reset.elapsed() > Duration::from_secs(2) {
            eprintln!("held ({}): reset", s["diagnosis"]);
            c.ok("POST", "/api/reset", Value::Null);
            last_reset = Instant::now();
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}
