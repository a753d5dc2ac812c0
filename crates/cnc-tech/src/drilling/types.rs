//! Cmd, Para, Info, inputs, outputs, states and errors of the drilling task.

use std::fmt;

use crate::machine::MachineFeedback;
use crate::plc_interface::{ExternalParameters, MFunctions};
use crate::setpoint::{Coupling, ZCommand};
use crate::spindle::SpindleInfo;
use crate::task::CmdFlag;

/// M60: drill one hole.
pub const M_DRILL: u16 = 60;
/// M61: spindle on.
pub const M_SPINDLE_ON: u16 = 61;
/// M62: spindle off.
pub const M_SPINDLE_OFF: u16 = 62;
/// M63: activate the drilling technology.
pub const M_ACTIVATE_DRILLING: u16 = 63;
/// M64: activate the cutting technology.
pub const M_ACTIVATE_CUTTING: u16 = 64;

/// Index of the spindle speed in the W array (EXW60, rpm).
pub(crate) const EXW_SPINDLE_RPM: usize = 60;
/// Index of the drilling speed in the F array (EXF61, mm/min).
pub(crate) const EXF_DRILLING_SPEED: usize = 61;
/// Index of the drilling depth in the F array (EXF62, mm).
pub(crate) const EXF_DRILLING_DEPTH: usize = 62;
/// Index of the peck increment in the F array (EXF63, mm; 0: one pass). A Motus extension
/// of the seed's interface, for G73/G83 (see docs/decisions.md).
pub(crate) const EXF_PECK_INCREMENT: usize = 63;
/// Index of the chip-breaking switch in the B array (EXB64: 1 = a short retract in the
/// hole between pecks, as G73; 0 = out of the hole, as G83).
pub(crate) const EXB_CHIP_BREAK: usize = 64;

/// A set of the technology's M-functions (M60..=M64).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MSet(u8);

impl MSet {
    /// No M-function.
    pub const EMPTY: Self = Self(0);

    fn bit(n: u16) -> Option<u8> {
        (M_DRILL..=M_ACTIVATE_CUTTING).contains(&n).then(|| 1u8 << (n - M_DRILL))
    }

    /// Adds `n`; false (and no change) if `n` is not one of M60..=M64.
    pub fn insert(&mut self, n: u16) -> bool {
        match Self::bit(n) {
            Some(b) => {
                self.0 |= b;
                true
            }
            None => false,
        }
    }

    /// Removes `n`.
    pub fn remove(&mut self, n: u16) {
        if let Some(b) = Self::bit(n) {
            self.0 &= !b;
        }
    }

    /// Whether `n` is in the set.
    pub fn contains(&self, n: u16) -> bool {
        Self::bit(n).is_some_and(|b| self.0 & b != 0)
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.0 == 0
    }

    /// The numbers in the set, ascending.
    pub fn iter(&self) -> impl Iterator<Item = u16> + '_ {
        (M_DRILL..=M_ACTIVATE_CUTTING).filter(|&n| self.contains(n))
    }

    /// The technology's bits that are set in the M-function array.
    pub fn from_mfunctions(m: &MFunctions) -> Self {
        let mut s = Self::EMPTY;
        for n in M_DRILL..=M_ACTIVATE_CUTTING {
            if m.is_set(n) {
                s.insert(n);
            }
        }
        s
    }
}

/// Drill or mill (the source's `ucModeVrtFrez`; the sequence is the same here).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Mode {
    /// Drilling.
    #[default]
    Drill,
    /// Milling / engraving.
    Mill,
}

/// Which technology owns the machine (M63 / M64).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Technology {
    /// Cutting (plasma / oxy-fuel); drilling is locked out.
    #[default]
    Cutting,
    /// Drilling / milling; X/Y shifted by the tool offset.
    Drilling,
}

