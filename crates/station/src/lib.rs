//! # motus-station — the station's runtime core
//!
//! * [`config`]: the cell file (links, devices, axes, groups, supervisor, tasks,
//!   programs) with errors that name the file, line, column and key.
//! * [`scheduler`]: cyclic task classes on dedicated threads with jitter, execution-time
//!   and CPU statistics, an overrun policy that raises alarms, skips missed cycles and
//!   degrades safely, and is always recoverable (`reset_alarms`, `resume`).
//! * [`trace`]: watch and trace — signals, per-signal ring buffers, cursors for
//!   streaming, CSV export and triggers with pre-trigger samples.
//! * [`devices`]: reconnection with back-off; a disconnected device's axes are faulted
//!   and stopped meanwhile, nothing else stops.
//! * [`alarm`]: the [`alarm::AlarmSink`] seam the station's alarm store plugs into.

#![forbid(unsafe_code)]

pub mod alarm;
pub mod config;
pub mod devices;
pub mod scheduler;
pub mod trace;
