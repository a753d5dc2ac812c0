//! The CNC program runner of issue 7: the G-code interpreter ([`motus_gcode`]) runs ahead of
//! motion into the block buffer of the look-ahead planner / executor ([`motus_cnc_planner`]),
//! whose per-cycle set-points drive the axes, while M-functions and external parameters go
//! to a [`Technology`] (the drilling unit of [`motus_cnc_tech`]) with the synchronous
//! handshake: the path stops at a synchronous M-function until the technology acknowledges.
//!
//! * [`adapter`]: canonical calls -> block-buffer items (machine mm, mm/s).
//! * [`runner`]: [`runner::ProgramRun`], one CNC system stepped cycle by cycle (time passed in),
//!   with progress, feed hold / resume / stop / override / single block, and per-axis peak
//!   velocity and acceleration measured on the executed set-points.
//! * [`service`]: [`service::ProgramService`], programs run in real time on a thread (hold,
//!   resume, stop, status) for the station.
//! * [`executed`]: [`executed::ExecutedPath`], the executed path of a run for the HMI.
//! * [`technology`]: the [`Technology`] trait and [`technology::DrillingTechnology`].

#![forbid(unsafe_code)]

pub mod adapter;
pub mod executed;
pub mod runner;
pub mod service;
pub mod technology;

pub use executed::{ExecutedPath, PathBatch};
pub use runner::{Limits3, ProgramRun, RunError, RunReport, RunStatus};
pub use service::{OverrideError, ProgramService, ServiceState, ServiceStatus, SetpointSink, StatusReader};
pub use technology::{DrillingTechnology, NoTechnology, Technology, TechnologyError};

/// Number of CNC axes planned (X, Y, Z).
pub const AXES: usize = 3;
