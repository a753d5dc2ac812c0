//! # motus-ps1a — the PS1A driver
//!
//! * [`Ps1aBus`]: PS1A transactions on a [`motus_serial::BusMaster`] (checksum-error
//!   replies are retried, replies must come from the addressed module), [`Ps1aBus::scan`]
//!   and parameter writes.
//! * [`Ps1aAxis`]: one module as an [`motus_axis::Axis`], in SI units, refusing motion
//!   until homed, latching the module's clear-after-report fault bits, and detecting a
//!   module reset (power loss, restart) as a fault that only homing clears.
//! * [`open_axis`]: builds an axis from a URI such as `ps1a:///dev/ttyUSB0?addr=3`.

#![forbid(unsafe_code)]

mod axis;
mod bus;
mod uri;

pub use axis::{AxisConfig, Ps1aAxis};
pub use bus::{Ps1aBus, Ps1aError};
pub use uri::{axis_config, open_axis, open_bus, LinkOptions, URI_PARAMS};
