//! The connection layer under the router: our own accept loop over hyper's HTTP/1.1 server
//! (with upgrades, for the WebSocket), so that no client can hold the station's descriptors.
//!
//! - Every connection has a phase: waiting for a request head (bounded by the
//!   header-read time-out, from the accept or from the first byte of the next request),
//!   processing requests, idle between keep-alive requests (bounded by the idle time-out), or
//!   upgraded to a WebSocket. A watchdog per connection closes it when its phase's time-out
//!   passes.
//! - Open HTTP connections are capped (`max_connections`). A new connection is always
//!   served: at the cap, the oldest connection that is idle or still waiting for its head is
//!   closed at once (else the oldest busy one is shut down gracefully: its request finishes
//!   within the header-read time-out). So a flood of half-open connections cannot keep an
//!   E-stop out.
//! - WebSockets are counted and capped separately (`max_websockets`): beyond the cap an
//!   upgrade is answered 503.
//! - Shutdown: stop accepting, close idle connections, let requests in progress finish
//!   within `shutdown_grace`, then drop what is left.

use std::collections::BTreeMap;
use std::convert::Infallible;
use std::future::Future;
use std::io;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::task::{Context, Poll};
use std::time::{Duration, Instant};

use axum::body::{Body, Bytes};
use axum::extract::ConnectInfo;
use axum::http::{header, Request, Response, StatusCode};
use axum::response::IntoResponse;
use axum::Router;
use hyper::body::{Frame, Incoming, SizeHint};
use hyper::server::conn::http1;
use hyper_util::rt::TokioIo;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{watch, Notify};
use tokio::task::JoinSet;

use crate::error::ApiError;

/// The connection limits (from `WebConfig`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Limits {
    /// From the accept, or the first byte of a request, to its complete head.
    pub header_read_timeout: Duration,
    /// Between keep-alive requests.
    pub idle_timeout: Duration,
    /// Open HTTP connections (WebSockets not counted).
    pub max_connections: usize,
    /// Open WebSockets.
    pub max_websockets: usize,
    /// How long requests in progress may finish at shutdown.
    pub shutdown_grace: Duration,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// What a connection is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Waiting for (the rest of) a request head.
    Head,
    /// Requests in progress (the handler runs or the response is being written).
    Busy,
    /// Between keep-alive requests.
    Idle,
    /// Handed over to a WebSocket.
    Upgraded,
}

/// The phase of one connection: a state machine on `now`.
#[derive(Debug, Clone)]
struct Track {
    phase: Phase,
    /// When the phase began.
    since: Instant,
    in_flight: usize,
    /// When the connection was asked to go (cap or shutdown).
    evicted: Option<Instant>,
}

/// What the watchdog does about a connection now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Verdict {
    /// Keep serving; look again at the deadline (or on the next phase change).
    Wait(Option<Instant>),
    /// Let the request in progress finish, then close; close at the deadline anyway.
    Graceful(Instant),
    /// Close now (why).
    Close(&'static str),
}

impl Track {
    fn new(now: Instant) -> Self {
        Track { phase: Phase::Head, since: now, in_flight: 0, evicted: None }
    }

    /// Bytes arrived; true if the phase changed (an idle connection starts a new head).
    fn bytes_read(&mut self, now: Instant) -> bool {
        if self.phase == Phase::Idle {
            self.phase = Phase::Head;
            self.since = now;
            true
        } else {
            false
        }
    }

    /// A complete request head was parsed and handed to the router.
    fn request_started(&mut self, now: Instant) {
        self.in_flight += 1;
        if self.phase != Phase::Upgraded {
            self.phase = Phase::Busy;
            self.since = now;
        }
    }

    /// A response was written (or abandoned); true if the connection became idle.
    fn request_done(&mut self, now: Instant) -> bool {
        self.in_flight = self.in_flight.saturating_sub(1);
        if self.in_flight == 0 && self.phase == Phase::Busy {
            self.phase = Phase::Idle;
            self.since = now;
            true
        } else {
            false
        }
    }

    fn upgraded(&mut self) {
        self.phase = Phase::Upgraded;
    }

    fn evict(&mut self, now: Instant) {
        self.evicted.get_or_insert(now);
    }

    /// Closable at once without cutting a request: idle or still reading a head.
    fn is_quiet(&self) -> bool {
        matches!(self.phase, Phase::Head | Phase::Idle)
    }

