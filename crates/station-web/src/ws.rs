//! `GET /api/ws`: live state frames for logged-in users.
//!
//! One broadcaster task builds a JSON frame `rate` times a second (axes, safety, program
//! status, active alarms, slot holder, new samples, scene) and publishes it on a `watch`
//! channel; each client task forwards the latest frame (a slow client skips frames rather
//! than queueing them). The broadcaster also raises and clears the lab alarms for
//! SafeToRun and the E-stop. A client is closed when its session ends or expires.
//!
//! An upgrade from a browser page is accepted only from the allowed origins
//! (`WebConfig::allowed_origins`, by default the origins the server is reached at): a
//! cross-site page cannot use a student's cookie to watch the station.

use std::net::{IpAddr, Ipv6Addr, SocketAddr};
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::State;
use axum::http::{header, HeaderMap};
use axum::response::{IntoResponse, Response};
use motus_lab::{AuditEntry, AuditOutcome, Severity, UnixMs};
use serde_json::{json, Value};

use crate::auth::authenticate;
use crate::error::ApiError;
use crate::server::{AppState, Inner};

/// Samples per frame at most (the newest are kept).
const MAX_SAMPLES_PER_FRAME: usize = 200;

/// `origin` as `scheme://host:port` (lower case, the scheme's default port written out, an
/// IPv6 address in its canonical form), or `None` if it is not an `http`/`https` origin
/// (a path, user info, `null`...).
#[must_use]
pub fn normalize_origin(origin: &str) -> Option<String> {
    let (scheme, rest) = origin.trim().split_once("://")?;
    let scheme = scheme.to_ascii_lowercase();
    let default_port: u16 = match scheme.as_str() {
        "http" => 80,
        "https" => 443,
        _ => return None,
    };
    let rest = rest.strip_suffix('/').unwrap_or(rest);
    if rest.is_empty() || rest.contains(['/', '?', '#', '@', ' ', '\\']) {
        return None;
    }
    let (host, port) = if let Some(v6) = rest.strip_prefix('[') {
        let (h, after) = v6.split_once(']')?;
        let ip: Ipv6Addr = h.parse().ok()?;
        let port = if after.is_empty() { None } else { Some(after.strip_prefix(':')?) };
        (format!("[{ip}]"), port)
    } else {
        match rest.rsplit_once(':') {
            Some((h, p)) => (h.to_ascii_lowercase(), Some(p)),
            None => (rest.to_ascii_lowercase(), None),
        }
    };
    if host.is_empty() || (host.contains(':') && !host.starts_with('[')) {
        return None;
    }
    let port = match port {
        None => default_port,
        Some(p) => p.parse().ok()?,
    };
    Some(format!("{scheme}://{host}:{port}"))
}

fn http_origin(host: &str, port: u16) -> Option<String> {
    normalize_origin(&format!("http://{host}:{port}"))
}

fn ip_host(ip: IpAddr) -> String {
    match ip {
        IpAddr::V4(v4) => v4.to_string(),
        IpAddr::V6(v6) => format!("[{v6}]"),
    }
}