/// Parameters of the drilling technology (the source's `tk_VRT_FREZ_param_type`, Tab.
/// 8.2, plus the machine data the sequence needs). Units: mm, mm/min, rpm, s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DrillingPara {
    /// Simulation: X/Y move (M63/M64 shift), everything else is only simulated
    /// (`ucSimulace`).
    pub simulation: bool,
    /// Largest change of the working height accepted without re-measuring, mm
    /// (`fTolerZmenyPracPolohy`).
    pub height_tolerance: f64,
    /// Drill or mill (`ucModeVrtFrez`).
    pub mode: Mode,
    /// Height of the tool tip above the material before drilling, mm (`fNajezdNastrojNadPP`).
    pub tool_approach_height: f64,
    /// Height of the pressure plate above the material after the fast approach, mm
    /// (`NajezdDeskaNadPp`).
    pub plate_approach_height: f64,
    /// Speed of the working-height search, mm/min (`fHledaniPracPozice_v`).
    pub search_speed: f64,
    /// Speed of the tool approach, mm/min (`fPriblizeniNastrojPP_v`).
    pub tool_approach_speed: f64,
    /// Length of the tool, mm (`fDelkaNastroje`); the drilling depth must be shorter.
    pub tool_length: f64,
    /// Height of the tool tip above the material when the reference switch closes, mm
    /// (`fVyskaHrotuNastroje`).
    pub tool_tip_height: f64,
    /// Drilling depth for `start_drilling`, mm (`fHloubkaVrtani`); EXF62 for M60.
    pub drilling_depth: f64,
    /// Spindle speed for `start_drilling`, rpm (`iOtackyVretene`); EXW60 for M60/M61.
    pub spindle_rpm: i32,
    /// Drilling speed for `start_drilling`, mm/min (`fRychlostVrtani`); EXF61 for M60.
    pub drilling_speed: f64,
    /// Start position, mm below the upper limit switch (`fVychoziPozice`).
    pub start_position: f64,
    /// Speed of retracting from the hole, mm/min (`fVyjizdeniZDiryVen_v`).
    pub retract_speed: f64,
    /// Travel from the first contact of the plate to the switch, mm (`fRefZasunuti`).
    pub reference_travel: f64,
    /// Z of the upper limit switch, mm (axis data).
    pub upper_limit: f64,
    /// Lowest Z the search may go to, mm (axis data).
    pub lower_limit: f64,
    /// Fast Z speed (plate approach, lift, return), mm/min.
    pub rapid_speed: f64,
    /// Longest search for the switch before giving up, mm (the search also stops at
    /// `lower_limit`).
    pub max_search_travel: f64,
    /// Time allowed for the spindle to reach its speed or stop, s.
    pub spindle_timeout: f64,
    /// Margin added to the expected duration of every move before it times out, s.
    pub move_timeout_margin: f64,
    /// Position of the drill relative to the cutting tool (X, Y), mm; M63 shifts the
    /// real axes by minus this, so the drill is where the program says.
    pub drill_offset: [f64; 2],
    /// Speed of the X/Y shift of M63/M64, mm/min.
    pub shift_speed: f64,
    /// Hole sequence: after a hole stay with the plate above the material (else return
    /// to the start position).
    pub hole_sequence: bool,
    /// Spindle turns in reverse.
    pub spindle_reverse: bool,
}

impl Default for DrillingPara {
    fn default() -> Self {
        Self {
            simulation: false,
            height_tolerance: 1.0,
            mode: Mode::Drill,
            tool_approach_height: 2.0,
            plate_approach_height: 10.0,
            search_speed: 1200.0,
            tool_approach_speed: 300.0,
            tool_length: 80.0,
            tool_tip_height: 5.0,
            drilling_depth: 10.0,
            spindle_rpm: 3000,
            drilling_speed: 100.0,
            start_position: 20.0,
            retract_speed: 1000.0,
            reference_travel: 3.0,
            upper_limit: 400.0,
            lower_limit: 0.0,
            rapid_speed: 3000.0,
            max_search_travel: 400.0,
            spindle_timeout: 5.0,
            move_timeout_margin: 5.0,
            drill_offset: [120.0, -45.0],
            shift_speed: 3000.0,
            hole_sequence: true,
            spindle_reverse: false,
        }
    }
}

