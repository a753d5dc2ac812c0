//! Load on the real `motus demo` from the same host (issue 18, acceptance 4): 200 logged-in
//! HTTP clients polling `/api/axes`, `/api/safety` and `/api/scene` (one request at a time
//! each, no pause) and 50 WebSocket clients for 60 s while the administrator presses E-stop
//! and reset every second; then 200 concurrent logins (mostly wrong passwords). The machine
//! must not notice: no device lost, no lost heartbeat on the wheels (EMCY 0x8130), no KV-01
//! time-out latch; every E-stop and reset answered; the RSS 5 s after the logins less than
//! 50 MB above the RSS before them. Prints the E-stop latency (p50/p99/max), the RSS before,
//! right after and 5 s after the logins, the request counts, each station thread's scheduling
//! and the juggler's supervisor trips.
//!
//! The juggler's supervisor trips under this load are a real-time figure (a 1 ms cycle with a
//! 9 ms lease beside a client load that saturates both cores, and on a CI host beside other
//! work): they are printed, not asserted (a trip is a safe stop, and the supervisor names
//! it), and under the test's policy written with the E-stop latency to
//! `target/realtime/from-suite/demo_load.log`, which `scripts/realtime.sh` puts in its table
//! (target: 0 trips). Everything else above is asserted.
//!
//! The station runs as a user starts it, with the default real-time policy (`auto`):
//! SCHED_FIFO for its device, cyclic and simulator threads where permitted (root: CI), else
//! nice levels and a warning; web threads at nice +10 either way. The test needs no privilege; with it, the machine's
//! threads hold beside other work on the host (the suite runs beside CPU hogs, issue 19). The clients run on one thread (a current-thread runtime).
//! `MOTUS_LOAD_SECONDS` (the load's duration: default 20 s on a developer's machine, the
//! issue's 60 s in CI) and `MOTUS_LOAD_REALTIME` (`auto`/`nice`/`off`: unset, the default) change
//! the run for measurements. Uses the release binary when it is built
//! (scripts/test.sh builds it), as the browser test does.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::collections::{BTreeMap, BTreeSet};
use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use futures_util::StreamExt;
use serde_json::{json, Value};
use tokio_tungstenite::tungstenite::client::IntoClientRequest;

/// Defaults of the load (`MOTUS_LOAD_HTTP`, `MOTUS_LOAD_WS` change them for measurements).
const HTTP_CLIENTS: usize = 200;
const WS_CLIENTS: usize = 50;
const LOGINS: usize = 200;
/// Viewer accounts the HTTP and WebSocket clients log in with (a class of students).
const VIEWERS: usize = 10;
const VIEWER_PASSWORD: &str = "load-test-password-1";
const RSS_GROWTH_LIMIT_KB: i64 = 50 * 1024;
/// Liveness only: no request of the test may take longer than this.
const REQUEST_TIMEOUT: Duration = Duration::from_secs(20);

struct Demo(Child);
impl Drop for Demo {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A logged-in session: its cookie and CSRF token.
#[derive(Clone)]
struct Session {
    cookie: String,
    csrf: String,
}

fn client() -> reqwest::Client {
    reqwest::Client::builder().pool_max_idle_per_host(1).timeout(REQUEST_TIMEOUT).build().unwrap()
}

/// `POST /api/login`: the status and, on success, the session.
async fn login(
    c: &reqwest::Client,
    base: &str,
    user: &str,
    password: &str,
) -> Result<(u16, Option<Session>), String> {
    let r = c
        .post(format!("{base}/api/login"))
        .json(&json!({ "user": user, "password": password }))
        .send()
        .await
        .map_err(|e| e.to_string())?;
    let status = r.status().as_u16();
    let cookie = r
        .headers()
        .get(reqwest::header::SET_COOKIE)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.split(';').next())
        .map(str::to_owned);
    let body: Value = r.json().await.unwrap_or(Value::Null);
    let session = match (status, cookie, body["csrf_token"].as_str()) {
        (200, Some(cookie), Some(csrf)) => Some(Session { cookie, csrf: csrf.to_owned() }),
        _ => None,
    };
    Ok((status, session))
}

async fn get_json(c: &reqwest::Client, base: &str, s: &Session, path: &str) -> Value {
    let r = c.get(format!("{base}{path}")).header("Cookie", &s.cookie).send().await.unwrap();
    assert_eq!(r.status(), 200, "GET {path}");
    r.json().await.unwrap()
}