/// The origins of pages served from `addr`: `http://<ip>:<port>`; on a loopback address
/// also `localhost`, `127.0.0.1` and `[::1]`; on an unspecified address (`0.0.0.0`, `::`)
/// those, every local interface address (IPv6 link-local ones aside) and the host name.
#[must_use]
pub fn served_origins(addr: SocketAddr) -> Vec<String> {
    let port = addr.port();
    let ip = addr.ip();
    let mut hosts = vec![ip_host(ip)];
    if ip.is_loopback() || ip.is_unspecified() {
        hosts.extend(["localhost".to_string(), "127.0.0.1".to_string(), "[::1]".to_string()]);
    }
    if ip.is_unspecified() {
        match nix::ifaddrs::getifaddrs() {
            Ok(ifs) => {
                for a in ifs.filter_map(|i| i.address) {
                    let found = a
                        .as_sockaddr_in()
                        .map(|s| IpAddr::V4(s.ip()))
                        .or_else(|| a.as_sockaddr_in6().map(|s| IpAddr::V6(s.ip())));
                    match found {
                        Some(IpAddr::V6(v6))
                            if v6.segments().first().is_some_and(|s| s & 0xffc0 == 0xfe80) => {}
                        Some(ip) if ip.is_ipv4() || addr.is_ipv6() => hosts.push(ip_host(ip)),
                        _ => {}
                    }
                }
            }
            Err(e) => tracing::warn!(error = %e, "cannot list the interface addresses"),
        }
        if let Ok(name) = nix::unistd::gethostname() {
            if let Some(name) = name.to_str() {
                hosts.push(name.to_string());
            }
        }
    }
    let mut out: Vec<String> = hosts.iter().filter_map(|h| http_origin(h, port)).collect();
    let mut seen = std::collections::HashSet::new();
    out.retain(|o| seen.insert(o.clone()));
    out
}

/// The allowed WebSocket origins: `configured` normalised, or [`served_origins`] of `addr`
/// when it is empty.
///
/// # Errors
/// The first configured entry that is not an origin.
pub fn resolve_origins(configured: &[String], addr: SocketAddr) -> Result<Vec<String>, String> {
    if configured.is_empty() {
        return Ok(served_origins(addr));
    }
    configured
        .iter()
        .map(|o| {
            normalize_origin(o).ok_or_else(|| format!("allowed origin {o:?} is not scheme://host[:port]"))
        })
        .collect()
}

/// Cross-site WebSocket hijacking guard: a browser always sends `Origin`; when it does, it
/// must be one of the station's allowed origins (the `Host` header proves nothing: a
/// rebound DNS name sends a matching one). A request without `Origin` is not a browser's
/// and still needs a valid session.
fn check_origin(headers: &HeaderMap, allowed: &[String]) -> Result<(), String> {
    let Some(origin) = headers.get(header::ORIGIN) else { return Ok(()) };
    let text = String::from_utf8_lossy(origin.as_bytes());
    match normalize_origin(&text) {
        Some(o) if allowed.contains(&o) => Ok(()),
        _ => Err(format!("WebSocket from origin {text:?}, which is not allowed")),
    }
}

/// `GET /api/ws` (401 without a session, 403 from an origin not allowed, audited).
pub async fn handler(State(state): State<AppState>, headers: HeaderMap, ws: WebSocketUpgrade) -> Response {
    if let Err(why) = check_origin(&headers, &state.config.allowed_origins) {
        let user =
            authenticate(&state, &headers).map_or_else(|_| "anonymous".to_string(), |a| a.session.user);
        let entry = AuditEntry {
            time: state.now(),
            user,
            action: "websocket".into(),
            target: "GET /api/ws".into(),
            outcome: AuditOutcome::Denied(why.clone()),
        };
        if let Err(e) = state.lab.audit().append(&entry) {
            tracing::error!(error = %e, "audit write failed");
        }
        return ApiError::forbidden(why).mark_audited().into_response();
    }
    match authenticate(&state, &headers) {
        Ok(auth) => {
            let hash = auth.session.token_hash;
            ws.on_upgrade(move |socket| client(state, socket, hash))
        }
        Err(e) => e.into_response(),
    }
}

/// True while the session exists and has not expired (read without extending it).
pub(crate) fn session_alive(state: &Inner, token_hash: &str, now: UnixMs) -> bool {
    let policy = state.lab.sessions().policy();
    match state.lab.store().get_session(token_hash) {
        Ok(Some(rec)) => {
            now < rec.created.plus(Duration::from_secs(policy.absolute_timeout_secs))
                && now < rec.last_seen.plus(Duration::from_secs(policy.idle_timeout_secs))
        }
        Ok(None) => false,
        Err(e) => {
            tracing::error!(error = %e, "session check failed");
            false
        }
    }
}