/// Commands (the source's `tk_VRT_FREZ_cmd_type`, Tab. 8.3). Set by a higher task or the
/// HMI, reset by the task when it takes them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DrillingCmd {
    /// Find the working height (material surface) (`bZjistPracPolohu`).
    pub find_working_height: CmdFlag,
    /// Drill one hole with the Para values (`bStartVrtani`, same as M60).
    pub start_drilling: CmdFlag,
    /// Stop the technology: spindle off, Z to the start position, abort the pending M;
    /// also leaves the error state (`bStopTechnol`).
    pub stop_technology: CmdFlag,
    /// Lift the spindle to the start position (`bZvedniVreteno`).
    pub lift_spindle: CmdFlag,
    /// Move the plate down until the switch is just closed (`bSjedDeskouNaSpinac`).
    pub plate_to_switch: CmdFlag,
}

/// What the task is doing: one job at a time, from a command or an M-function.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Job {
    /// M60 / `start_drilling`.
    Drill,
    /// M61.
    SpindleOn,
    /// M62.
    SpindleOff,
    /// M63.
    ActivateDrilling,
    /// M64.
    ActivateCutting,
    /// `find_working_height`.
    FindWorkingHeight,
    /// `lift_spindle`.
    LiftSpindle,
    /// `plate_to_switch`.
    PlateToSwitch,
}

impl fmt::Display for Job {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self, f)
    }
}

/// States of the technology's state machine.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum State {
    /// Waiting for a command or an M-function.
    #[default]
    Idle,
    /// Simulation mode: the job is acknowledged without moving Z or the spindle.
    Simulated,
    /// Spindle starting, waiting for "ready" at the set speed.
    SpindleStart,
    /// Spindle stopping, waiting for standstill.
    SpindleStop,
    /// Lifting until the plate's switch opens, then by a clearance.
    SearchLift,
    /// Searching the working height: down at search speed until the switch closes.
    SearchDescend,
    /// Plate to switch: back to the exact Z where the switch closed.
    Settle,
    /// Plate down fast to its approach height above the material.
    PlateApproach,
    /// Tool approach at approach speed, watching the switch.
    ToolApproach,
    /// Clamping the material.
    Clamp,
    /// Drilling at the drilling speed to depth (or to the next peck's depth).
    Drill,
    /// Between pecks: out of the hole (G83) or back a little (chip breaking, G73).
    PeckRetract,
    /// Between pecks: fast back down to just above the depth reached.
    PeckReturn,
    /// Retracting out of the hole.
    Retract,
    /// Releasing the clamp.
    Unclamp,
    /// Up to the plate's approach height (hole sequence, or after a search).
    AboveMaterial,
    /// Fast to the start position below the upper limit switch.
    ReturnToStart,
    /// Releasing the real X/Y from the virtual axes.
    Decouple,
    /// Moving the real X/Y by the tool offset.
    ShiftMove,
    /// Coupling the real X/Y to the virtual axes again.
    Recouple,
    /// Stopping the technology (spindle off, Z to start).
    Stopping,
    /// A job failed; waiting for `stop_technology`.
    Error,
}

impl State {
    /// The state's name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Idle => "Idle",
            Self::Simulated => "Simulated",
            Self::SpindleStart => "SpindleStart",
            Self::SpindleStop => "SpindleStop",
            Self::SearchLift => "SearchLift",
            Self::SearchDescend => "SearchDescend",
            Self::Settle => "Settle",
            Self::PlateApproach => "PlateApproach",
            Self::ToolApproach => "ToolApproach",
            Self::Clamp => "Clamp",
            Self::Drill => "Drill",
            Self::PeckRetract => "PeckRetract",
            Self::PeckReturn => "PeckReturn",
            Self::Retract => "Retract",
            Self::Unclamp => "Unclamp",
            Self::AboveMaterial => "AboveMaterial",
            Self::ReturnToStart => "ReturnToStart",
            Self::Decouple => "Decouple",
            Self::ShiftMove => "ShiftMove",
            Self::Recouple => "Recouple",
            Self::Stopping => "Stopping",
            Self::Error => "Error",
        }
    }
}

