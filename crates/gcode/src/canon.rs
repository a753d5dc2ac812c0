//! Canonical machining calls, named and ordered like LinuxCNC's canonical interface.
//!
//! Values are what LinuxCNC's standalone `rs274` prints: lengths in the **program units
//! in force** (mm after G21, inch after G20), absolute, in the program coordinate system
//! (G5x / G92 offsets are *not* applied; they arrive as [`Canon::SetG5xOffset`] and
//! [`Canon::SetG92Offset`]). Angles (A, B, C) are degrees. For motion, every
//! [`CanonCall`] also carries a [`MachineMove`] in machine millimetres (units converted,
//! offsets applied) for a planner.

use serde::{Deserialize, Serialize};

/// Length units (`USE_LENGTH_UNITS`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Units {
    /// G21.
    Mm,
    /// G20.
    Inch,
}

impl Units {
    /// Millimetres per unit (1 or 25.4).
    pub fn mm_per_unit(self) -> f64 {
        match self {
            Units::Mm => 1.0,
            Units::Inch => 25.4,
        }
    }
}

/// Active plane (`SELECT_PLANE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Plane {
    /// G17: arcs in X,Y about Z.
    Xy,
    /// G18: arcs in Z,X about Y (LinuxCNC's first/second order is Z then X).
    Xz,
    /// G19: arcs in Y,Z about X.
    Yz,
}

impl Plane {
    /// Indices (0 = X, 1 = Y, 2 = Z) of the arc's first and second coordinate and its axis,
    /// in LinuxCNC's order (G18 is Z, X, axis Y).
    pub fn axes(self) -> (usize, usize, usize) {
        match self {
            Plane::Xy => (0, 1, 2),
            Plane::Xz => (2, 0, 1),
            Plane::Yz => (1, 2, 0),
        }
    }
}

/// Whether an M-function pauses the program until the PLC clears its bit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MSync {
    /// The program waits until the PLC clears the bit.
    Sync,
    /// The program continues; the same M may only be set again once it was cleared.
    Async,
}

/// The four external-parameter arrays (`EXB`, `EXW`, `EXL`, `EXF`, 100 entries each).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ExArray {
    /// int8.
    B,
    /// int16.
    W,
    /// int32.
    L,
    /// float32.
    F,
}

/// A value written to an external parameter, typed like its array.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", content = "value", rename_all = "snake_case")]
pub enum ExValue {
    /// EXB value.
    B(i8),
    /// EXW value.
    W(i16),
    /// EXL value.
    L(i32),
    /// EXF value.
    F(f32),
}

/// Six-axis position X, Y, Z (program length units), A, B, C (degrees).
pub type Pose = [f64; 6];

/// An `ARC_FEED` in LinuxCNC's argument order.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ArcFeed {
    /// End point, first coordinate of the plane (X for G17, Z for G18, Y for G19).
    pub first_end: f64,
    /// End point, second coordinate of the plane.
    pub second_end: f64,
    /// Centre, first coordinate (absolute).
    pub first_centre: f64,
    /// Centre, second coordinate (absolute).
    pub second_centre: f64,
    /// Negative for G2 (clockwise), positive for G3; magnitude = turns (P word).
    pub rotation: i32,
    /// End point along the plane's normal axis (helix).
    pub axis_end: f64,
    /// A end (degrees).
    pub a: f64,
    /// B end (degrees).
    pub b: f64,
    /// C end (degrees).
    pub c: f64,
}

