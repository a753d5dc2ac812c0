//! The web face of a Motus station: an HTTP/JSON API with an OpenAPI document, a WebSocket
//! stream of live state, and an embedded web HMI for the remote laboratory
//! (`specs/remote-lab.md`).
//!
//! - [`backend::MachineBackend`]: what the web layer needs from the machine; the station
//!   implements it, [`fake::FakeBackend`] is an in-memory machine for tests and the
//!   `fake_station` example.
//! - [`server`]: the axum router, [`server::serve`] (async) and [`server::start`] (blocking,
//!   returns a [`server::WebHandle`]).
//! - Users, sessions (cookie + CSRF), the login limiter, reservations, authorisation, the
//!   audit log and alarms are `motus-lab`'s: every command goes through its `authorize` and
//!   is written to its audit log. No route sets SafeToRun.

#![forbid(unsafe_code)]

pub mod api_lab;
pub mod api_machine;
pub mod assets;
pub mod auth;
pub mod backend;
pub mod clock;
pub mod error;
pub mod fake;
pub mod gcode;
pub mod openapi;
pub mod server;
pub mod ws;

pub use backend::{
    AxisAction, AxisLimits, AxisParameters, AxisView, BackendError, Caller, GroupAction, GroupKind,
    GroupView, MachineBackend, PredictedReach, ProgramCheck, ProgramDiagnostic, ProgramInfo, ProgramStatus,
    RobotScene, RunState, SafetyView, Sample, SampleBatch, SceneView, SignalView, TaskView,
};
pub use clock::{Clock, OffsetClock, SystemClock};
pub use error::ApiError;
pub use fake::FakeBackend;
pub use server::{router, serve, serve_on, start, WebConfig, WebError, WebHandle};