    fn verdict(&self, now: Instant, limits: &Limits) -> Verdict {
        let due = |deadline: Instant, why| {
            if now >= deadline {
                Verdict::Close(why)
            } else {
                Verdict::Wait(Some(deadline))
            }
        };
        match (self.phase, self.evicted) {
            (Phase::Upgraded, _) => Verdict::Wait(None),
            (Phase::Head | Phase::Idle, Some(_)) => Verdict::Close("connection limit or shutdown"),
            (Phase::Head, None) => due(self.since + limits.header_read_timeout, "header-read time-out"),
            (Phase::Idle, None) => due(self.since + limits.idle_timeout, "idle time-out"),
            (Phase::Busy, None) => Verdict::Wait(None),
            (Phase::Busy, Some(at)) => {
                let deadline = at + limits.header_read_timeout;
                if now >= deadline {
                    Verdict::Close("request still in progress after eviction")
                } else {
                    Verdict::Graceful(deadline)
                }
            }
        }
    }
}

/// The connection to evict from `(id, quiet)` in age order: the oldest quiet one, else the
/// oldest.
fn pick_victim(conns: impl IntoIterator<Item = (u64, bool)>) -> Option<u64> {
    let mut oldest = None;
    for (id, quiet) in conns {
        if quiet {
            return Some(id);
        }
        oldest.get_or_insert(id);
    }
    oldest
}

/// One accepted connection.
struct Conn {
    id: u64,
    track: Mutex<Track>,
    /// Wakes the watchdog on a phase change or an eviction.
    wake: Notify,
    /// Held while the connection is a WebSocket.
    ws_slot: Mutex<Option<WsSlot>>,
}

impl Conn {
    fn with<R>(&self, f: impl FnOnce(&mut Track) -> R) -> R {
        f(&mut lock(&self.track))
    }
}

/// Open connections: HTTP ones by age (ids increase), WebSockets by count.
struct Registry {
    limits: Limits,
    http: Mutex<BTreeMap<u64, Arc<Conn>>>,
    websockets: AtomicUsize,
    next_id: AtomicU64,
}

impl Registry {
    fn new(limits: Limits) -> Self {
        Registry {
            limits,
            http: Mutex::new(BTreeMap::new()),
            websockets: AtomicUsize::new(0),
            next_id: AtomicU64::new(0),
        }
    }

    fn add(&self, now: Instant) -> Arc<Conn> {
        let id = self.next_id.fetch_add(1, Ordering::Relaxed);
        let conn = Arc::new(Conn {
            id,
            track: Mutex::new(Track::new(now)),
            wake: Notify::new(),
            ws_slot: Mutex::new(None),
        });
        lock(&self.http).insert(id, Arc::clone(&conn));
        conn
    }

    fn remove(&self, id: u64) {
        lock(&self.http).remove(&id);
    }

    /// Evicts connections until a new one fits under the cap; returns how many.
    fn make_room(&self, now: Instant) -> usize {
        let mut map = lock(&self.http);
        let mut n = 0;
        while map.len() >= self.limits.max_connections.max(1) {
            if !Self::evict_from(&mut map, now) {
                break;
            }
            n += 1;
        }
        n
    }

    /// Evicts one connection (the descriptors ran out); false if there is none.
    fn evict_one(&self, now: Instant) -> bool {
        Self::evict_from(&mut lock(&self.http), now)
    }

    fn evict_from(map: &mut BTreeMap<u64, Arc<Conn>>, now: Instant) -> bool {
        let victim = pick_victim(map.iter().map(|(id, c)| (*id, c.with(|t| t.is_quiet()))));
        let Some(conn) = victim.and_then(|id| map.remove(&id)) else { return false };
        conn.with(|t| t.evict(now));
        conn.wake.notify_one();
        true
    }

    /// A WebSocket slot, or `None` at the cap.
    fn try_reserve_ws(self: &Arc<Self>) -> Option<WsSlot> {
        let max = self.limits.max_websockets;
        self.websockets
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |n| (n < max).then_some(n + 1))
            .ok()
            .map(|_| WsSlot(Arc::clone(self)))
    }
}

/// One counted WebSocket; released on drop.
struct WsSlot(Arc<Registry>);

impl Drop for WsSlot {
    fn drop(&mut self) {
        self.0.websockets.fetch_sub(1, Ordering::AcqRel);
    }
}

/// The socket, reporting reads to the connection's `Track` and leaving the registry when
/// it closes (also after an upgrade: the WebSocket owns it then).
struct TrackedIo {
    stream: TcpStream,
    conn: Arc<Conn>,
    registry: Arc<Registry>,
}

