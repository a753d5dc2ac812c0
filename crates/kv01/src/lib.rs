//! # motus-kv01 — the KV-01 arm driver
//!
//! * [`Kv01Bus`]: KV-01 transactions on the serial bus master; "TO" and "UC" are typed
//!   errors, reply CRCs strict by default.
//! * [`Kv01Arm`]: one control thread keeps all six modules alive (one message each per
//!   cycle, far inside the 700 ms safety time-out), moves joints with a host-side position
//!   loop using D2 (speed command and position in one round trip), enforces the safe
//!   order (EN before brake release; brake before DI), the soft limits, and synchronised
//!   multi-joint moves.
//! * [`JointSpec`]: the spec's offset and limit table, gear and sign per joint.
//!
//! Time is an input: the control cycle, the arm's waits, the ages of readings, the latched
//! safety time-outs and recovery's progress watch all run on a [`motus_clock::Clock`] (the
//! bus master's, or the one given to [`Kv01Arm::start_with_clock`]), so tests run the
//! driver and the simulated arm (`motus_kv01_sim::SimLine::sim_link`) in one process on a
//! threaded virtual clock.

#![forbid(unsafe_code)]

mod arm;
mod axis;
mod bus;
mod controller;
mod joints;
mod recover;

pub use arm::{ArmConfig, ArmError, JointState, Kv01Arm, LatchedTimeout};
pub use axis::Kv01JointAxis;
pub use bus::{Kv01Bus, Kv01Error};
pub use joints::{normalise_deg, JointSpec, SPEC_OFFSETS_DEG, SPEC_SOFT_LIMITS_DEG};
pub use recover::{RECOVERY_RPM, WRONG_WAY_TOLERANCE_DEG};
