//! What the executor reports: its state, events for the technology, and set-points.

use crate::coupling::CouplingState;
use crate::item::ExArray;
use crate::piece::Marker;

/// What the executor is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExecState {
    /// Nothing to execute (at rest at the end of the buffer).
    Idle,
    /// Moving along the path.
    Running,
    /// Feed hold requested, decelerating.
    Holding,
    /// Feed hold: at rest on the path.
    Held,
    /// Stop requested: decelerating, then the buffer is flushed.
    Stopping,
    /// At a synchronous M-function, waiting for its acknowledgement.
    WaitingAck(u16),
    /// Dwelling.
    Dwelling,
    /// Single-block mode: at rest at the end of a block, waiting for cycle start.
    BlockStop,
    /// Moving backwards along the executed path.
    Reversing,
    /// Real axes re-approaching the virtual position.
    Recoupling,
}

impl ExecState {
    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            ExecState::Idle => "idle",
            ExecState::Running => "running",
            ExecState::Holding => "holding",
            ExecState::Held => "held",
            ExecState::Stopping => "stopping",
            ExecState::WaitingAck(_) => "waiting_ack",
            ExecState::Dwelling => "dwelling",
            ExecState::BlockStop => "block_stop",
            ExecState::Reversing => "reversing",
            ExecState::Recoupling => "recoupling",
        }
    }
}

/// Something the technology (PLC) should know about.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Event {
    /// The path reached an M-function (a synchronous one waits for `acknowledge`).
    MFunction {
        /// M number.
        number: u16,
        /// Synchronous.
        sync: bool,
        /// Program line.
        line: u32,
    },
    /// The path reached an external parameter write.
    ExternalParameter {
        /// Array.
        array: ExArray,
        /// Index.
        index: u8,
        /// Value.
        value: f64,
        /// Program line.
        line: u32,
    },
    /// The path reached a decoder synchronisation point: the decoder may continue.
    DecoderSyncReached {
        /// Program line.
        line: u32,
    },
    /// Single-block stop at the end of a block.
    BlockStop {
        /// Line of the block just finished.
        line: u32,
    },
    /// A marker was passed while moving backwards (after the motion, as in the source).
    Reversed {
        /// The marker.
        marker: Marker,
        /// Program line.
        line: u32,
    },
    /// Feed hold completed: at rest.
    Held,
    /// Stop completed: at rest, buffer flushed.
    Stopped,
}

/// One cycle's output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Setpoint<const N: usize> {
    /// Real axis positions to send to the drives.
    pub positions: [f64; N],
    /// Real axis velocities (feed-forward).
    pub velocities: [f64; N],
    /// Virtual (path) axis positions.
    pub path_positions: [f64; N],
    /// Path speed (units/s, >= 0; the direction is backwards while reversing).
    pub path_speed: f64,
    /// Program line being executed.
    pub line: u32,
    /// Block sequence number being executed.
    pub block: u64,
    /// Executor state after this cycle.
    pub state: ExecState,
    /// Coupling state after this cycle.
    pub coupling: CouplingState,
    /// Time since creation (sum of `dt`).
    pub time: f64,
}
