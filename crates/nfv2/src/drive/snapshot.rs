//! What the host knows of a drive at one instant: the trusted readings, the intent, and
//! the flags and faults derived from them.

use std::time::Instant;

use motus_axis::Fault;
use motus_nfv2_protocol::DriveStatus;

use crate::samples::PositionSample;

/// What the host is making the drive do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IntentKind {
    /// Nothing commanded since the scheduler started (only queries are sent).
    Unknown,
    /// Switched off (mode ERROR) on request.
    Disabled,
    /// POSITION mode: moving to or holding a target.
    Position,
    /// SPEED mode.
    Jog,
    /// HOMING.
    Homing,
    /// Following a host trajectory.
    Stream,
    /// Stopped by a fault until a fault reset.
    Faulted,
}

/// The latest trusted state of a drive.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveSnapshot {
    /// Bus address.
    pub address: u8,
    /// Newest accepted position sample.
    pub position: Option<PositionSample>,
    /// Speed over the last two samples, counts/s.
    pub velocity: Option<f64>,
    /// Status word (fault-relevant bits debounced over two answers).
    pub status: Option<DriveStatus>,
    /// Status word as last read.
    pub raw_status: Option<DriveStatus>,
    /// Motor current, mA (read every few cycles).
    pub current_ma: Option<i64>,
    /// Digital inputs (bit 0 LIM_POS, 1 LIM_NEG, 2 HOME, 3 ENABLE).
    pub inputs: Option<u8>,
    /// What the host is making the drive do.
    pub intent: IntentKind,
    /// POSITION target, counts, as the drive clamps it to its position limits.
    pub target: Option<i64>,
    /// The drive is in a mode other than ERROR and no fault is latched.
    pub enabled: bool,
    /// Status bit 4 "synchronized".
    pub homed: bool,
    /// A move, jog, homing or stream runs, or the axis is not at rest.
    pub moving: bool,
    /// The POSITION target is reached and the axis is at rest.
    pub target_reached: bool,
    /// LIM_POS closed (status bit 0).
    pub limit_up: bool,
    /// LIM_NEG closed (status bit 1).
    pub limit_down: bool,
    /// Active faults: latched by the host (ERROR entered by the drive) and level faults.
    pub faults: Vec<Fault>,
    /// Every set-point sent was acknowledged by an answer.
    pub settled: bool,
    /// When the last valid answer arrived.
    pub last_answer: Option<Instant>,
}

/// A snapshot without any reading (an unknown drive).
pub(crate) fn empty(address: u8) -> DriveSnapshot {
    DriveSnapshot {
        address,
        position: None,
        velocity: None,
        status: None,
        raw_status: None,
        current_ma: None,
        inputs: None,
        intent: IntentKind::Unknown,
        target: None,
        enabled: false,
        homed: false,
        moving: false,
        target_reached: false,
        limit_up: false,
        limit_down: false,
        faults: Vec::new(),
        settled: false,
        last_answer: None,
    }
}
