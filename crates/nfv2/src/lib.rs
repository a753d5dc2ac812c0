//! # motus-nfv2 — the 1209A driver, the NFv2 bus scheduler and the pan-tilt head
//!
//! * [`Nfv2Bus`]: NFv2 exchanges on a shared [`motus_serial::BusMaster`] (raw frames for
//!   `motus nfv2 <port> raw '<json>'`), answers found by the codec's
//!   [`motus_nfv2_protocol::FrameScanner`] and accepted only from the addressed slave with
//!   the expected shape ([`AnswerShape`]).
//! * [`Scheduler`]: one packed frame per slave per cycle, the wire budget ([`CyclePlan`])
//!   with a warning when the requested cycle is physically impossible, achieved cycle
//!   statistics ([`CycleStats`]), missed samples counted, never used.
//! * [`Drive`]: one 1209A in device units (modes, set-points, limits, homing, faults with
//!   the device's reasons), and its timestamped position history ([`SampleHistory`]).
//! * [`Nfv2Axis`]: a 1209A as a [`motus_axis::Axis`] in SI units (radians after the gear).
//! * [`PanTilt`]: two 1209A on one bus: homing, synchronised `goto`, tracking a target
//!   stream within velocity and acceleration limits, and `where_at(t)`.
//!
//! # For the CLI
//! * `motus axis nfv2://<port>?addr=N ...`: [`open_axis`] (URI parameters in [`uri`]) gives
//!   an [`Nfv2Axis`] that runs its own scheduler; `Axis::execute` / `read_state` as for
//!   every family.
//! * `motus nfv2 <port> raw '<json>'`: [`Nfv2Bus::open`] (or [`open_bus`]), then
//!   [`Nfv2Bus::transact`] with the codec's JSON `Frame`; `Ok(None)` for a frame without
//!   query.
//! * `motus pantilt <port> home | goto <pan> <tilt> | track <file-or-stdin> | where <t>`:
//!   [`PanTilt::open`], then [`PanTilt::home`], [`PanTilt::goto`] + [`PanTilt::wait_idle`],
//!   [`parse_track`] + [`PanTilt::track`] (or [`PanTilt::track_live`] and
//!   [`TrackFeed::push`] line by line from stdin) + [`PanTilt::wait_idle`], and
//!   [`PanTilt::where_at`]; [`Scheduler::stats`] for the cycle report.
//!
//! Device units: positions in encoder counts (200 000 per axis turn on the head), speeds
//! in NFv2 units of 10 counts/s, accelerations in counts/s², currents in mA.

#![forbid(unsafe_code)]

mod axis;
mod bus;
pub mod drive;
mod error;
mod framing;
pub mod pantilt;
pub mod plan;
pub mod samples;
mod scheduler;
mod stats;
pub mod stream;
pub mod uri;

pub use axis::{AxisConfig, Nfv2Axis, DEFAULT_COUNTS_PER_REV};
pub use bus::Nfv2Bus;
pub use drive::{DeviceLimits, Drive, DriveConfig, DriveSnapshot, IntentKind};
pub use error::Nfv2Error;
pub use framing::AnswerShape;
pub use pantilt::sources::SetpointRecord;
pub use pantilt::targets::{parse_target_line, parse_track, ParseTargetError, TargetPoint};
pub use pantilt::{HeadAxis, PanTilt, PanTiltConfig, PanTiltError, TrackFeed};
pub use plan::{CyclePlan, ExchangeBudget, Packing, SlaveBudget};
pub use samples::{PositionSample, SampleHistory, WhereError};
pub use scheduler::{Scheduler, SchedulerConfig};
pub use stats::{CycleStats, SlaveStats};
pub use stream::{SetpointSource, SharedSource, StreamCommand, COUNTS_PER_S_PER_SPEED_UNIT};
pub use uri::{open_axis, open_bus};
