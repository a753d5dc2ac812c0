//! # motus-ps1a-sim — a simulated PS1A module
//!
//! A faithful model of the PS1A (spec `specs/ps1a.md`): the DDA trajectory generator at
//! the configured cycle, the status bits with their clear-after-report rules, homing to
//! the reference switch and the encoder zero pulse, jog and stop, the maximum-position
//! check, limit switches that switch the power stage off, following-error detection,
//! reset, and parameters persisted like EEPROM. A [`SimLine`] serves up to 16 modules on
//! one link (a pty for tests), each answering only its own address, with optional
//! baud-rate pacing and fault injection.
//!
//! Time is injected: a [`Module`] advances to the `now` it is given, in whole DDA
//! cycles, so tests can step it deterministically.

#![forbid(unsafe_code)]

mod line;
mod machine;
mod module;
mod state_file;
mod state_writer;

pub use line::{LineError, LineOptions, Modules, SimLine};
pub use machine::MachineConfig;
pub use module::Module;
pub use state_file::{ModuleState, StateFile, StateFileError};