async fn client(state: AppState, mut socket: WebSocket, token_hash: String) {
    let mut rx = state.frames.subscribe();
    let mut shutdown = state.shutdown.clone();
    let mut check = tokio::time::interval(Duration::from_secs(1));
    let hello =
        json!({ "type": "hello", "signals": state.backend.signals(), "rate_hz": state.config.ws_rate_hz });
    if socket.send(Message::Text(hello.to_string())).await.is_err() {
        return;
    }
    loop {
        tokio::select! {
            changed = rx.changed() => {
                if changed.is_err() {
                    break;
                }
                let frame = rx.borrow_and_update().clone();
                if socket.send(Message::Text(frame.to_string())).await.is_err() {
                    break;
                }
            }
            msg = socket.recv() => match msg {
                None | Some(Err(_)) | Some(Ok(Message::Close(_))) => break,
                Some(Ok(_)) => {}
            },
            _ = check.tick() => {
                if !session_alive(&state, &token_hash, state.now()) {
                    let _ = socket.send(Message::Text(json!({ "type": "logout" }).to_string())).await;
                    break;
                }
            }
            _ = shutdown.changed() => break,
        }
    }
    let _ = socket.send(Message::Close(None)).await;
}

/// Microseconds since the epoch (frame time stamps for latency measurement).
#[must_use]
pub fn now_us() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX))
}

/// Alarm bookkeeping and cached slow-changing parts of the frame.
#[derive(Default)]
struct Broadcaster {
    seq: u64,
    cursor: u64,
    unsafe_alarm: Option<bool>,
    estop_alarm: Option<bool>,
    alarms: Value,
    holder: Value,
    slots: Value,
}

impl Broadcaster {
    fn alarm_edge(
        state: &Inner,
        prev: &mut Option<bool>,
        now_on: bool,
        code: &str,
        source: &str,
        msg: &str,
    ) -> bool {
        if *prev == Some(now_on) {
            return false;
        }
        *prev = Some(now_on);
        let now = state.now();
        let r = if now_on {
            state.lab.alarms().raise(code, source, msg, Severity::Critical, now).map(|_| ())
        } else {
            state.lab.alarms().clear(code, source, now).map(|_| ())
        };
        if let Err(e) = r {
            tracing::error!(error = %e, code, "alarm update failed");
        }
        true
    }

    /// One tick: alarms always; the frame only when someone listens.
    fn tick(&mut self, state: &Inner) -> Option<Arc<str>> {
        let safety = state.backend.safety();
        let unsafe_now = !safety.safe_to_run && !safety.estop;
        let diag = safety.diagnosis.clone().unwrap_or_else(|| "SafeToRun is false".into());
        let mut changed = Self::alarm_edge(
            state,
            &mut self.unsafe_alarm,
            unsafe_now,
            "safe_to_run_false",
            "supervisor",
            &diag,
        );
        changed |= Self::alarm_edge(
            state,
            &mut self.estop_alarm,
            safety.estop,
            "estop",
            "station",
            "emergency stop pressed",
        );
        let listening = state.frames.receiver_count() > 0;
        if !listening {
            self.cursor = state.backend.samples_since(self.cursor).cursor;
            return None;
        }
        let dirty = state.lab_changed.swap(false, Ordering::SeqCst);
        if changed || dirty || self.seq % 10 == 0 {
            self.alarms = state.lab.alarms().active().map(|a| json!(a)).unwrap_or(Value::Null);
            self.holder = state
                .lab
                .reservations()
                .active_at(&state.config.station, state.now())
                .map(|r| json!(r))
                .unwrap_or(Value::Null);
            self.slots = json!(crate::machines::running_slots(state, state.now()));
        }
        self.seq += 1;
        let batch = state.backend.samples_since(self.cursor);
        self.cursor = batch.cursor;
        let skip = batch.samples.len().saturating_sub(MAX_SAMPLES_PER_FRAME);
        let samples: Vec<_> = batch.samples.into_iter().skip(skip).collect();
        let frame = json!({
            "type": "state",
            "seq": self.seq,
            "t_us": now_us(),
            "axes": state.backend.axes(),
            "safety": safety,
            "program": state.backend.program_status(),
            "alarms": self.alarms,
            "slot": self.holder,
            "slots": self.slots,
            "samples": samples,
            "scene": state.backend.scene(),
        });
        Some(Arc::from(frame.to_string()))
    }
}

