//! The HTTP server: configuration, shared state, the router (every route of the API, the
//! WebSocket and the embedded HMI), [`serve`] (async) and [`start`] (blocking, for the CLI).

use std::future::Future;
use std::net::SocketAddr;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use axum::routing::{delete, get, post, put};
use axum::Router;
use motus_lab::{Lab, UnixMs};
use tokio::net::TcpListener;
use tokio::sync::{oneshot, watch};

use crate::backend::MachineBackend;
use crate::clock::{Clock, SystemClock};
use crate::listener::{self, Limits};
use crate::{api_cnc, api_lab, api_machine, assets, auth, openapi, ws};

/// Server settings.
#[derive(Clone)]
pub struct WebConfig {
    /// Address to listen on (`127.0.0.1:0` picks a free port).
    pub listen: SocketAddr,
    /// The station name used in reservations, authorisation and the audit log.
    pub station: String,
    /// WebSocket state frames per second (default 20).
    pub ws_rate_hz: f64,
    /// How often due end-of-slot cleanups are executed, and free machines given to the first
    /// student in their queue (default 1 s).
    pub cleanup_interval: Duration,
    /// How long a slot given from a machine's queue lasts (default 15 min; shortened to the
    /// machine's next booked slot).
    pub instant_slot: Duration,
    /// The clock (tests inject an [`crate::clock::OffsetClock`]).
    pub clock: Arc<dyn Clock>,
    /// Longest time from a connection's accept, or from the first byte of its next request,
    /// to the request's complete head (default 10 s); then the connection is closed.
    pub header_read_timeout: Duration,
    /// Longest pause between requests on a keep-alive connection (default 60 s).
    pub idle_timeout: Duration,
    /// Open HTTP connections at most (default 1024). A new connection is still served at the
    /// cap: the oldest idle connection (or one still sending its head) is closed for it.
    pub max_connections: usize,
    /// Open WebSockets at most, counted apart from HTTP connections (default 256); beyond
    /// it an upgrade is answered 503.
    pub max_websockets: usize,
    /// At shutdown, how long requests in progress may finish before their connections are
    /// dropped (default 1 s).
    pub shutdown_grace: Duration,
    /// Origins (`scheme://host[:port]`) whose pages may open the WebSocket. Empty (the
    /// default): the served origin, `http://<listen address>:<port>`, plus `localhost`,
    /// `127.0.0.1` and `[::1]` on a loopback address (and every local interface address and
    /// the host name on an unspecified one, `0.0.0.0`); see [`ws::served_origins`].
    pub allowed_origins: Vec<String>,
}

impl std::fmt::Debug for WebConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WebConfig")
            .field("listen", &self.listen)
            .field("station", &self.station)
            .field("ws_rate_hz", &self.ws_rate_hz)
            .field("cleanup_interval", &self.cleanup_interval)
            .field("instant_slot", &self.instant_slot)
            .field("header_read_timeout", &self.header_read_timeout)
            .field("idle_timeout", &self.idle_timeout)
            .field("max_connections", &self.max_connections)
            .field("max_websockets", &self.max_websockets)
            .field("shutdown_grace", &self.shutdown_grace)
            .field("allowed_origins", &self.allowed_origins)
            .finish_non_exhaustive()
    }
}

impl Default for WebConfig {
    fn default() -> Self {
        WebConfig {
            listen: SocketAddr::from(([127, 0, 0, 1], 8080)),
            station: "station".to_string(),
            ws_rate_hz: 20.0,
            cleanup_interval: Duration::from_secs(1),
            instant_slot: Duration::from_secs(15 * 60),
            clock: Arc::new(SystemClock),
            header_read_timeout: Duration::from_secs(10),
            idle_timeout: Duration::from_secs(60),
            max_connections: 1024,
            max_websockets: 256,
            shutdown_grace: Duration::from_secs(1),
            allowed_origins: Vec::new(),
        }
    }
}

impl WebConfig {
    fn validate(&self) -> Result<(), WebError> {
        let rate = self.ws_rate_hz;
        if !(rate.is_finite() && rate > 0.0 && rate <= 1000.0) {
            return Err(WebError::Config(format!("ws_rate_hz {rate} not in (0, 1000]")));
        }
        if self.header_read_timeout.is_zero() || self.idle_timeout.is_zero() {
            return Err(WebError::Config("header_read_timeout and idle_timeout must be > 0".into()));
        }
        if self.max_connections == 0 {
            return Err(WebError::Config("max_connections must be > 0".into()));
        }
        ws::resolve_origins(&self.allowed_origins, self.listen).map_err(WebError::Config)?;
        Ok(())
    }

