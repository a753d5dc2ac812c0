//! A camera per machine, seen through the station: `GET /api/groups/{id}/camera.mjpg`.
//!
//! The answer is an MJPEG stream (`multipart/x-mixed-replace`, one JPEG per part, which
//! every browser shows in an `<img>`), for logged-in users only (401 otherwise, audited;
//! the stream ends when the session ends or expires, and when the station stops). Cameras
//! need no route from the browser: the station draws the simulated ones
//! ([`render::frame`], [`FRAMES_PER_SECOND`]) and fetches the external ones for each viewer
//! ([`relay`]). Bounded: at most [`MAX_STREAMS`] streams at once and
//! [`MAX_STREAMS_PER_USER`] per user (503 beyond, audited).

pub mod relay;
pub mod render;

use std::collections::HashMap;
use std::convert::Infallible;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use axum::body::{Body, Bytes};
use axum::extract::{Path, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use tokio::sync::mpsc;

use motus_lab::{AuditEntry, AuditOutcome};

use crate::auth::authenticate;
use crate::backend::CameraFeed;
use crate::error::ApiError;
use crate::server::{AppState, Inner};

/// Frames per second of a simulated camera.
pub const FRAMES_PER_SECOND: f64 = 15.0;
/// Camera streams open at once, every user together.
pub const MAX_STREAMS: usize = 32;
/// Camera streams one user may hold open at once.
pub const MAX_STREAMS_PER_USER: usize = 4;
/// The part boundary of the streams the station sends.
pub const BOUNDARY: &str = "motus-camera-frame";
/// How often a stream checks that its viewer's session is still valid.
const SESSION_CHECK: Duration = Duration::from_secs(1);
/// A viewer that takes no frame for this long (connected, not reading) loses its stream.
const STALLED_VIEWER: Duration = Duration::from_secs(30);

/// The camera streams open now, per user.
#[derive(Debug, Default)]
pub struct Streams {
    open: Mutex<HashMap<String, usize>>,
}

/// One open stream; closes it when dropped.
pub struct StreamTicket {
    state: AppState,
    user: String,
}

impl Streams {
    /// Opens a stream for `user`, or says which bound refuses it.
    fn open(state: &AppState, user: &str) -> Result<StreamTicket, String> {
        let mut open = state.cameras.open.lock().unwrap_or_else(PoisonError::into_inner);
        let total: usize = open.values().sum();
        let mine = open.get(user).copied().unwrap_or(0);
        if total >= MAX_STREAMS {
            return Err(format!("{MAX_STREAMS} camera streams are open on this station: try again later"));
        }
        if mine >= MAX_STREAMS_PER_USER {
            return Err(format!("you have {MAX_STREAMS_PER_USER} camera streams open already: close one"));
        }
        *open.entry(user.to_string()).or_insert(0) += 1;
        Ok(StreamTicket { state: Arc::clone(state), user: user.to_string() })
    }

    /// Camera streams open now.
    #[must_use]
    pub fn count(&self) -> usize {
        self.open.lock().unwrap_or_else(PoisonError::into_inner).values().sum()
    }
}

impl Drop for StreamTicket {
    fn drop(&mut self) {
        let mut open = self.state.cameras.open.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(n) = open.get_mut(&self.user) {
            *n = n.saturating_sub(1);
            if *n == 0 {
                open.remove(&self.user);
            }
        }
    }
}

/// One JPEG as a part of the stream.
#[must_use]
pub fn part(jpeg: &[u8]) -> Bytes {
    let mut out = Vec::with_capacity(jpeg.len() + 96);
    out.extend_from_slice(
        format!("--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {}\r\n\r\n", jpeg.len())
            .as_bytes(),
    );
    out.extend_from_slice(jpeg);
    out.extend_from_slice(b"\r\n");
    Bytes::from(out)
}

/// Where a stream's frames go: ends when the viewer left, the session ended or the station
/// stops.
pub struct Viewer {
    tx: mpsc::Sender<Bytes>,
    state: AppState,
    token_hash: String,
    checked: Instant,
    _ticket: StreamTicket,
}

impl Viewer {
    /// Sends one frame; `false` when the stream is over.
    pub async fn send(&mut self, jpeg: &[u8]) -> bool {
        if *self.state.shutdown.borrow() {
            return false;
        }
        if self.checked.elapsed() >= SESSION_CHECK {
            self.checked = Instant::now();
            if !crate::ws::session_alive(&self.state, &self.token_hash, self.state.now()) {
                return false;
            }
        }
        let mut shutdown = self.state.shutdown.clone();
        tokio::select! {
            sent = tokio::time::timeout(STALLED_VIEWER, self.tx.send(part(jpeg))) => matches!(sent, Ok(Ok(()))),
            _ = shutdown.changed() => false,
        }
    }

    /// The station's state.
    #[must_use]
    pub fn state(&self) -> &Inner {
        &self.state
    }
}

/// `GET /api/groups/{id}/camera.mjpg`.
///
/// # Errors
/// 401 without a session, 404 for a group without a camera, 503 beyond the stream bounds;
/// each refusal is audited (action `camera`).
pub async fn stream(
    State(state): State<AppState>,
    Path(group): Path<String>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let target = format!("GET /api/groups/{group}/camera.mjpg");
    let refuse = |user: &str, e: ApiError| {
        let message = format!("{} {}: {}", e.status.as_u16(), e.error, e.detail_text());
        let outcome = if e.status == StatusCode::NOT_FOUND {
            AuditOutcome::Error(message)
        } else {
            AuditOutcome::Denied(message)
        };
        let entry = AuditEntry {
            time: state.now(),
            user: user.into(),
            action: "camera".into(),
            target: target.clone(),
            outcome,
        };
        if let Err(err) = state.lab.audit().append(&entry) {
            tracing::error!(error = %err, "audit write failed");
        }
        e.mark_audited()
    };
    let auth = authenticate(&state, &headers).map_err(|e| refuse("anonymous", e))?;
    let user = auth.session.user.clone();
    let Some(feed) = state.backend.camera(&group) else {
        return Err(refuse(&user, ApiError::not_found(format!("group {group:?} has no camera"))));
    };
    let ticket = Streams::open(&state, &user)
        .map_err(|why| refuse(&user, ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "busy", why)))?;
    // Two frames in flight at most: a slow viewer gets fewer frames, never a queue.
    let (tx, rx) = mpsc::channel::<Bytes>(2);
    let viewer = Viewer {
        tx,
        state: Arc::clone(&state),
        token_hash: auth.session.token_hash.clone(),
        checked: Instant::now(),
        _ticket: ticket,
    };
    match feed {
        CameraFeed::Simulated => {
            tokio::spawn(simulated(viewer, group));
        }
        CameraFeed::Http(url) => {
            tokio::spawn(relay::relay(viewer, url));
        }
    }
    let body = futures_util::stream::unfold(rx, |mut rx| async move {
        rx.recv().await.map(|b| (Ok::<Bytes, Infallible>(b), rx))
    });
    Ok((
        [
            (header::CONTENT_TYPE, format!("multipart/x-mixed-replace; boundary={BOUNDARY}")),
            (header::CACHE_CONTROL, "no-store".to_string()),
        ],
        Body::from_stream(body),
    )
        .into_response())
}

/// The simulated camera of `group`: its axes drawn [`FRAMES_PER_SECOND`] times a second.
async fn simulated(mut viewer: Viewer, group: String) {
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / FRAMES_PER_SECOND));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let started = Instant::now();
    loop {
        tick.tick().await;
        let backend = Arc::clone(&viewer.state().backend);
        let group = group.clone();
        let t = started.elapsed().as_secs_f64();
        let drawn = tokio::task::spawn_blocking(move || {
            let axes: Vec<_> =
                backend.axes().into_iter().filter(|a| a.group.as_deref() == Some(group.as_str())).collect();
            render::frame(&axes, t)
        })
        .await;
        let jpeg = match drawn {
            Ok(Ok(jpeg)) => jpeg,
            Ok(Err(e)) => {
                tracing::error!(error = %e, "camera frame not encoded");
                return;
            }
            Err(_) => return,
        };
        if !viewer.send(&jpeg).await {
            return;
        }
    }
}
