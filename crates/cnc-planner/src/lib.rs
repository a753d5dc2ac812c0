//! CNC path planner and executor (sans-IO, deterministic, time passed in).
//!
//! The decoder (G-code interpreter) pushes [`PathItem`]s into the block buffer of an
//! [`Executor`]; the [`Planner`] inside it splits arcs into chords within the chord
//! tolerance, rounds every corner with a circular blend within the path tolerance, projects
//! the per-axis velocity and acceleration limits onto each piece and runs the look-ahead
//! backward pass. [`Executor::tick`] returns one [`Setpoint`] per cycle: positions and
//! velocities for every axis, the program line and the state. Feed hold, stop, feed override
//! (0-200 %), single block, synchronous M-functions (waiting for [`Executor::acknowledge`]),
//! dwell, decoder synchronisation, backward motion in the buffer and the release / recouple
//! of the virtual axes ([`Coupling`]) are commands on the executor. [`AxisSink`] streams
//! the set-points to real axes of the axis model.
//!
//! Units: CNC units (mm, degrees) and seconds throughout. `N` is the number of axes (X, Y, Z
//! first; arcs need `N >= 3`). No jerk limit: acceleration is piecewise constant.

#![forbid(unsafe_code)]

mod arc;
pub mod config;
pub mod coupling;
pub mod error;
pub mod executor;
pub mod item;
pub mod piece;
pub mod planner;
mod ramp;
pub mod sink;
mod vector;

pub use config::{AxisLimits, Config};
pub use coupling::{Coupling, CouplingState, Recouple};
pub use error::{CommandError, ConfigError, PushError};
pub use executor::{Event, ExecState, Executor, Setpoint};
pub use item::{ArcDirection, ExArray, PathItem, PathMode, Plane, Segment};
pub use piece::{Geometry, Marker, Piece};
pub use planner::{Planner, MAX_OVERRIDE};
pub use sink::{AxisSink, SinkError, METRES_PER_MM, RADIANS_PER_DEGREE};
