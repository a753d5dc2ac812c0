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
use crate::{api_lab, api_machine, assets, openapi, ws};

/// Server settings.
#[derive(Clone)]
pub struct WebConfig {
    /// Address to listen on (`127.0.0.1:0` picks a free port).
    pub listen: SocketAddr,
    /// The station name used in reservations, authorisation and the audit log.
    pub station: String,
    /// WebSocket state frames per second (default 20).
    pub ws_rate_hz: f64,
    /// How often due end-of-slot cleanups are executed (default 1 s).
    pub cleanup_interval: Duration,
    /// The clock (tests inject an [`crate::clock::OffsetClock`]).
    pub clock: Arc<dyn Clock>,
}

impl std::fmt::Debug for WebConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WebConfig")
            .field("listen", &self.listen)
            .field("station", &self.station)
            .field("ws_rate_hz", &self.ws_rate_hz)
            .field("cleanup_interval", &self.cleanup_interval)
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
            clock: Arc::new(SystemClock),
        }
    }
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
        .route("/api/signals", get(api_machine::signals))
        .route("/api/samples", get(api_machine::samples))
        .route("/api/samples.csv", get(api_machine::samples_csv))
        .route("/api/tasks", get(api_machine::tasks))
        .route("/api/trace.csv", get(api_machine::trace_csv))
        .route("/api/scene", get(api_machine::scene))
        .route("/api/camera", get(api_machine::camera))
        .route("/api/reservations", get(api_lab::reservations).post(api_lab::book))
        .route("/api/reservations/:id", delete(api_lab::cancel))
        .route("/api/audit", get(api_lab::audit))
        .route("/api/alarms", get(api_lab::alarms))
        .route("/api/alarms/:id/ack", post(api_lab::ack_alarm))
        .route("/api/users", get(api_lab::users).post(api_lab::add_user))
        .route("/api/users/:name", delete(api_lab::delete_user))
        .route("/api/ws", get(ws::handler))
        .fallback(api_lab::not_found)
        .with_state(state)
}

/// Serves on `listener` until `shutdown` completes; then WebSocket streams end, in-flight
/// requests finish, and the function returns.
///
/// # Errors
/// [`WebError::Config`] for a bad rate, [`WebError::Io`] if serving fails.
pub async fn serve_on(
    listener: TcpListener,
    config: WebConfig,
    backend: Arc<dyn MachineBackend>,
    lab: Arc<Lab>,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), WebError> {
    if !(config.ws_rate_hz.is_finite() && config.ws_rate_hz > 0.0 && config.ws_rate_hz <= 1000.0) {
        return Err(WebError::Config(format!("ws_rate_hz {} not in (0, 1000]", config.ws_rate_hz)));
    }
    let addr = listener.local_addr().map_err(|source| WebError::Io { addr: config.listen, source })?;
    let (frames, _) = watch::channel::<Arc<str>>(Arc::from("{}"));
    let (stop_tx, stop_rx) = watch::channel(false);
    let state = Arc::new(Inner {
        config,
        backend,
        lab,
        frames,
        shutdown: stop_rx,
        lab_changed: AtomicBool::new(true),
    });
    let broadcaster = tokio::spawn(ws::broadcast(Arc::clone(&state)));
    let sweeper = tokio::spawn(api_lab::cleanup_loop(Arc::clone(&state)));
    tracing::info!(%addr, station = %state.config.station, "web server listening");
    let app = router(Arc::clone(&state)).into_make_service_with_connect_info::<SocketAddr>();
    let signal = async move {
        shutdown.await;
        let _ = stop_tx.send(true);
    };
    let result = axum::serve(listener, app).with_graceful_shutdown(signal).await;
    broadcaster.abort();
    sweeper.abort();
    result.map_err(|source| WebError::Io { addr, source })
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

    /// Stops the server and waits for it (at most about a second for open streams).
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
    let listen = config.listen;
    let io = |source| WebError::Io { addr: listen, source };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("motus-web")
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
            let r = rt.block_on(async move {
                let listener =
                    TcpListener::from_std(std_listener).map_err(|source| WebError::Io { addr, source })?;
                serve_on(listener, config, backend, lab, async {
                    let _ = rx.await;
                })
                .await
            });
            rt.shutdown_timeout(Duration::from_secs(1));
            r
        })
        .map_err(io)?;
    Ok(WebHandle { addr, stop: Some(tx), thread: Some(thread) })
}