/// One canonical call.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "call", rename_all = "snake_case")]
pub enum Canon {
    /// `USE_LENGTH_UNITS(CANON_UNITS_MM|CANON_UNITS_INCHES)`.
    UseLengthUnits {
        /// The units now in force.
        units: Units,
    },
    /// `SET_G5X_OFFSET(index, x, y, z, a, b, c)`: the active work offset (1 = G54 .. 9 = G59.3), program units.
    SetG5xOffset {
        /// 1..=9.
        index: u8,
        /// Offset per axis.
        offset: Pose,
    },
    /// `SET_G92_OFFSET(x, y, z, a, b, c)`, program units.
    SetG92Offset {
        /// Offset per axis.
        offset: Pose,
    },
    /// `SET_XY_ROTATION(degrees)`: the active coordinate system's rotation about Z
    /// (G10 L2 R); positions in the calls stay unrotated, [`MachineMove`]s are rotated.
    SetXyRotation {
        /// Degrees.
        degrees: f64,
    },
    /// `SET_FEED_REFERENCE(CANON_XYZ)`.
    SetFeedReference,
    /// `SET_FEED_MODE(0, m)`: 0 = per minute (G94) or inverse time (G93, whose rates the
    /// interpreter sends per move), 1 = per spindle revolution (G95).
    SetFeedMode {
        /// G95.
        per_revolution: bool,
    },
    /// `SET_FEED_RATE(f)`, program units per minute.
    SetFeedRate {
        /// Feed rate.
        rate: f64,
    },
    /// `SET_SPINDLE_SPEED(0, s)`, rpm.
    SetSpindleSpeed {
        /// Speed (rpm).
        rpm: f64,
    },
    /// `START_SPINDLE_CLOCKWISE(0)` (M3).
    StartSpindleClockwise,
    /// `START_SPINDLE_COUNTERCLOCKWISE(0)` (M4).
    StartSpindleCounterclockwise,
    /// `STOP_SPINDLE_TURNING(0)` (M5).
    StopSpindleTurning,
    /// `SET_SPINDLE_MODE(0 d)`: 0 = rpm (G97), else constant surface speed (G96) with `d`
    /// the rpm limit.
    SetSpindleMode {
        /// Rpm limit under G96; 0 under G97.
        max_rpm: f64,
    },
    /// `MIST_ON()` (M7).
    MistOn,
    /// `FLOOD_ON()` (M8).
    FloodOn,
    /// `MIST_OFF()` (M9, first call).
    MistOff,
    /// `FLOOD_OFF()` (M9, second call).
    FloodOff,
    /// `SELECT_PLANE(...)`.
    SelectPlane {
        /// The plane.
        plane: Plane,
    },
    /// `COMMENT("...")`.
    Comment {
        /// The text between the parentheses.
        text: String,
    },
    /// `MESSAGE("...")` from `(MSG,...)`.
    Message {
        /// The text after `MSG,`.
        text: String,
    },
    /// `STRAIGHT_TRAVERSE(x, y, z, a, b, c)` (G0).
    StraightTraverse {
        /// End point.
        end: Pose,
    },
    /// `STRAIGHT_FEED(x, y, z, a, b, c)` (G1).
    StraightFeed {
        /// End point.
        end: Pose,
    },
    /// `ARC_FEED(...)` (G2/G3).
    ArcFeed(ArcFeed),
    /// `DWELL(seconds)` (G4).
    Dwell {
        /// Seconds.
        seconds: f64,
    },
    /// `SET_MOTION_CONTROL_MODE(...)`: how the path joins its moves (G61, G61.1, G64 P;
    /// exact path around a canned cycle).
    SetMotionControlMode {
        /// The mode.
        mode: MotionControl,
        /// Path tolerance of [`MotionControl::Continuous`] (G64 P), program units; 0 = none.
        tolerance: f64,
    },
    /// `SET_NAIVECAM_TOLERANCE(q)`: G64 Q, the tolerance within which the planner may join
    /// collinear feeds (CAM output's short segments), program units.
    SetNaivecamTolerance {
        /// Tolerance.
        tolerance: f64,
    },
    /// `SELECT_TOOL(t)`: the T word (the changer may prepare it).
    SelectTool {
        /// Tool number.
        tool: u32,
    },
    /// `START_CHANGE()`: M6 begins.
    StartChange,
    /// `CHANGE_TOOL(p)`: M6, the selected tool into the spindle; `p` is its place in the
    /// tool table (1-based; 0 = no tool).
    ChangeTool {
        /// Place in the table.
        index: usize,
    },
    /// `USE_TOOL_LENGTH_OFFSET(x y z, a b c, u v w)`: G43/G43.1/G49, program units.
    UseToolLengthOffset {
        /// Offset per axis (X Y Z A B C).
        offset: Pose,
    },
    /// `OPTIONAL_PROGRAM_STOP()` (M1).
    OptionalProgramStop,
    /// `PROGRAM_STOP()` (M0).
    ProgramStop,
    /// `PALLET_SHUTTLE()` (M30, before `PROGRAM_END`).
    PalletShuttle,
    /// `PROGRAM_END()` (M2/M30).
    ProgramEnd,
    /// `SET_MOTION_OUTPUT_BIT(n)` / `CLEAR_MOTION_OUTPUT_BIT(n)` (M62/M63: with the next
    /// move's start) or `SET_AUX_OUTPUT_BIT(n)` / `CLEAR_AUX_OUTPUT_BIT(n)` (M64/M65: at
    /// once). LinuxCNC dialect only ([`crate::MCodeDialect::LinuxCnc`]).
    DigitalOutput {
        /// The output (the P word, rounded as LinuxCNC rounds it).
        index: i32,
        /// Set (M62/M64) or cleared (M63/M65).
        on: bool,
        /// Synchronised with motion (M62/M63) rather than immediate (M64/M65).
        with_motion: bool,
    },
    /// `SET_MOTION_OUTPUT_VALUE(n,v)` (M67: with the next move) or
    /// `SET_AUX_OUTPUT_VALUE(n,v)` (M68: at once). LinuxCNC dialect only.
    AnalogOutput {
        /// The output (the E word, rounded; never negative).
        index: i32,
        /// The value (the Q word).
        value: f64,
        /// Synchronised with motion (M67) rather than immediate (M68).
        with_motion: bool,
    },
    /// `WAIT(n, DIGITAL_INPUT|ANALOG_INPUT, mode, timeout)`: M66, the program waits on an
    /// input (LinuxCNC's `WAIT`; its standalone `rs274` prints nothing for it). The value
    /// read is the machine's business: the interpreter leaves #5399 as it is. LinuxCNC
    /// dialect only.
    WaitInput {
        /// The input (P word for a digital one, E word for an analog one).
        index: i32,
        /// Digital (P) or analog (E).
        analog: bool,
        /// The L word: what to wait for.
        mode: WaitMode,
        /// The Q word, seconds (0: none).
        timeout: f64,
    },
    /// `CHANGE_TOOL_NUMBER(p)`: M61 Q, the spindle's tool is declared without a change;
    /// `p` is the tool's place in the table (0 = no tool). LinuxCNC dialect only.
    ChangeToolNumber {
        /// Place in the table.
        index: usize,
    },
    /// `M_FUNCTION(n, SYNC|ASYNC)`: one of the seed's M-functions 0..=1023 (bit n).
    MFunction {
        /// 0..=1023.
        number: u16,
        /// Whether the program waits for the PLC.
        sync: MSync,
    },
    /// `EXTERNAL_PARAMETER(W, 60, 3600)`: `EX<array><index>=value`.
    ExternalParameter {
        /// Which array.
        array: ExArray,
        /// 0..=99.
        index: u8,
        /// The typed value.
        value: ExValue,
    },
}

