//! The web face of a Motus station: an HTTP/JSON API with an OpenAPI document, a WebSocket
//! stream of live state, and an embedded web HMI for the remote laboratory
//! (`specs/remote-lab.md`).
//!
//! - [`backend::MachineBackend`]: what the web layer needs from the machine; the station's
//!   machine (`motus-station-machine`) implements it, and the API tests run against it on a
//!   simulated cell (`crates/station-machine/tests/web_*.rs`).
//! - [`server`]: the axum router, [`server::serve`] (async) and [`server::start`] (blocking,
//!   returns a [`server::WebHandle`]).
//! - [`listener`]: the connections under the router (time-outs, caps, graceful shutdown).
//! - Users, sessions (cookie + CSRF), the login limiter, reservations, authorisation, the
//!   audit log and alarms are `motus-lab`'s: every command goes through its `authorize` and
//!   is written to its audit log. No route sets SafeToRun.

#![forbid(unsafe_code)]

pub mod api_cnc;
pub mod api_lab;
pub mod api_machine;
pub mod assets;
pub mod auth;
pub mod backend;
pub mod camera;
pub mod clock;
pub mod error;
pub mod listener;
pub mod machines;
pub mod openapi;
pub mod queue;
pub mod server;
pub mod ws;

pub use backend::{
    AxisAction, AxisLimits, AxisParameters, AxisView, BackendError, Caller, CameraFeed, ExecutedPathView,
    GroupAction, GroupKind, GroupView, MachineBackend, PredictedReach, ProgramCheck, ProgramDiagnostic,
    ProgramInfo, ProgramPreview, ProgramStatus, RobotScene, RunState, SafetyView, Sample, SampleBatch,
    SceneView, SignalView, TaskView,
};
pub use clock::{Clock, OffsetClock, SystemClock};
pub use error::ApiError;
pub use server::{raise_fd_limit, router, serve, serve_on, start, WebConfig, WebError, WebHandle};
