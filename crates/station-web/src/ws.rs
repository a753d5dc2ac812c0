//! `GET /api/ws`: live state frames for logged-in users.
//!
//! One broadcaster task builds a JSON frame `rate` times a second (axes, safety, program
//! status, active alarms, slot holder, new samples, scene) and publishes it on a `watch`
//! channel; each client task forwards the latest frame (a slow client skips frames rather
//! than queueing them). The broadcaster also raises and clears the lab alarms for
//! SafeToRun and the E-stop. A client is closed when its session ends or expires.

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::State;
use axum::http::{header, HeaderMap};
use axum::response::{IntoResponse, Response};
use motus_lab::{Severity, UnixMs};
use serde_json::{json, Value};

use crate::auth::authenticate;
use crate::error::ApiError;
use crate::server::{AppState, Inner};

/// Samples per frame at most (the newest are kept).
const MAX_SAMPLES_PER_FRAME: usize = 200;

/// Cross-site WebSocket hijacking guard: a browser always sends `Origin`; when it does, its
/// host must be the one the request was sent to.
fn same_origin(headers: &HeaderMap) -> bool {
    let Some(origin) = headers.get(header::ORIGIN).and_then(|v| v.to_str().ok()) else { return true };
    let host = headers.get(header::HOST).and_then(|v| v.to_str().ok()).unwrap_or("");
    origin.split_once("://").is_some_and(|(_, h)| h == host)
}

/// `GET /api/ws` (401 without a session, 403 from another origin).
pub async fn handler(State(state): State<AppState>, headers: HeaderMap, ws: WebSocketUpgrade) -> Response {
    if !same_origin(&headers) {
        return ApiError::forbidden("WebSocket from another origin").into_response();
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
fn session_alive(state: &Inner, token_hash: &str, now: UnixMs) -> bool {
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