async fn post(
    c: &reqwest::Client,
    base: &str,
    s: &Session,
    path: &str,
    body: Option<Value>,
) -> (u16, String) {
    let mut req = c.post(format!("{base}{path}")).header("Cookie", &s.cookie).header("X-CSRF-Token", &s.csrf);
    if let Some(b) = body {
        req = req.json(&b);
    }
    match req.send().await {
        Ok(r) => {
            let st = r.status().as_u16();
            (st, r.text().await.unwrap_or_default())
        }
        Err(e) => (0, e.to_string()),
    }
}

/// VmRSS of `pid` in kB.
fn rss_kb(pid: u32) -> i64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap()
}

/// Each station thread's scheduling, grouped by thread name.
fn thread_scheduling(pid: u32) -> BTreeMap<String, BTreeMap<String, usize>> {
    let mut out: BTreeMap<String, BTreeMap<String, usize>> = BTreeMap::new();
    let Ok(dir) = std::fs::read_dir(format!("/proc/{pid}/task")) else { return out };
    for task in dir.flatten() {
        let Ok(stat) = std::fs::read_to_string(task.path().join("stat")) else { continue };
        if let Some((name, s)) = motus_realtime::parse_stat(&stat) {
            *out.entry(name).or_default().entry(s.to_string()).or_default() += 1;
        }
    }
    out
}

/// A number from the environment, else `default`.
fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name).ok().and_then(|s| s.parse().ok()).unwrap_or(default)
}