    fn limits(&self) -> Limits {
        Limits {
            header_read_timeout: self.header_read_timeout,
            idle_timeout: self.idle_timeout,
            max_connections: self.max_connections,
            max_websockets: self.max_websockets,
            shutdown_grace: self.shutdown_grace,
        }
    }
}

/// Raises this process's soft limit of open descriptors (`RLIMIT_NOFILE`) to its hard
/// limit, so that the connection cap, not the descriptor table, bounds the server. Returns
/// the soft limit now in force. Idempotent; [`serve_on`] calls it.
///
/// # Errors
/// The system's refusal.
pub fn raise_fd_limit() -> Result<u64, nix::Error> {
    use nix::sys::resource::{getrlimit, setrlimit, Resource};
    let (soft, hard) = getrlimit(Resource::RLIMIT_NOFILE)?;
    if soft < hard {
        setrlimit(Resource::RLIMIT_NOFILE, hard, hard)?;
    }
    Ok(getrlimit(Resource::RLIMIT_NOFILE)?.0)
}

/// Why the server could not start.
#[derive(Debug, thiserror::Error)]
pub enum WebError {
    /// Binding the address or running the server failed.
    #[error("web server I/O on {addr}: {source}")]
    Io {
        /// The address.
        addr: SocketAddr,
        /// The error.
        source: std::io::Error,
    },
    /// The configuration is unusable.
    #[error("invalid web configuration: {0}")]
    Config(String),
}

/// Everything the handlers share.
pub struct Inner {
    /// Settings.
    pub config: WebConfig,
    /// The machine.
    pub backend: Arc<dyn MachineBackend>,
    /// Users, sessions, reservations, audit, alarms.
    pub lab: Arc<Lab>,
    /// Latest WebSocket state frame (JSON).
    pub frames: watch::Sender<Arc<str>>,
    /// Becomes true when the server shuts down.
    pub shutdown: watch::Receiver<bool>,
    /// Set when reservations or alarms changed: the next frame re-reads them.
    pub lab_changed: AtomicBool,
    /// The camera streams open now.
    pub cameras: crate::camera::Streams,
    /// Held while a reservation is booked (a machine's slots against the whole cell's).
    pub booking: tokio::sync::Mutex<()>,
    /// Students waiting for a machine.
    pub queues: crate::queue::Queues,
}

impl Inner {
    /// The current time.
    #[must_use]
    pub fn now(&self) -> UnixMs {
        self.config.clock.now()
    }
}

/// Shared state of the handlers.
pub type AppState = Arc<Inner>;