impl AsyncRead for TrackedIo {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let before = buf.filled().len();
        let r = Pin::new(&mut self.stream).poll_read(cx, buf);
        if matches!(r, Poll::Ready(Ok(())))
            && buf.filled().len() > before
            && self.conn.with(|t| t.bytes_read(Instant::now()))
        {
            self.conn.wake.notify_one();
        }
        r
    }
}

impl AsyncWrite for TrackedIo {
    fn poll_write(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.stream).poll_write(cx, buf)
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.stream).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.stream).poll_shutdown(cx)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.stream).poll_write_vectored(cx, bufs)
    }

    fn is_write_vectored(&self) -> bool {
        self.stream.is_write_vectored()
    }
}

impl Drop for TrackedIo {
    fn drop(&mut self) {
        self.registry.remove(self.conn.id);
        drop(lock(&self.conn.ws_slot).take());
    }
}

/// Marks the end of one request when the response body is dropped (written or abandoned).
struct RequestGuard(Arc<Conn>);

impl Drop for RequestGuard {
    fn drop(&mut self) {
        if self.0.with(|t| t.request_done(Instant::now())) {
            self.0.wake.notify_one();
        }
    }
}

/// A response body carrying its request's `RequestGuard`.
struct TrackedBody {
    inner: Body,
    _guard: RequestGuard,
}

impl hyper::body::Body for TrackedBody {
    type Data = Bytes;
    type Error = axum::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, axum::Error>>> {
        Pin::new(&mut self.inner).poll_frame(cx)
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        self.inner.size_hint()
    }
}

/// The router as a hyper service for one connection: adds `ConnectInfo<SocketAddr>`, tracks
/// requests, counts WebSockets.
#[derive(Clone)]
struct ConnService {
    router: Router,
    conn: Arc<Conn>,
    registry: Arc<Registry>,
    peer: SocketAddr,
}

type ServiceFuture = Pin<Box<dyn Future<Output = Result<Response<TrackedBody>, Infallible>> + Send>>;

impl hyper::service::Service<Request<Incoming>> for ConnService {
    type Response = Response<TrackedBody>;
    type Error = Infallible;
    type Future = ServiceFuture;

    fn call(&self, mut req: Request<Incoming>) -> ServiceFuture {
        self.conn.with(|t| t.request_started(Instant::now()));
        let guard = RequestGuard(Arc::clone(&self.conn));
        let wrap = |r: Response<Body>, guard| r.map(|inner| TrackedBody { inner, _guard: guard });
        let slot = if req.headers().contains_key(header::UPGRADE) {
            match self.registry.try_reserve_ws() {
                Some(s) => Some(s),
                None => {
                    tracing::warn!(peer = %self.peer, max = self.registry.limits.max_websockets, "WebSocket refused: too many");
                    let r = ApiError::new(
                        StatusCode::SERVICE_UNAVAILABLE,
                        "busy",
                        "too many WebSocket connections",
                    )
                    .into_response();
                    return Box::pin(std::future::ready(Ok(wrap(r, guard))));
                }
            }
        } else {
            None
        };
        req.extensions_mut().insert(ConnectInfo(self.peer));
        let mut router = self.router.clone();
        let conn = Arc::clone(&self.conn);
        let registry = Arc::clone(&self.registry);
        Box::pin(async move {
            let response = match tower_service::Service::call(&mut router, req).await {
                Ok(r) => r,
                Err(never) => match never {},
            };
            if let Some(slot) = slot {
                if response.status() == StatusCode::SWITCHING_PROTOCOLS {
                    conn.with(Track::upgraded);
                    *lock(&conn.ws_slot) = Some(slot);
                    registry.remove(conn.id);
                }
            }
            Ok(wrap(response, guard))
        })
    }
}

