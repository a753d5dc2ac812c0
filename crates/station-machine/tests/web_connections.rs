//! The connection layer under the API: half-open connections cannot keep an E-stop out, the
//! header-read and idle time-outs close what clients leave open, the connection cap makes
//! room for newcomers, WebSockets are capped apart. Real sockets on 127.0.0.1, the real
//! station machine (small simulated cell) behind them.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use common::web::{Env, ADMIN_PW, VIEWER_PW};
use reqwest::StatusCode;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;

/// A request head that never ends.
const PARTIAL_HEAD: &[u8] = b"GET /api/session HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ";

/// As many half-open connections as the descriptor limit allows (client and server ends
/// are both in this process), at most `want`.
fn affordable(want: usize) -> usize {
    let limit = motus_station_web::raise_fd_limit().unwrap();
    let n = usize::try_from(limit.saturating_sub(300) / 2).unwrap().min(want);
    assert!(n >= 100, "descriptor limit {limit} too low for this test");
    n
}

/// Opens `n` connections that each send a partial request head and then nothing.
async fn half_open(addr: SocketAddr, n: usize) -> Vec<TcpStream> {
    let mut out = Vec::with_capacity(n);
    let mut left = n;
    while left > 0 {
        let k = left.min(64);
        let batch = (0..k).map(|_| async move {
            let mut s = TcpStream::connect(addr).await.unwrap();
            // The server may already have closed it (connection cap): that is fine.
            let _ = s.write_all(PARTIAL_HEAD).await;
            s
        });
        out.extend(futures_util::future::join_all(batch).await);
        left -= k;
    }
    out
}

/// True if the server closes `s` (EOF or reset) within `within`.
async fn closed_within(s: &mut TcpStream, within: Duration) -> bool {
    let end = Instant::now() + within;
    let mut buf = [0u8; 1024];
    loop {
        let left = end.saturating_duration_since(Instant::now());
        match tokio::time::timeout(left, s.read(&mut buf)).await {
            Ok(Ok(0) | Err(_)) => return true,
            Ok(Ok(_)) => {} // an error response before the close: keep reading
            Err(_) => return false,
        }
    }
}

/// How many of `conns` the server closes within `within` (all waited for together).
async fn count_closed(conns: &mut [TcpStream], within: Duration) -> usize {
    let waits = conns.iter_mut().map(|s| closed_within(s, within));
    futures_util::future::join_all(waits).await.into_iter().filter(|c| *c).count()
}

/// A fresh client logs in as admin and presses the E-stop within 5 s; then the machine
/// reports the E-stop.
async fn estop_from_a_fresh_client(env: &Env) {
    let c = tokio::time::timeout(Duration::from_secs(5), async {
        let c = env.login("admin", ADMIN_PW).await;
        assert_eq!(c.post0("/api/estop").await.0, StatusCode::OK);
        c
    })
    .await
    .expect("login + E-stop within 5 s");
    assert_eq!(c.get("/api/safety").await.1["estop"], true, "the E-stop reached the machine");
}

#[tokio::test]
async fn half_open_connections_cannot_keep_the_estop_out_and_are_closed_after_the_header_time_out() {
    let n = affordable(2000);
    let env = Env::with_web(
        |_| {},
        |w| {
            w.header_read_timeout = Duration::from_millis(500);
            w.max_connections = 512;
        },
    );
    let mut conns = half_open(env.handle.addr(), n).await;
    estop_from_a_fresh_client(&env).await;
    // Every half-open connection is closed by the server (header-read time-out or cap).
    let closed = count_closed(&mut conns, Duration::from_secs(15)).await;
    assert_eq!(closed, n, "half-open connections left open");
}