/// The router with every route. Paths use axum's `:param` syntax; the OpenAPI document
/// lists the same paths with `{param}`.
pub fn router(state: AppState) -> Router {
    Router::new()
        .route("/", get(assets::index))
        .route("/app.js", get(assets::app_js))
        .route("/style.css", get(assets::style_css))
        .route("/api/openapi.json", get(openapi::handler))
        .route("/api/login", post(api_lab::login))
        .route("/api/logout", post(api_lab::logout))
        .route("/api/session", get(api_lab::session))
        .route("/api/sessions/:user/end", post(api_lab::end_session))
        .route("/api/axes", get(api_machine::axes))
        .route("/api/axes/:id/jog", post(api_machine::jog))
        .route("/api/axes/:id/move", post(api_machine::move_to))
        .route("/api/axes/:id/home", post(api_machine::home))
        .route("/api/axes/:id/stop", post(api_machine::stop))
        .route("/api/axes/:id/parameters", put(api_machine::parameters))
        .route("/api/estop", post(api_machine::estop))
        .route("/api/reset", post(api_machine::reset))
        .route("/api/safety", get(api_machine::safety))
        .route("/api/safety/rules", put(api_machine::safety_rules))
        .route("/api/groups", get(api_machine::groups))
        .route("/api/groups/:id", post(api_machine::group_command))
        .route("/api/programs", get(api_machine::programs).post(api_machine::upload_program))
        .route("/api/programs/status", get(api_machine::program_status))
        .route("/api/programs/hold", post(api_machine::hold_program))
        .route("/api/programs/resume", post(api_machine::resume_program))
        .route("/api/programs/stop", post(api_machine::stop_program))
        .route("/api/programs/:id/check", post(api_machine::check_program))
        .route("/api/programs/:id/run", post(api_machine::run_program))
        .route("/api/programs/:id/preview", get(api_cnc::preview))
        .route("/api/programs/override", post(api_cnc::set_override))
        .route("/api/programs/single-block", post(api_cnc::set_single_block))
        .route("/api/programs/path", get(api_cnc::executed_path))
        .route("/api/mdi", post(api_cnc::mdi))
        .route(
            "/api/programs/:id/publish",
            post(api_machine::publish_program).delete(api_machine::unpublish_program),
        )
        .route("/api/signals", get(api_machine::signals))
        .route("/api/samples", get(api_machine::samples))
        .route("/api/samples.csv", get(api_machine::samples_csv))
        .route("/api/tasks", get(api_machine::tasks))
        .route("/api/trace.csv", get(api_machine::trace_csv))
        .route("/api/scene", get(api_machine::scene))
        .route("/api/camera", get(api_machine::camera))
        .route("/api/groups/:id/camera.mjpg", get(crate::camera::stream))
        .route("/api/reservations", get(api_lab::reservations).post(api_lab::book))
        .route("/api/reservations/:id", delete(api_lab::cancel))
        .route("/api/queues", get(crate::queue::queues))
        .route("/api/machines/:id/queue", post(crate::queue::join).delete(crate::queue::leave))
        .route("/api/audit", get(api_lab::audit))
        .route("/api/alarms", get(api_lab::alarms))
        .route("/api/alarms/:id/ack", post(api_lab::ack_alarm))
        .route("/api/users", get(api_lab::users).post(api_lab::add_user))
        .route("/api/users/:name", delete(api_lab::delete_user))
        .route("/api/ws", get(ws::handler))
        .fallback(api_lab::not_found)
        .layer(axum::middleware::from_fn_with_state(Arc::clone(&state), auth::audit_refusals))
        .with_state(state)
}

/// Serves on `listener` until `shutdown` completes; then WebSocket streams and idle
/// connections end, requests in progress get `shutdown_grace` to finish, and the function
/// returns.
///
/// Connections are served by [`crate::listener`]: HTTP/1.1 with upgrades, the header-read
/// and idle time-outs and the connection caps of `config`; handlers see the peer as
/// `ConnectInfo<SocketAddr>`. Raises the descriptor limit first ([`raise_fd_limit`]).
///
/// # Errors
/// [`WebError::Config`] for a bad rate, limit or origin, [`WebError::Io`] if the listener
/// has no address.
pub async fn serve_on(
    listener: TcpListener,
    mut config: WebConfig,
    backend: Arc<dyn MachineBackend>,
    lab: Arc<Lab>,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), WebError> {
    config.validate()?;
    let addr = listener.local_addr().map_err(|source| WebError::Io { addr: config.listen, source })?;
    config.allowed_origins = ws::resolve_origins(&config.allowed_origins, addr).map_err(WebError::Config)?;
    match raise_fd_limit() {
        Ok(n) => {
            let needed = config.max_connections.saturating_add(config.max_websockets);
            if u64::try_from(needed).unwrap_or(u64::MAX) >= n {
                tracing::warn!(limit = n, needed, "descriptor limit below the connection caps");
            }
        }
        Err(e) => tracing::warn!(error = %e, "cannot raise the descriptor limit"),
    }
    let (frames, _) = watch::channel::<Arc<str>>(Arc::from("{}"));
    let (stop_tx, stop_rx) = watch::channel(false);
    let state = Arc::new(Inner {
        config,
        backend,
        lab,
        frames,
        shutdown: stop_rx,
        lab_changed: AtomicBool::new(true),
        cameras: crate::camera::Streams::default(),
        booking: tokio::sync::Mutex::new(()),
        queues: crate::queue::Queues::default(),
    });
    let broadcaster = tokio::spawn(ws::broadcast(Arc::clone(&state)));
    let sweeper = tokio::spawn(api_lab::cleanup_loop(Arc::clone(&state)));
    tracing::info!(%addr, station = %state.config.station, origins = ?state.config.allowed_origins, "web server listening");
    let limits = state.config.limits();
    listener::serve(listener, router(Arc::clone(&state)), limits, shutdown, stop_tx).await;
    broadcaster.abort();
    sweeper.abort();
    Ok(())
}

