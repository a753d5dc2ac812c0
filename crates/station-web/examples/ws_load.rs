//! Load measurement against a running station (e.g. `motus demo`): N WebSocket clients
//! (default 50) on its state stream. Reports the frame rate each client gets, the update
//! latency (client receive time minus the frame's server time stamp; same host clock)
//! p50/p99/max, the HMI first-load time (GET / + /app.js + /style.css on a fresh
//! connection) and, with `--pid`, the server's CPU use (from /proc/<pid>/stat: utime +
//! stime over the window).
//!
//! ```text
//! cargo run --release -p motus-station-web --example ws_load -- --url http://127.0.0.1:8080 \
//!     --user admin --password <password> [--pid <station pid>] [--clients 50] [--secs 10]
//! ```
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use std::process::Command;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use futures_util::StreamExt;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::Message;

/// The value after `name` on the command line.
fn arg_str(name: &str) -> Option<String> {
    let args: Vec<String> = std::env::args().collect();
    args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).cloned()
}

fn arg(name: &str, default: f64) -> f64 {
    arg_str(name).map_or(default, |v| v.parse().unwrap())
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
    let usage = "usage: ws_load --url http://HOST:PORT --user USER --password PASSWORD [--pid PID] [--clients N] [--secs S]";
    let base = arg_str("--url").expect(usage).trim_end_matches('/').to_string();
    let user = arg_str("--user").expect(usage);
    let password = arg_str("--password").expect(usage);
    let pid: Option<u32> = arg_str("--pid").map(|p| p.parse().unwrap());
    let clients = arg("--clients", 50.0) as usize;
    let secs = arg("--secs", 10.0);
    let addr = base.split_once("://").map_or(base.as_str(), |(_, a)| a).to_string();
    let ws_base = if base.starts_with("https://") { "wss" } else { "ws" };

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
        .json(&serde_json::json!({ "user": user, "password": password }))
        .send()
        .await
        .unwrap();
    assert!(r.status().is_success(), "login: {}", r.status());
    let cookie = r.headers()["set-cookie"].to_str().unwrap().split(';').next().unwrap().to_string();

    let mut tasks = Vec::new();
    for _ in 0..clients {
        let mut req = format!("{ws_base}://{addr}/api/ws").into_client_request().unwrap();
        req.headers_mut().insert("Cookie", cookie.parse().unwrap());
        req.headers_mut().insert("Origin", base.parse().unwrap());
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
    let (c0, t0) = (pid.map(cpu_ticks), Instant::now());
    tokio::time::sleep(Duration::from_secs_f64(secs)).await;
    let (c1, wall) = (pid.map(cpu_ticks), t0.elapsed().as_secs_f64());
    let mut all = Vec::new();
    let mut rates = Vec::new();
    for t in tasks {
        let l = t.await.unwrap();
        rates.push(l.len() as f64 / secs);
        all.extend(l);
    }
    all.sort_unstable();
    let cpu = c0.zip(c1).map(|(c0, c1)| (c1 - c0) as f64 / clk_tck() / wall * 100.0);
    let min_rate = rates.iter().copied().fold(f64::INFINITY, f64::min);
    let mean_rate = rates.iter().sum::<f64>() / rates.len() as f64;
    println!("station: {base}, clients: {clients}, window: {secs} s");
    match cpu {
        Some(cpu) => println!("server CPU: {cpu:.1} % of one core"),
        None => println!("server CPU: not measured (give --pid)"),
    }
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