#[tokio::test]
async fn at_the_connection_cap_the_oldest_waiting_connections_make_room() {
    let n = affordable(400);
    let cap = 100;
    // A header-read time-out far beyond the test: only the cap closes connections here.
    let env = Env::with_web(
        |_| {},
        |w| {
            w.header_read_timeout = Duration::from_secs(300);
            w.max_connections = cap;
        },
    );
    let mut conns = half_open(env.handle.addr(), n).await;
    estop_from_a_fresh_client(&env).await;
    // The oldest are closed to make room for younger ones (and for the E-stop client): all
    // but the youngest `cap`, give or take the order within one batch of connects ...
    let oldest = n - cap - 64;
    assert_eq!(count_closed(&mut conns[..oldest], Duration::from_secs(10)).await, oldest);
    // ... and the youngest still wait for their head.
    let young = &mut conns[n - cap / 2..];
    assert_eq!(count_closed(young, Duration::from_millis(300)).await, 0);
}

/// Sends `GET /api/session` on `s` and reads the whole response; its status.
async fn request_on(s: &mut TcpStream) -> u16 {
    s.write_all(b"GET /api/session HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n").await.unwrap();
    let mut data = Vec::new();
    let mut buf = [0u8; 4096];
    loop {
        let n = tokio::time::timeout(Duration::from_secs(5), s.read(&mut buf)).await.unwrap().unwrap();
        assert!(n > 0, "closed before the response ended");
        data.extend_from_slice(&buf[..n]);
        let text = String::from_utf8_lossy(&data).to_string();
        if let Some((head, body)) = text.split_once("\r\n\r\n") {
            let len: usize = head
                .lines()
                .find_map(|l| {
                    l.to_ascii_lowercase().strip_prefix("content-length:").map(|v| v.trim().parse().unwrap())
                })
                .unwrap();
            if body.len() >= len {
                return head.split(' ').nth(1).unwrap().parse().unwrap();
            }
        }
    }
}

#[tokio::test]
async fn keep_alive_connections_get_the_idle_time_out_not_the_header_time_out() {
    let env = Env::with_web(
        |_| {},
        |w| {
            w.header_read_timeout = Duration::from_millis(300);
            w.idle_timeout = Duration::from_secs(6);
        },
    );
    let mut s = TcpStream::connect(env.handle.addr()).await.unwrap();
    assert_eq!(request_on(&mut s).await, 401);
    // Idle for several header-read time-outs: the connection still serves.
    tokio::time::sleep(Duration::from_millis(1500)).await;
    assert_eq!(request_on(&mut s).await, 401);
    // Then left idle: closed by the idle time-out.
    assert!(closed_within(&mut s, Duration::from_secs(20)).await);
}

fn ws_request(env: &Env, cookie: &str) -> tokio_tungstenite::tungstenite::handshake::client::Request {
    let mut req = format!("ws://{}/api/ws", env.handle.addr()).into_client_request().unwrap();
    req.headers_mut().insert("Cookie", cookie.parse().unwrap());
    req
}

#[tokio::test]
async fn websockets_are_capped_apart_from_http() {
    let env = Env::with_web(
        |_| {},
        |w| {
            w.max_websockets = 2;
            w.max_connections = 4;
        },
    );
    let c = env.login("viewer", VIEWER_PW).await;
    let cookie = c.cookie.clone().unwrap();
    let (ws1, _) = tokio_tungstenite::connect_async(ws_request(&env, &cookie)).await.unwrap();
    let (_ws2, _) = tokio_tungstenite::connect_async(ws_request(&env, &cookie)).await.unwrap();
    match tokio_tungstenite::connect_async(ws_request(&env, &cookie)).await.unwrap_err() {
        tokio_tungstenite::tungstenite::Error::Http(r) => {
            assert_eq!(r.status(), StatusCode::SERVICE_UNAVAILABLE)
        }
        other => panic!("{other}"),
    }
    // WebSockets do not take HTTP connection slots: more HTTP clients than the HTTP cap
    // minus the WebSockets are served, one after another.
    for _ in 0..6 {
        assert_eq!(env.client().get("/api/openapi.json").await.0, StatusCode::OK);
    }
    // A closed WebSocket frees its slot.
    drop(ws1);
    assert!(
        common::web::wait_for(5.0, || async {
            tokio_tungstenite::connect_async(ws_request(&env, &cookie)).await.is_ok()
        })
        .await
    );
}