fn percentile(sorted: &[Duration], p: f64) -> Duration {
    if sorted.is_empty() {
        return Duration::ZERO;
    }
    let rank = ((p / 100.0) * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

fn ms(d: Duration) -> String {
    format!("{:.1} ms", d.as_secs_f64() * 1e3)
}

/// What the HTTP clients did.
#[derive(Default)]
struct HttpTally {
    ok: u64,
    other_status: BTreeMap<u16, u64>,
    errors: u64,
    latencies: Vec<Duration>,
}

/// What the monitor saw on the machine during the run.
#[derive(Default)]
struct Seen {
    /// Axis -> distinct faults reported.
    faults: BTreeMap<String, BTreeSet<String>>,
    /// Distinct supervisor diagnoses while it said "not safe to run" outside an E-stop.
    trips: BTreeSet<String>,
}

#[test]
fn two_hundred_clients_and_a_login_burst_do_not_starve_the_machine() {
    let seconds = env_or("MOTUS_LOAD_SECONDS", 20);
    // Unset: `motus demo` as a user starts it (its default policy).
    let realtime = std::env::var("MOTUS_LOAD_REALTIME").ok();
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let addr = format!("127.0.0.1:{port}");
    let debug = PathBuf::from(common::MOTUS);
    let release =
        debug.parent().and_then(|d| d.parent()).map(|t| t.join("release/motus")).unwrap_or_default();
    let bin = if release.exists() { release } else { debug };
    // The station's log (the real-time line, every alarm raised) stays for reading.
    let stderr_path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("cli_demo_load.stderr");
    println!("station log: {}", stderr_path.display());
    let mut args = vec!["demo".to_owned(), "--listen".to_owned(), addr.clone()];
    if let Some(policy) = &realtime {
        args.extend(["--realtime".to_owned(), policy.clone()]);
    }
    println!("demo: {} {}", bin.display(), args.join(" "));
    let mut child = Command::new(&bin)
        .args(&args)
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(&stderr_path).unwrap())
        .spawn()
        .unwrap();
    let pid = child.id();
    let out = child.stdout.take().unwrap();
    let _demo = Demo(child);
    let mut lines = BufReader::new(out).lines();
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut password = None;
    while password.is_none() && Instant::now() < deadline {
        let l = lines.next().expect("demo exited").unwrap();
        password = l.strip_prefix("administrator login: user admin, password ").map(|p| p.trim().to_owned());
    }
    let password = password.unwrap();
    std::thread::spawn(move || for _ in lines {});
    let stderr = std::fs::read_to_string(&stderr_path).unwrap_or_default();
    let realtime_line = stderr.lines().find(|l| l.starts_with("real-time:")).unwrap_or("(none)").to_owned();
    println!("station: {realtime_line}");

    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    let report = rt.block_on(run(format!("http://{addr}"), password, pid, seconds, realtime.is_none()));

    println!("station threads (name: scheduling x count):");
    for (name, s) in thread_scheduling(pid) {
        let s: Vec<String> = s.iter().map(|(k, n)| format!("{k} x{n}")).collect();
        println!("  {name}: {}", s.join(", "));
    }
    let stderr = std::fs::read_to_string(&stderr_path).unwrap_or_default();
    let warnings: Vec<&str> = stderr.lines().filter(|l| l.contains("WARN") || l.contains("ERROR")).collect();
    println!("station log: {} warning/error lines; last ones:", warnings.len());
    for l in warnings.iter().rev().take(10).rev() {
        println!("  {l}");
    }
    report.check();
}

/// Everything measured, checked at the end (after printing).
struct Report {
    device_lost: Vec<String>,
    heartbeat_loss: Vec<String>,
    kv01_latch: Vec<String>,
    juggler_trips: Vec<String>,
    /// The station ran with its default policy: the figures are written for
    /// `scripts/realtime.sh`.
    default_policy: bool,
    /// E-stop request to answer, p99.
    estop_p99: Duration,
    estop_failures: Vec<String>,
    estops: usize,
    rss_growth_kb: i64,
    http_ok: u64,
    ws_without_messages: usize,
    http_clients: usize,
}

impl Report {
    fn check(&self) {
        assert!(self.estop_failures.is_empty(), "E-stop/reset failed: {:?}", self.estop_failures);
        assert!(self.estops > 0, "no E-stop was pressed");
        assert!(self.http_ok >= self.http_clients as u64, "the HTTP clients did not load the station");
        assert_eq!(self.ws_without_messages, 0, "WebSocket clients that received nothing");
        assert!(self.device_lost.is_empty(), "device-lost events under load: {:?}", self.device_lost);
        assert!(
            self.heartbeat_loss.is_empty(),
            "wheel faults (heartbeat loss) under load: {:?}",
            self.heartbeat_loss
        );
        assert!(
            self.kv01_latch.is_empty(),
            "KV-01 arm faults (time-out latch) under load: {:?}",
            self.kv01_latch
        );
        // A trip is a safe stop the supervisor explains: every one names its reason.
        for trip in &self.juggler_trips {
            assert!(trip.contains(": "), "a juggler trip without its reason: {trip}");
        }
        let trips = self.juggler_trips.iter().filter(|t| t.starts_with("supervisor: ")).count();
        println!("juggler supervisor trips (a real-time figure: printed, not asserted): {trips}");
        if self.default_policy {
            let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/realtime/from-suite");
            let mut figures = format!(
                "REALTIME suite.demo_load.juggler_trips {trips} count\nREALTIME suite.demo_load.estop.p99 {:.1} ms\n",
                self.estop_p99.as_secs_f64() * 1e3
            );
            // Each trip's diagnosis, for scripts/realtime.sh to print under its table (CI
            // keeps no output of a passing test).
            for trip in &self.juggler_trips {
                figures.push_str(&format!(
                    "REALTIME-NOTE suite.demo_load.juggler_trips {}\n",
                    trip.replace('\n', " ")
                ));
            }
            if let Err(e) = std::fs::create_dir_all(&dir)
                .and_then(|()| std::fs::write(dir.join("demo_load.log"), figures))
            {
                println!("cannot write the figures to {}: {e}", dir.display());
            }
        }
        // The memory the burst took and kept (5 s after it: the hashing buffers and the
        // blocking threads' heaps are given back by then).
        assert!(
            self.rss_growth_kb < RSS_GROWTH_LIMIT_KB,
            "the station kept {} kB after 200 concurrent logins (limit 50 MB)",
            self.rss_growth_kb
        );
    }
}

async fn run(base: String, password: String, pid: u32, seconds: u64, default_policy: bool) -> Report {
    let http_clients = env_or("MOTUS_LOAD_HTTP", HTTP_CLIENTS);
    let ws_clients = env_or("MOTUS_LOAD_WS", WS_CLIENTS);
    let c = client();
    let (st, admin) = login(&c, &base, "admin", &password).await.unwrap();
    let admin = admin.unwrap_or_else(|| panic!("admin login: {st}"));
    // The juggler starts held: release it, so that its supervisor and drives run.
    let (st, b) = post(&c, &base, &admin, "/api/reset", None).await;
    assert_eq!(st, 200, "{b}");
    // The class of viewers the load logs in with.
    let mut sessions = Vec::new();
    for i in 0..VIEWERS {
        let name = format!("load{i:02}");
        let body = json!({ "name": name, "password": VIEWER_PASSWORD, "role": "viewer" });
        let (st, b) = post(&c, &base, &admin, "/api/users", Some(body)).await;
        assert_eq!(st, 200, "add {name}: {b}");
        let (st, s) = login(&c, &base, &name, VIEWER_PASSWORD).await.unwrap();
        sessions.push(s.unwrap_or_else(|| panic!("login {name}: {st}")));
    }
    let groups = get_json(&c, &base, &admin, "/api/groups").await;
    let group_of: BTreeMap<String, String> = groups
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|g| {
            let id = g["id"].as_str().unwrap().to_owned();
            g["axes"].as_array().unwrap().iter().map(move |a| (a.as_str().unwrap().to_owned(), id.clone()))
        })
        .collect();
    tokio::time::sleep(Duration::from_secs(3)).await;
    let alarms = get_json(&c, &base, &admin, "/api/alarms").await;
    let baseline_alarm =
        alarms["history"].as_array().unwrap().iter().filter_map(|a| a["id"].as_i64()).max().unwrap_or(0);
    let rss_start = rss_kb(pid);
    println!(
        "load: {http_clients} HTTP + {ws_clients} WebSocket clients for {seconds} s; station RSS {} MB",
        rss_start / 1024
    );

    let t0 = tokio::time::Instant::now();
    let end = t0 + Duration::from_secs(seconds);
    let tally = Arc::new(Mutex::new(HttpTally::default()));
    let mut tasks = Vec::new();
    for i in 0..http_clients {
        let (base, s, tally) = (base.clone(), sessions[i % VIEWERS].clone(), Arc::clone(&tally));
        tasks.push(tokio::spawn(async move {
            let c = client();
            let paths = ["/api/axes", "/api/safety", "/api/scene"];
            let mut mine = HttpTally::default();
            let mut n = i;
            while tokio::time::Instant::now() < end {
                let path = paths[n % paths.len()];
                n += 1;
                let sent = Instant::now();
                match c.get(format!("{base}{path}")).header("Cookie", &s.cookie).send().await {
                    Ok(r) if r.status() == 200 => {
                        let _ = r.bytes().await;
                        mine.ok += 1;
                        mine.latencies.push(sent.elapsed());
                    }
                    Ok(r) => *mine.other_status.entry(r.status().as_u16()).or_default() += 1,
                    Err(_) => {
                        mine.errors += 1;
                        tokio::time::sleep(Duration::from_millis(100)).await;
                    }
                }
            }
            let mut t = tally.lock().unwrap();
            t.ok += mine.ok;
            t.errors += mine.errors;
            for (k, v) in mine.other_status {
                *t.other_status.entry(k).or_default() += v;
            }
            t.latencies.extend(mine.latencies);
        }));
    }
    let ws_counts = Arc::new(Mutex::new(Vec::new()));
    for i in 0..ws_clients {
        let (base, s, counts) = (base.clone(), sessions[i % VIEWERS].clone(), Arc::clone(&ws_counts));
        tasks.push(tokio::spawn(async move {
            let url = format!("{}/api/ws", base.replace("http://", "ws://"));
            let mut req = url.into_client_request().unwrap();
            req.headers_mut().insert("Cookie", s.cookie.parse().unwrap());
            let mut messages = 0u64;
            match tokio::time::timeout(REQUEST_TIMEOUT, tokio_tungstenite::connect_async(req)).await {
                Ok(Ok((mut ws, _))) => {
                    while let Ok(Some(Ok(_))) = tokio::time::timeout_at(end, ws.next()).await {
                        messages += 1;
                    }
                }
                Ok(Err(e)) => println!("WebSocket {i}: {e}"),
                Err(_) => println!("WebSocket {i}: connect timed out"),
            }
            counts.lock().unwrap().push(messages);
        }));
    }
    // The monitor: what the machine reports, four times a second.
    let seen = Arc::new(Mutex::new(Seen::default()));
    {
        let (base, admin, seen) = (base.clone(), admin.clone(), Arc::clone(&seen));
        tasks.push(tokio::spawn(async move {
            let c = client();
            while tokio::time::Instant::now() < end {
                if let Ok(r) = c.get(format!("{base}/api/axes")).header("Cookie", &admin.cookie).send().await
                {
                    if let Ok(Value::Array(axes)) = r.json::<Value>().await {
                        let mut s = seen.lock().unwrap();
                        for a in axes {
                            if let (Some(id), Some(f)) = (a["id"].as_str(), a["fault"].as_str()) {
                                s.faults.entry(id.to_owned()).or_default().insert(f.to_owned());
                            }
                        }
                    }
                }
                if let Ok(r) =
                    c.get(format!("{base}/api/safety")).header("Cookie", &admin.cookie).send().await
                {
                    if let Ok(v) = r.json::<Value>().await {
                        if v["safe_to_run"] == json!(false) && v["estop"] != json!(true) {
                            let d = v["diagnosis"].as_str().unwrap_or("?").to_owned();
                            seen.lock().unwrap().trips.insert(d);
                        }
                    }
                }
                tokio::time::sleep(Duration::from_millis(250)).await;
            }
        }));
    }
    // The administrator: E-stop, then reset 300 ms later, every second.
    let mut estop_lat = Vec::new();
    let mut reset_lat = Vec::new();
    let mut estop_failures = Vec::new();
    {
        let c = client();
        let mut tick = tokio::time::interval(Duration::from_secs(1));
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        tick.tick().await;
        while tokio::time::Instant::now() + Duration::from_millis(500) < end {
            tick.tick().await;
            let sent = Instant::now();
            let (st, b) = post(&c, &base, &admin, "/api/estop", None).await;
            estop_lat.push(sent.elapsed());
            if st != 200 {
                estop_failures.push(format!("estop {st}: {b}"));
            }
            tokio::time::sleep(Duration::from_millis(300)).await;
            let sent = Instant::now();
            let (st, b) = post(&c, &base, &admin, "/api/reset", None).await;
            reset_lat.push(sent.elapsed());
            if st != 200 {
                estop_failures.push(format!("reset {st}: {b}"));
            }
        }
    }
    for t in tasks {
        t.await.unwrap();
    }
    let elapsed = t0.elapsed().as_secs_f64();
    let mut tally = std::mem::take(&mut *tally.lock().unwrap());
    tally.latencies.sort();
    let ws_counts = ws_counts.lock().unwrap().clone();
    let ws_total: u64 = ws_counts.iter().sum();
    let ws_without_messages = ws_counts.iter().filter(|&&n| n == 0).count() + ws_clients - ws_counts.len();
    estop_lat.sort();
    reset_lat.sort();
    println!(
        "HTTP: {} answered 200 ({:.0}/s), other statuses {:?}, connection errors {}; latency p50 {} p99 {} max {}",
        tally.ok,
        tally.ok as f64 / elapsed,
        tally.other_status,
        tally.errors,
        ms(percentile(&tally.latencies, 50.0)),
        ms(percentile(&tally.latencies, 99.0)),
        ms(percentile(&tally.latencies, 100.0)),
    );
    println!(
        "WebSocket: {} messages ({:.1}/s per client), {} clients without a message",
        ws_total,
        ws_total as f64 / elapsed / ws_clients.max(1) as f64,
        ws_without_messages
    );
    println!(
        "E-stop latency over {} presses: p50 {} p99 {} max {}; reset p50 {} p99 {} max {}",
        estop_lat.len(),
        ms(percentile(&estop_lat, 50.0)),
        ms(percentile(&estop_lat, 99.0)),
        ms(percentile(&estop_lat, 100.0)),
        ms(percentile(&reset_lat, 50.0)),
        ms(percentile(&reset_lat, 99.0)),
        ms(percentile(&reset_lat, 100.0)),
    );

    // 200 concurrent logins: most with wrong passwords, for various users, some right.
    tokio::time::sleep(Duration::from_secs(2)).await;
    let rss_before = rss_kb(pid);
    let users: Vec<String> = ["admin", "root", "teacher", "nobody"]
        .iter()
        .map(|s| (*s).to_owned())
        .chain((0..VIEWERS).map(|i| format!("load{i:02}")))
        .collect();
    let burst_start = Instant::now();
    let mut logins = Vec::new();
    for i in 0..LOGINS {
        let base = base.clone();
        let (user, pw) = if i % 10 == 0 {
            (format!("load{:02}", (i / 10) % VIEWERS), VIEWER_PASSWORD.to_owned())
        } else {
            (users[i % users.len()].clone(), format!("wrong-password-{i:04}"))
        };
        logins.push(tokio::spawn(async move {
            let c = client();
            match login(&c, &base, &user, &pw).await {
                Ok((st, _)) => st,
                Err(_) => 0,
            }
        }));
    }
    let mut statuses: BTreeMap<u16, usize> = BTreeMap::new();
    for l in logins {
        *statuses.entry(l.await.unwrap()).or_default() += 1;
    }
    let burst = burst_start.elapsed();
    let rss_after = rss_kb(pid);
    tokio::time::sleep(Duration::from_secs(5)).await;
    let rss_later = rss_kb(pid);
    println!("{LOGINS} concurrent logins in {}: statuses {statuses:?} (0 = no answer)", ms(burst));
    println!(
        "station RSS: {} kB at the start, {} kB before the logins, {} kB right after (growth {} kB), {} kB 5 s later",
        rss_start,
        rss_before,
        rss_after,
        rss_after - rss_before,
        rss_later
    );

    // What the machine said.
    let alarms = get_json(&c, &base, &admin, "/api/alarms").await;
    let new_alarms: Vec<&Value> = alarms["history"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| a["id"].as_i64().unwrap_or(0) > baseline_alarm)
        .collect();
    let mut by_code: BTreeMap<String, usize> = BTreeMap::new();
    for a in &new_alarms {
        *by_code.entry(a["code"].as_str().unwrap_or("?").to_owned()).or_default() += 1;
    }
    println!("alarms raised during the run: {by_code:?}");
    let describe = |a: &Value| {
        format!(
            "{} {}: {}",
            a["code"].as_str().unwrap_or("?"),
            a["source"].as_str().unwrap_or("?"),
            a["message"].as_str().unwrap_or("?")
        )
    };
    let mentions = |a: &Value, words: &[&str]| {
        let text = describe(a).to_lowercase();
        words.iter().any(|w| text.contains(w))
    };
    let device_lost: Vec<String> = new_alarms
        .iter()
        .filter(|a| {
            a["code"] == json!("device_disconnected") || mentions(a, &["disconnected", "device lost"])
        })
        .map(|a| describe(a))
        .collect();
    let seen = std::mem::take(&mut *seen.lock().unwrap());
    let group_faults = |group: &str| -> Vec<String> {
        seen.faults
            .iter()
            .filter(|(axis, _)| group_of.get(*axis).map(String::as_str) == Some(group))
            .map(|(axis, f)| format!("{axis}: {f:?}"))
            .collect()
    };
    let omni =
        group_of.iter().find(|(a, _)| a.starts_with("wheel")).map(|(_, g)| g.clone()).unwrap_or_default();
    let arm =
        group_of.iter().find(|(a, _)| a.starts_with("joint")).map(|(_, g)| g.clone()).unwrap_or_default();
    let mut heartbeat_loss = group_faults(&omni);
    heartbeat_loss
        .extend(new_alarms.iter().filter(|a| mentions(a, &["8130", "heartbeat"])).map(|a| describe(a)));
    let mut kv01_latch = group_faults(&arm);
    kv01_latch.extend(
        new_alarms
            .iter()
            .filter(|a| {
                a["code"] == json!("device_latched")
                    || (mentions(a, &["kv01", "kv-01", "arm"])
                        && mentions(a, &["time-out", "timeout", "timed out"]))
            })
            .map(|a| describe(a)),
    );
    let mut juggler_trips: Vec<String> = seen.trips.iter().map(|d| format!("supervisor: {d}")).collect();
    juggler_trips
        .extend(new_alarms.iter().filter(|a| a["code"] == json!("safe_to_run_false")).map(|a| describe(a)));
    let other_faults: Vec<String> = seen
        .faults
        .iter()
        .filter(|(axis, _)| {
            let g = group_of.get(*axis).map(String::as_str).unwrap_or("");
            g != omni && g != arm
        })
        .map(|(axis, f)| format!("{axis}: {f:?}"))
        .collect();
    println!("device-lost events: {} {device_lost:?}", device_lost.len());
    println!("heartbeat loss (wheel faults, EMCY 0x8130): {} {heartbeat_loss:?}", heartbeat_loss.len());
    println!("KV-01 time-out latch (arm faults, device_latched): {} {kv01_latch:?}", kv01_latch.len());
    println!("juggler trips: {} {juggler_trips:?}", juggler_trips.len());
    println!("other axis faults seen (E-stop stops the juggler's drives by its lease): {other_faults:?}");
    Report {
        device_lost,
        heartbeat_loss,
        kv01_latch,
        juggler_trips,
        default_policy,
        estop_p99: percentile(&estop_lat, 99.0),
        estop_failures,
        estops: estop_lat.len(),
        rss_growth_kb: rss_later - rss_before,
        http_ok: tally.ok,
        ws_without_messages,
        http_clients,
    }
}