/// Publishes frames at `ws_rate_hz` until shutdown.
pub async fn broadcast(state: AppState) {
    let period = Duration::from_secs_f64(1.0 / state.config.ws_rate_hz);
    let mut tick = tokio::time::interval(period);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut shutdown = state.shutdown.clone();
    let mut b = Broadcaster::default();
    loop {
        tokio::select! {
            _ = tick.tick() => {}
            _ = shutdown.changed() => return,
        }
        let s = Arc::clone(&state);
        let r = tokio::task::spawn_blocking(move || {
            let frame = b.tick(&s);
            (b, frame)
        })
        .await;
        match r {
            Ok((back, frame)) => {
                b = back;
                if let Some(f) = frame {
                    state.frames.send_replace(f);
                }
            }
            Err(e) => {
                tracing::error!(error = %e, "frame builder failed");
                b = Broadcaster::default();
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]
mod tests {
    use super::*;

    #[test]
    fn origins_are_normalised() {
        assert_eq!(normalize_origin("http://127.0.0.1:8080").unwrap(), "http://127.0.0.1:8080");
        assert_eq!(normalize_origin("HTTP://Station.Lab").unwrap(), "http://station.lab:80");
        assert_eq!(normalize_origin("https://lab.example.org/").unwrap(), "https://lab.example.org:443");
        assert_eq!(normalize_origin("http://[0:0::1]:9000").unwrap(), "http://[::1]:9000");
        for bad in [
            "null",
            "",
            "station:8080",
            "ftp://a",
            "http://",
            "http://a/b",
            "http://u@a",
            "http://a:b:1",
            "http://a:x",
        ] {
            assert_eq!(normalize_origin(bad), None, "{bad}");
        }
    }

    #[test]
    fn served_origins_of_loopback_and_specific_addresses() {
        let o = served_origins("127.0.0.1:8080".parse().unwrap());
        assert_eq!(o, ["http://127.0.0.1:8080", "http://localhost:8080", "http://[::1]:8080"]);
        let o = served_origins("192.168.1.20:80".parse().unwrap());
        assert_eq!(o, ["http://192.168.1.20:80"]);
        let any = served_origins("0.0.0.0:8080".parse().unwrap());
        assert!(any.contains(&"http://localhost:8080".to_string()), "{any:?}");
        assert!(any.len() >= 4, "{any:?}");
    }

    #[test]
    fn the_origin_must_be_allowed_and_the_host_header_proves_nothing() {
        let allowed = resolve_origins(&[], "127.0.0.1:8080".parse().unwrap()).unwrap();
        let with = |origin: &str, host: &str| {
            let mut h = HeaderMap::new();
            h.insert(header::ORIGIN, origin.parse().unwrap());
            h.insert(header::HOST, host.parse().unwrap());
            check_origin(&h, &allowed)
        };
        assert!(with("http://localhost:8080", "localhost:8080").is_ok());
        assert!(with("http://127.0.0.1:8080", "127.0.0.1:8080").is_ok());
        assert!(
            with("http://evil.example:8080", "evil.example:8080").is_err(),
            "rebound name, matching Host"
        );
        assert!(with("http://127.0.0.1:8081", "127.0.0.1:8080").is_err());
        assert!(check_origin(&HeaderMap::new(), &allowed).is_ok(), "no Origin: not a browser");
        let configured =
            resolve_origins(&["https://lab.example.org".into()], "0.0.0.0:443".parse().unwrap()).unwrap();
        assert_eq!(configured, ["https://lab.example.org:443"]);
        assert!(resolve_origins(&["lab.example.org".into()], "0.0.0.0:443".parse().unwrap()).is_err());
    }
}
