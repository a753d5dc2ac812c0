//! Load measurement: N WebSocket clients (default 50) on a station streaming at 20 Hz.
//! Reports the server's CPU use (from /proc/<pid>/stat of the server process: utime +
//! stime over the window), the frame rate each client gets, the update latency (client
//! receive time minus the frame's server time stamp; same host clock) p50/p99/max, and
//! the HMI first-load time (GET / + /app.js + /style.css on a fresh connection).
//!
//! ```text
//! cargo run --release -p motus-station-web --example ws_load -- [--clients 50] [--secs 10] [--rate 20]
//! ```
//! The server runs in a child process (this binary with `--serve`) so its CPU is measured
//! alone.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use futures_util::StreamExt;
use motus_lab::{HashParams, Lab, LabConfig, MemoryStore, Role, UnixMs};
use motus_station_web::{start, FakeBackend, WebConfig};
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::Message;

const PW: &str = "load-password-1";

fn arg(name: &str, default: f64) -> f64 {
    let args: Vec<String> = std::env::args().collect();
    args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).map_or(default, |v| v.parse().unwrap())
}

fn serve(rate: f64) {
    let mut cfg = LabConfig::default();
    cfg.sessions.cookie.secure = false;
    cfg.password.hash = HashParams { memory_kib: 64, iterations: 1, parallelism: 1 };
    let lab = Arc::new(Lab::new(Arc::new(MemoryStore::new()), cfg));
    lab.users().add("load", PW, Role::Viewer, UnixMs::from(SystemTime::now())).unwrap();
    let h = start(
        WebConfig { listen: "127.0.0.1:0".parse().unwrap(), ws_rate_hz: rate, ..WebConfig::default() },
        Arc::new(FakeBackend::new()),
        lab,
    )
    .unwrap();
    println!("{}", h.addr());
    // Ends when the parent closes our stdin.
    let mut s = String::new();
    while std::io::stdin().read_line(&mut s).map(|n| n > 0).unwrap_or(false) {}
}

fn cpu_ticks(pid: u32) -> u64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap();
    let after = stat.rsplit_once(')').unwrap().1;
    let f: Vec<&str> = after.split_whitespace().collect();
    // Fields 14 and 15 of proc(5) (utime, stime) are at 11 and 12 after "pid (comm)".
    f[11].parse::<u64>().unwrap() + f[12].parse::<u64>().unwrap()
}

fn clk_tck() -> f64 {
    Command::new("getconf")
        .arg("CLK_TCK")
        .output()
        .ok()
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .and_then(|s| s.trim().parse().ok())
        .unwrap_or(100.0)
}

fn now_us() -> u64 {
    u64::try_from(SystemTime::now().duration_since(UNIX_EPOCH).unwrap().as_micros()).unwrap()
}

fn pct(v: &[u64], p: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let i = ((v.len() - 1) as f64 * p).round() as usize;
    v[i] as f64 / 1000.0
}

#[tokio::main]
async fn main() {
    let rate = arg("--rate", 20.0);
    if std::env::args().any(|a| a == "--serve") {
        serve(rate);
        return;
    }
    let clients = arg("--clients", 50.0) as usize;
    let secs = arg("--secs", 10.0);
    let mut child = Command::new(std::env::current_exe().unwrap())
        .args(["--serve", "--rate", &rate.to_string()])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let addr = line.trim().to_string();
    let base = format!("http://{addr}");

    // HMI first load: fresh client (new connection) each time.
    let mut loads = Vec::new();
    for _ in 0..20 {
        let http = reqwest::Client::new();
        let t = Instant::now();
        for p in ["/", "/app.js", "/style.css"] {
            let r = http.get(format!("{base}{p}")).send().await.unwrap();
            assert!(r.status().is_success());
            r.bytes().await.unwrap();
        }
        loads.push(u64::try_from(t.elapsed().as_micros()).unwrap());
    }
    let first_load = loads[0];
    loads.sort_unstable();

    let http = reqwest::Client::new();
    let r = http
        .post(format!("{base}/api/login"))
        .json(&serde_json::json!({ "user": "load", "password": PW }))
        .send()
        .await
        .unwrap();
    let cookie = r.headers()["set-cookie"].to_str().unwrap().split(';').next().unwrap().to_string();

    let mut tasks = Vec::new();
    for _ in 0..clients {
        let mut req = format!("ws://{addr}/api/ws").into_client_request().unwrap();
        req.headers_mut().insert("Cookie", cookie.parse().unwrap());
        let (mut ws, _) = tokio_tungstenite::connect_async(req).await.unwrap();
        tasks.push(tokio::spawn(async move {
            let mut lat = Vec::new();
            let end = Instant::now() + Duration::from_secs_f64(secs + 1.0);
            let warm = Instant::now() + Duration::from_secs(1);
            while Instant::now() < end {
                let Ok(Some(Ok(Message::Text(t)))) =
                    tokio::time::timeout(Duration::from_secs(2), ws.next()).await
                else {
                    break;
                };
                if Instant::now() < warm {
                    continue;
                }
                if let Some(i) = t.find("\"t_us\":") {
                    let rest = &t[i + 7..];
                    let ts: u64 = rest[..rest.find(|c: char| !c.is_ascii_digit()).unwrap()].parse().unwrap();
                    lat.push(now_us().saturating_sub(ts));
                }
            }
            lat
        }));
    }
    // Measure CPU over the same window as the clients (after their 1 s warm-up).
    tokio::time::sleep(Duration::from_secs(1)).await;
    let pid = child.id();
    let (c0, t0) = (cpu_ticks(pid), Instant::now());
    tokio::time::sleep(Duration::from_secs_f64(secs)).await;
    let (c1, wall) = (cpu_ticks(pid), t0.elapsed().as_secs_f64());
    let mut all = Vec::new();
    let mut rates = Vec::new();
    for t in tasks {
        let l = t.await.unwrap();
        rates.push(l.len() as f64 / secs);
        all.extend(l);
    }
    drop(child.stdin.take());
    let _ = child.wait();
    all.sort_unstable();
    let cpu = (c1 - c0) as f64 / clk_tck() / wall * 100.0;
    let min_rate = rates.iter().copied().fold(f64::INFINITY, f64::min);
    let mean_rate = rates.iter().sum::<f64>() / rates.len() as f64;
    println!("clients: {clients}, rate: {rate} Hz, window: {secs} s");
    println!("server CPU: {cpu:.1} % of one core");
    println!("frames/s per client: mean {mean_rate:.2}, min {min_rate:.2}");
    println!(
        "update latency ms: p50 {:.2}, p99 {:.2}, max {:.2} ({} frames)",
        pct(&all, 0.5),
        pct(&all, 0.99),
        pct(&all, 1.0),
        all.len()
    );
    println!(
        "HMI first load (/, app.js, style.css; new connection): first {:.2} ms, median {:.2} ms, max {:.2} ms",
        first_load as f64 / 1000.0, pct(&loads, 0.5), pct(&loads, 1.0)
    );
}
