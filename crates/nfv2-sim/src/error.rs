//! The simulator's error type: bad configuration and misuse of the test hooks (our own
//! misuse). The device itself never refuses anything with an error: NFv2 has no error
//! replies, so a refused or clamped set-point shows only in the status bits.

use thiserror::Error;

/// What went wrong setting up or poking a simulated controller.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum SimError {
    /// The configuration cannot be simulated (the message names the field).
    #[error("invalid controller configuration: {0}")]
    Config(String),
    /// The 1209A has two analog inputs, AI0 and AI1.
    #[error("analog input {0} does not exist (the 1209A has AI0 and AI1)")]
    NoSuchAnalogInput(usize),
    /// A voltage or position given to a test hook is not a finite number.
    #[error("{what} must be a finite number")]
    NotFinite {
        /// The hook's argument.
        what: &'static str,
    },
}