impl fmt::Display for State {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Why a job failed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum DrillingError {
    /// A drilling job while the cutting technology is active (M60 without M63).
    #[error("{job} needs the drilling technology active (M63)")]
    TechnologyNotActive {
        /// The job refused.
        job: Job,
    },
    /// A parameter (Para or external parameter) out of its range.
    #[error("invalid {name}: {value}")]
    InvalidParameter {
        /// Which parameter (e.g. "EXF62 drilling depth").
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// The spindle did not report ready in time.
    #[error("spindle not ready at {rpm} rpm within {timeout_s} s")]
    SpindleNotReady {
        /// Set speed.
        rpm: i32,
        /// Time allowed.
        timeout_s: f64,
    },
    /// The spindle did not stop in time.
    #[error("spindle not at standstill within {timeout_s} s")]
    SpindleNotStopped {
        /// Time allowed.
        timeout_s: f64,
    },
    /// The spindle lost its "ready" while the tool was in the material.
    #[error("spindle lost ready in state {state}")]
    SpindleLost {
        /// State at the time.
        state: State,
    },
    /// The plate's switch did not close within the search travel (or down to the lower
    /// limit).
    #[error("reference switch did not close within {travel} mm of search")]
    SwitchNotFound {
        /// Travel searched, mm.
        travel: f64,
    },
    /// The switch stayed closed up to the start position.
    #[error("reference switch still closed at z = {z} mm")]
    SwitchStuck {
        /// Z, mm.
        z: f64,
    },
    /// The Z axis reported its travel limit.
    #[error("Z travel limit at z = {z} mm in state {state}")]
    ZLimit {
        /// Z, mm.
        z: f64,
        /// State at the time.
        state: State,
    },
    /// A Z move took longer than expected.
    #[error("{state} not finished after {after_s} s")]
    MoveTimeout {
        /// State of the move.
        state: State,
        /// Time waited, s.
        after_s: f64,
    },
    /// The X/Y shift or the (de)coupling took longer than expected.
    #[error("X/Y shift not finished after {after_s} s")]
    ShiftTimeout {
        /// Time waited, s.
        after_s: f64,
    },
}

/// The context saved when a job fails.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorRecord {
    /// What went wrong.
    pub error: DrillingError,
    /// State the task was in.
    pub state: State,
    /// Job it was running.
    pub job: Option<Job>,
    /// The M-function that started the job (still set: the program stays paused).
    pub m: Option<u16>,
    /// Z at the time, mm.
    pub z: f64,
    /// Task time, s.
    pub time: f64,
}

/// Spindle speed, feed and depth of one hole.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HoleSettings {
    /// Spindle speed, rpm.
    pub rpm: i32,
    /// Drilling speed, mm/min.
    pub feed: f64,
    /// Depth below the surface, mm.
    pub depth: f64,
    /// Peck increment, mm (0: the whole depth in one pass).
    pub peck: f64,
    /// Between pecks, only a short retract in the hole (chip breaking) instead of out of it.
    pub chip_break: bool,
}

/// Status of the technology (the source's `tk_VRT_FREZ_info_type`, Tab. 8.4, plus the
/// state machine). Written only by the task.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DrillingInfo {
    /// Working-height search running (`bHledaniPPaktivni`).
    pub height_search_active: bool,
    /// Drilling sequence running (`bVrtaniAktivni`).
    pub drilling_active: bool,
    /// Drilling technology active, i.e. after M63 (`bTechnologieAktivni`).
    pub technology_active: bool,
    /// Technology stopping (`ucStopTechnol`).
    pub stopping: bool,
    /// The working height has been found since start (`bNulBodNalezen`).
    pub zero_point_found: bool,
    /// Plate moving onto the switch (`bSjizdiDeskouNaSpinac`).
    pub plate_moving_to_switch: bool,
    /// Current state.
    pub state: State,
    /// Current job.
    pub job: Option<Job>,
    /// The M-function being executed (its bit is set until acknowledged).
    pub pending_m: Option<u16>,
    /// Which technology is active.
    pub technology: Technology,
    /// Z where the plate's switch closes over the material, mm (the zero point).
    pub working_height: Option<f64>,
    /// Settings of the current (or last) hole.
    pub hole: Option<HoleSettings>,
    /// Holes finished.
    pub holes_done: u32,
    /// Times the working height was measured again because it changed beyond the
    /// tolerance.
    pub remeasurements: u32,
    /// The last error (kept after `stop_technology`, for diagnosis).
    pub last_error: Option<ErrorRecord>,
}