/// Serves one connection until it ends, its phase's time-out passes or it is evicted.
async fn serve_connection(
    stream: TcpStream,
    peer: SocketAddr,
    conn: Arc<Conn>,
    registry: Arc<Registry>,
    router: Router,
    mut stop: watch::Receiver<bool>,
) {
    let limits = registry.limits;
    let service = ConnService { router, conn: Arc::clone(&conn), registry: Arc::clone(&registry), peer };
    let io = TokioIo::new(TrackedIo { stream, conn: Arc::clone(&conn), registry });
    let mut builder = http1::Builder::new();
    // Our watchdog enforces the head and idle time-outs (hyper's header-read time-out would
    // also cut idle keep-alive connections at the same, short, time).
    builder.keep_alive(true).header_read_timeout(None::<Duration>);
    let connection = builder.serve_connection(io, service).with_upgrades();
    tokio::pin!(connection);
    let mut graceful = false;
    let mut stopping = *stop.borrow();
    loop {
        let now = Instant::now();
        if stopping {
            conn.with(|t| t.evict(now));
        }
        let deadline = match conn.with(|t| t.verdict(now, &limits)) {
            Verdict::Close(why) => {
                tracing::debug!(%peer, why, "closing connection");
                return;
            }
            Verdict::Graceful(deadline) => {
                if !graceful {
                    connection.as_mut().graceful_shutdown();
                    graceful = true;
                }
                Some(deadline)
            }
            Verdict::Wait(deadline) => deadline,
        };
        let sleep = async move {
            match deadline {
                Some(d) => tokio::time::sleep_until(d.into()).await,
                None => std::future::pending().await,
            }
        };
        tokio::select! {
            r = connection.as_mut() => {
                if let Err(e) = r {
                    tracing::debug!(%peer, error = %e, "connection ended");
                }
                return;
            }
            () = sleep => {}
            () = conn.wake.notified() => {}
            _ = stop.changed(), if !stopping => stopping = true,
        }
    }
}

/// Logs accept failures at most once a second.
struct AcceptErrors {
    last: Option<Instant>,
    suppressed: u64,
}

impl AcceptErrors {
    fn log(&mut self, e: &io::Error, now: Instant) {
        if self.last.is_some_and(|t| now.duration_since(t) < Duration::from_secs(1)) {
            self.suppressed += 1;
            return;
        }
        tracing::warn!(error = %e, suppressed = self.suppressed, "accept failed");
        self.last = Some(now);
        self.suppressed = 0;
    }
}

fn out_of_descriptors(e: &io::Error) -> bool {
    matches!(e.raw_os_error(), Some(c) if c == nix::errno::Errno::EMFILE as i32 || c == nix::errno::Errno::ENFILE as i32)
}