/// What M66 waits for (its L word, LinuxCNC's `WAIT_MODE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WaitMode {
    /// L0: no wait, the input is read at once.
    Immediate,
    /// L1: a rising edge.
    Rise,
    /// L2: a falling edge.
    Fall,
    /// L3: the input high.
    High,
    /// L4: the input low.
    Low,
}

impl WaitMode {
    /// LinuxCNC's number for the mode (the L word).
    pub fn number(self) -> u8 {
        match self {
            WaitMode::Immediate => 0,
            WaitMode::Rise => 1,
            WaitMode::Fall => 2,
            WaitMode::High => 3,
            WaitMode::Low => 4,
        }
    }
}

/// How the path joins its moves (LinuxCNC's `CANON_MOTION_MODE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum MotionControl {
    /// G61.1: stop at the end of every move.
    ExactStop,
    /// G61: follow the programmed path exactly (corners are corners).
    ExactPath,
    /// G64: blend corners, within a path tolerance when one is given.
    Continuous,
}

/// A motion in machine coordinates: millimetres (A/B/C degrees), G5x and G92 offsets applied.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum MachineMove {
    /// Rapid move (G0).
    Traverse {
        /// Start (machine mm).
        start: Pose,
        /// End (machine mm).
        end: Pose,
    },
    /// Straight feed move (G1).
    Feed {
        /// Start (machine mm).
        start: Pose,
        /// End (machine mm).
        end: Pose,
        /// Feed rate in mm/min.
        feed: f64,
    },
    /// Arc / helix (G2/G3).
    Arc {
        /// Start (machine mm).
        start: Pose,
        /// End (machine mm).
        end: Pose,
        /// Centre X, Y, Z (machine mm); the component along the plane's axis is the start's.
        centre: [f64; 3],
        /// Plane of the arc.
        plane: Plane,
        /// Negative = clockwise (G2) seen from the positive normal axis, magnitude = turns.
        rotation: i32,
        /// Feed rate in mm/min.
        feed: f64,
    },
}

/// A canonical call with where it came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CanonCall {
    /// 1-based source line (0 for the set-up calls emitted before the first line).
    pub line: u32,
    /// The block's N number, if any.
    pub n: Option<u32>,
    /// The call.
    pub canon: Canon,
    /// For motion calls: the same motion in machine millimetres.
    pub machine: Option<MachineMove>,
}