/// What the task reads each cycle.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DrillingInputs {
    /// The technology's M bits that are set.
    pub m: MSet,
    /// EXW60, spindle rpm.
    pub ext_spindle_rpm: i16,
    /// EXF61, drilling speed, mm/min.
    pub ext_drilling_speed: f32,
    /// EXF62, drilling depth, mm.
    pub ext_drilling_depth: f32,
    /// EXF63, peck increment, mm (0: one pass).
    pub ext_peck_increment: f32,
    /// EXB64, 1: chip breaking between pecks.
    pub ext_chip_break: i8,
    /// Z of the drilling unit, mm.
    pub z: f64,
    /// Z axis at its travel limit.
    pub z_limit: bool,
    /// Pressure plate reference switch.
    pub plate_switch: bool,
    /// Exact Z where the switch closed during the last cycle (probe latch), if it did.
    pub switch_latch: Option<f64>,
    /// Spindle inverter "ready".
    pub spindle_ready: bool,
    /// Spindle actual speed, rpm.
    pub spindle_rpm: f64,
    /// Real - virtual X/Y, mm.
    pub xy_offset: [f64; 2],
    /// Real X/Y coupled to the virtual axes.
    pub xy_coupled: bool,
}

impl DrillingInputs {
    /// Gathers the inputs from the machine feedback, the spindle's Info, the M-function
    /// array and the external parameters.
    pub fn gather(
        machine: &MachineFeedback,
        spindle: &SpindleInfo,
        m: &MFunctions,
        ext: &ExternalParameters,
    ) -> Self {
        Self {
            m: MSet::from_mfunctions(m),
            ext_spindle_rpm: ext.get_w(EXW_SPINDLE_RPM).unwrap_or(0),
            ext_drilling_speed: ext.get_f(EXF_DRILLING_SPEED).unwrap_or(0.0),
            ext_drilling_depth: ext.get_f(EXF_DRILLING_DEPTH).unwrap_or(0.0),
            ext_peck_increment: ext.get_f(EXF_PECK_INCREMENT).unwrap_or(0.0),
            ext_chip_break: ext.get_b(EXB_CHIP_BREAK).unwrap_or(0),
            z: machine.z,
            z_limit: machine.z_limit,
            plate_switch: machine.plate_switch,
            switch_latch: machine.switch_latch,
            spindle_ready: spindle.ready,
            spindle_rpm: spindle.actual_rpm,
            xy_offset: machine.xy_offset,
            xy_coupled: machine.xy_coupled,
        }
    }
}

/// What the task writes each cycle.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DrillingOutputs {
    /// Z set-point.
    pub z: ZCommand,
    /// Spindle inverter: start (one cycle).
    pub spindle_start: bool,
    /// Spindle inverter: stop (one cycle).
    pub spindle_stop: bool,
    /// Spindle inverter: set speed, rpm.
    pub spindle_rpm: i32,
    /// Spindle inverter: reverse.
    pub spindle_reverse: bool,
    /// Material clamp.
    pub clamp: bool,
    /// X/Y coupling.
    pub coupling: Coupling,
    /// M-functions finished: the caller must clear their bits before the next cycle.
    pub acknowledge: MSet,
    /// M-functions aborted by `stop_technology`: the caller clears their bits and ends
    /// (or restarts) the program.
    pub abort: MSet,
}