/// Binds `config.listen` and serves forever.
///
/// # Errors
/// [`WebError`] if binding or serving fails.
pub async fn serve(
    config: WebConfig,
    backend: Arc<dyn MachineBackend>,
    lab: Arc<Lab>,
) -> Result<(), WebError> {
    let listener = TcpListener::bind(config.listen)
        .await
        .map_err(|source| WebError::Io { addr: config.listen, source })?;
    serve_on(listener, config, backend, lab, std::future::pending()).await
}

/// A server started by [`start`]; dropping it shuts the server down.
#[derive(Debug)]
pub struct WebHandle {
    addr: SocketAddr,
    stop: Option<oneshot::Sender<()>>,
    thread: Option<JoinHandle<Result<(), WebError>>>,
}

impl WebHandle {
    /// The bound address (with the port actually chosen).
    #[must_use]
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// `http://addr`.
    #[must_use]
    pub fn url(&self) -> String {
        format!("http://{}", self.addr)
    }

    /// Stops the server and waits for it: requests in progress get the configured
    /// `shutdown_grace`, blocking work left behind (a backend call that does not return)
    /// another 250 ms, then it is abandoned.
    ///
    /// # Errors
    /// The server's own error, if it failed while running.
    pub fn shutdown(mut self) -> Result<(), WebError> {
        self.stop_and_join()
    }

    fn stop_and_join(&mut self) -> Result<(), WebError> {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(r)) => r,
            Some(Err(_)) => Err(WebError::Config("web server thread panicked".into())),
            None => Ok(()),
        }
    }
}

impl Drop for WebHandle {
    fn drop(&mut self) {
        if let Err(e) = self.stop_and_join() {
            tracing::error!(error = %e, "web server ended with an error");
        }
    }
}

/// Starts the server on its own tokio runtime (two worker threads) in a background thread
/// and returns once it listens. For synchronous callers such as the CLI.
///
/// # Errors
/// [`WebError::Io`] if the runtime cannot be built or the address cannot be bound.
pub fn start(
    config: WebConfig,
    backend: Arc<dyn MachineBackend>,
    lab: Arc<Lab>,
) -> Result<WebHandle, WebError> {
    config.validate()?;
    let listen = config.listen;
    let io = |source| WebError::Io { addr: listen, source };
    // One worker per core beyond the first, at most 4: the machine's threads keep a core
    // (with 2 workers on a 2-core host, a saturating client load took both cores, and the
    // juggler's 9 ms lease expired 3-4 times a minute; 1 worker: 1, with more requests served).
    let workers = std::thread::available_parallelism().map_or(1, |n| n.get().saturating_sub(1).clamp(1, 4));
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(workers)
        .thread_name("motus-web")
        // Web work yields to the machine: workers and blocking threads at nice +10 under the
        // process's real-time policy (docs/decisions.md, "Real-time priorities").
        .on_thread_start(motus_realtime::demote_current_thread_for_web)
        // Blocking work (logins, device commands, program checks) on at most 32 threads: a
        // burst of 200 logins otherwise started 200 threads that periodic blocking tasks kept
        // alive for good (tokio wakes its idle threads in turn), +136 MB that never went back.
        .max_blocking_threads(32)
        .enable_all()
        .build()
        .map_err(io)?;
    // Bound with std so that `start` also works when called from inside another runtime.
    let std_listener = std::net::TcpListener::bind(listen).map_err(io)?;
    std_listener.set_nonblocking(true).map_err(io)?;
    let addr = std_listener.local_addr().map_err(io)?;
    let (tx, rx) = oneshot::channel::<()>();
    let thread = std::thread::Builder::new()
        .name("motus-web-main".into())
        .spawn(move || {
            motus_realtime::demote_current_thread_for_web();
            let r = rt.block_on(async move {
                let listener =
                    TcpListener::from_std(std_listener).map_err(|source| WebError::Io { addr, source })?;
                serve_on(listener, config, backend, lab, async {
                    let _ = rx.await;
                })
                .await
            });
            rt.shutdown_timeout(Duration::from_millis(250));
            r
        })
        .map_err(io)?;
    Ok(WebHandle { addr, stop: Some(tx), thread: Some(thread) })
}
