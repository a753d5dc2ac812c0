//! Typed errors.

use thiserror::Error;

/// A configuration value is unusable.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ConfigError {
    /// `N` is zero.
    #[error("a CNC system needs at least one axis")]
    NoAxes,
    /// Axis velocity limit not finite and positive.
    #[error("axis {axis}: velocity limit {value} must be finite and > 0")]
    Velocity {
        /// Axis index.
        axis: usize,
        /// Value given.
        value: f64,
    },
    /// Axis acceleration limit not finite and positive.
    #[error("axis {axis}: acceleration limit {value} must be finite and > 0")]
    Acceleration {
        /// Axis index.
        axis: usize,
        /// Value given.
        value: f64,
    },
    /// Path tolerance negative or not finite.
    #[error("path tolerance {0} must be finite and >= 0")]
    PathTolerance(f64),
    /// Chord tolerance not finite and positive.
    #[error("chord tolerance {0} must be finite and > 0")]
    ChordTolerance(f64),
    /// Centripetal share outside 0.05..=0.95.
    #[error("blend centripetal share {0} must be within 0.05..=0.95")]
    CentripetalShare(f64),
    /// Buffer capacity too small.
    #[error("buffer capacity {0} must be at least 4 pieces")]
    BufferCapacity(usize),
}

/// An item was refused by the block buffer (the caller's misuse or a full buffer).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PushError {
    /// The buffer holds `capacity` pieces ahead of the executor; push again later.
    #[error("block buffer full ({capacity} pieces ahead)")]
    Full {
        /// Configured capacity.
        capacity: usize,
    },
    /// A decoder synchronisation point has not been reached by the path yet.
    #[error("decoder synchronisation pending (line {line}): wait until the path reaches it")]
    AwaitingDecoderSync {
        /// Line of the synchronisation item.
        line: u32,
    },
    /// A coordinate is NaN or infinite.
    #[error("line {line}: coordinate of axis {axis} is not finite")]
    NonFinite {
        /// Program line.
        line: u32,
        /// Axis index.
        axis: usize,
    },
    /// Feed rate not finite and positive.
    #[error("line {line}: feed rate {feed} must be finite and > 0")]
    Feed {
        /// Program line.
        line: u32,
        /// Value given.
        feed: f64,
    },
    /// Arc with less than three axes, a zero radius, or start and end radii too different.
    #[error("line {line}: bad arc: {reason}")]
    Arc {
        /// Program line.
        line: u32,
        /// What is wrong.
        reason: &'static str,
    },
    /// Dwell time negative or not finite.
    #[error("line {line}: dwell {seconds} s must be finite and >= 0")]
    Dwell {
        /// Program line.
        line: u32,
        /// Value given.
        seconds: f64,
    },
    /// A path tolerance (G64 P or Q) negative or not finite.
    #[error("line {line}: path tolerance {tolerance} must be finite and >= 0")]
    Tolerance {
        /// Program line.
        line: u32,
        /// Value given.
        tolerance: f64,
    },
    /// The executor is stopping; push after it is idle.
    #[error("executor is stopping; the buffer is being flushed")]
    Stopping,
}

/// A command was refused in the executor's present state.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CommandError {
    /// The command needs the path to be at rest (held, idle, waiting).
    #[error("{command} needs the path at rest (state {state})")]
    NotAtRest {
        /// Command name.
        command: &'static str,
        /// State at the time.
        state: &'static str,
    },
    /// The virtual axes are not coupled to the real ones.
    #[error("{command} needs the axes coupled (coupling is {coupling})")]
    NotCoupled {
        /// Command name.
        command: &'static str,
        /// Coupling state at the time.
        coupling: &'static str,
    },
    /// The coupling is not released.
    #[error("{command} needs the coupling released")]
    NotReleased {
        /// Command name.
        command: &'static str,
    },
    /// Axis index out of range.
    #[error("axis {0} does not exist")]
    Axis(usize),
    /// Value not finite or out of range.
    #[error("{what} {value} out of range")]
    Value {
        /// Which value.
        what: &'static str,
        /// Value given.
        value: f64,
    },
}
