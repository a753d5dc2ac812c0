//! # motus-axis — one interface for every axis
//!
//! Every device driver in Motus (PS1A, KV-01 joints, 1209A, CiA 402 drives, POWERLINK
//! drives) presents its axes through the [`Axis`] trait, so motion planning, the safety
//! supervisor, the station and the CLI never need to know which protocol moves the motor.
//!
//! * Raw device units stay on the wire and in the driver; the axis interface speaks SI
//!   (metres or radians, seconds), converted by a [`Scale`] from configuration.
//! * [`AxisState`] is a snapshot: position, velocity, optional current and following
//!   error, and [`AxisFlags`] (enabled, homed, moving, target reached, limit switches,
//!   brake) plus an optional [`Fault`] with the device's reason.
//! * [`AxisCommand`] lists what a host can ask; [`Capabilities`] says which of those a
//!   device supports. A refused command returns an [`AxisError`] that says why.

#![forbid(unsafe_code)]

mod command;
mod error;
pub mod profile;
mod state;
mod units;
mod wait;

pub use command::{AxisCommand, Capabilities, Direction, MotionProfile};
pub use error::{AxisError, Blame};
pub use state::{AxisFlags, AxisState, Fault, FaultKind};
pub use units::{Scale, ScaleError, UnitKind};
pub use wait::{wait_until, WaitOutcome};

/// A controllable axis, whatever the device and protocol behind it.
///
/// Methods take `&mut self`: a driver owns its share of the bus and serialises access
/// itself. All positions, velocities and accelerations are SI (see [`Scale`]).
pub trait Axis: Send {
    /// A short human-readable name, e.g. `ps1a:/dev/ttyUSB0#3`.
    fn name(&self) -> &str;

    /// What this device can do.
    fn capabilities(&self) -> Capabilities;

    /// The conversion between the device's raw units and SI units.
    fn scale(&self) -> &Scale;

    /// Reads a fresh state snapshot from the device.
    fn read_state(&mut self) -> Result<AxisState, AxisError>;

    /// Executes one command. Returns once the device accepted it (motion then runs on;
    /// poll [`Axis::read_state`] or use [`wait_until`] to wait for the end).
    fn execute(&mut self, command: &AxisCommand) -> Result<(), AxisError>;
}