/// Accepts and serves connections on `listener` until `shutdown` completes; then sends
/// `true` on `stop` (WebSockets and idle connections end), lets requests in progress finish
/// within `limits.shutdown_grace` and drops the rest.
pub(crate) async fn serve(
    listener: TcpListener,
    router: Router,
    limits: Limits,
    shutdown: impl Future<Output = ()>,
    stop: watch::Sender<bool>,
) {
    let registry = Arc::new(Registry::new(limits));
    let mut tasks = JoinSet::new();
    let mut errors = AcceptErrors { last: None, suppressed: 0 };
    tokio::pin!(shutdown);
    loop {
        tokio::select! {
            biased;
            () = &mut shutdown => break,
            Some(_) = tasks.join_next(), if !tasks.is_empty() => {}
            accepted = listener.accept() => match accepted {
                Ok((stream, peer)) => {
                    let now = Instant::now();
                    let evicted = registry.make_room(now);
                    if evicted > 0 {
                        tracing::debug!(evicted, max = limits.max_connections, "connection limit: oldest closed");
                    }
                    if let Err(e) = stream.set_nodelay(true) {
                        tracing::debug!(%peer, error = %e, "TCP_NODELAY");
                    }
                    let conn = registry.add(now);
                    tasks.spawn(serve_connection(stream, peer, conn, Arc::clone(&registry), router.clone(), stop.subscribe()));
                }
                Err(e) => {
                    let now = Instant::now();
                    if out_of_descriptors(&e) {
                        registry.evict_one(now);
                    }
                    errors.log(&e, now);
                    tokio::time::sleep(Duration::from_millis(10)).await;
                }
            },
        }
    }
    drop(listener);
    let _ = stop.send(true);
    let drained =
        tokio::time::timeout(limits.shutdown_grace, async { while tasks.join_next().await.is_some() {} })
            .await;
    if drained.is_err() {
        tracing::warn!(
            connections = tasks.len(),
            "requests still in progress at the shutdown deadline: dropped"
        );
        tasks.abort_all();
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]
mod tests {
    use super::*;

    fn limits() -> Limits {
        Limits {
            header_read_timeout: Duration::from_secs(10),
            idle_timeout: Duration::from_secs(60),
            max_connections: 3,
            max_websockets: 2,
            shutdown_grace: Duration::from_secs(1),
        }
    }

    #[test]
    fn a_head_must_arrive_within_the_header_read_time_out() {
        let t0 = Instant::now();
        let l = limits();
        let t = Track::new(t0);
        assert_eq!(t.verdict(t0, &l), Verdict::Wait(Some(t0 + l.header_read_timeout)));
        assert_eq!(
            t.verdict(t0 + Duration::from_millis(9_999), &l),
            Verdict::Wait(Some(t0 + l.header_read_timeout))
        );
        assert_eq!(t.verdict(t0 + l.header_read_timeout, &l), Verdict::Close("header-read time-out"));
    }

    #[test]
    fn idle_keep_alive_gets_the_idle_time_out_and_a_new_head_the_header_time_out() {
        let t0 = Instant::now();
        let l = limits();
        let mut t = Track::new(t0);
        t.request_started(t0 + Duration::from_secs(1));
        // A request in progress has no time-out of its own.
        assert_eq!(t.verdict(t0 + Duration::from_secs(1000), &l), Verdict::Wait(None));
        let done = t0 + Duration::from_secs(1001);
        assert!(t.request_done(done));
        assert_eq!(t.verdict(done + Duration::from_secs(30), &l), Verdict::Wait(Some(done + l.idle_timeout)));
        assert_eq!(t.verdict(done + l.idle_timeout, &l), Verdict::Close("idle time-out"));
        // The first byte of the next request starts the header-read time-out.
        let first = done + Duration::from_secs(5);
        assert!(t.bytes_read(first));
        assert!(!t.bytes_read(first + Duration::from_secs(1)), "more bytes of the same head");
        assert_eq!(t.verdict(first + l.header_read_timeout, &l), Verdict::Close("header-read time-out"));
    }

    #[test]
    fn pipelined_requests_stay_busy_until_the_last_response() {
        let t0 = Instant::now();
        let mut t = Track::new(t0);
        t.request_started(t0);
        t.request_started(t0);
        assert!(!t.request_done(t0));
        assert_eq!(t.phase, Phase::Busy);
        assert!(t.request_done(t0));
        assert_eq!(t.phase, Phase::Idle);
    }

    #[test]
    fn eviction_closes_quiet_connections_at_once_and_busy_ones_after_their_request() {
        let t0 = Instant::now();
        let l = limits();
        let mut head = Track::new(t0);
        head.evict(t0);
        assert!(matches!(head.verdict(t0, &l), Verdict::Close(_)));
        let mut busy = Track::new(t0);
        busy.request_started(t0);
        busy.evict(t0 + Duration::from_secs(1));
        let deadline = t0 + Duration::from_secs(1) + l.header_read_timeout;
        assert_eq!(busy.verdict(t0 + Duration::from_secs(2), &l), Verdict::Graceful(deadline));
        assert!(matches!(busy.verdict(deadline, &l), Verdict::Close(_)));
        // Its request ends: closed at once.
        busy.request_done(t0 + Duration::from_secs(3));
        assert!(matches!(busy.verdict(t0 + Duration::from_secs(3), &l), Verdict::Close(_)));
        // An upgraded connection is no longer the HTTP layer's.
        let mut ws = Track::new(t0);
        ws.request_started(t0);
        ws.upgraded();
        ws.request_done(t0);
        assert_eq!(ws.verdict(t0 + Duration::from_secs(10_000), &l), Verdict::Wait(None));
    }

    #[test]
    fn the_oldest_quiet_connection_is_evicted_first() {
        assert_eq!(pick_victim([(1, false), (2, true), (3, true)]), Some(2));
        assert_eq!(pick_victim([(1, false), (2, false)]), Some(1));
        assert_eq!(pick_victim([]), None);
    }

    #[test]
    fn the_registry_keeps_room_for_a_new_connection_and_counts_websockets() {
        let t0 = Instant::now();
        let r = Arc::new(Registry::new(limits()));
        let a = r.add(t0);
        let b = r.add(t0);
        let c = r.add(t0);
        a.with(|t| t.request_started(t0));
        assert_eq!(r.make_room(t0), 1);
        assert!(b.with(|t| t.evicted.is_some()), "the oldest quiet one");
        assert!(a.with(|t| t.evicted.is_none()) && c.with(|t| t.evicted.is_none()));
        assert_eq!(lock(&r.http).len(), 2);
        let s1 = r.try_reserve_ws().unwrap();
        let _s2 = r.try_reserve_ws().unwrap();
        assert!(r.try_reserve_ws().is_none());
        drop(s1);
        assert!(r.try_reserve_ws().is_some());
    }
}
