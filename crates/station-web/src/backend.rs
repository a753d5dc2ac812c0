//! [`MachineBackend`]: what the web layer needs from the machine, and the validated command
//! types shared with the CLI ([`AxisAction`], [`GroupAction`]).
//!
//! The station implements this trait over its real devices (`motus-station-machine`); the
//! API tests run against that machine on a simulated cell. The web layer
//! authorises every call (lab's `authorize`) before it reaches the backend; the backend
//! still validates every number it receives (finite, within the axis limits).

use motus_lab::Role;
use serde::{Deserialize, Serialize};

/// Who asks (already authenticated and authorised by the web layer).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Caller {
    /// User name (`console` for the local CLI).
    pub user: String,
    /// Role at the time of the request.
    pub role: Role,
}

impl Caller {
    /// A caller.
    #[must_use]
    pub fn new(user: &str, role: Role) -> Self {
        Caller { user: user.to_string(), role }
    }
}

/// Position and motion limits of one axis, in its SI unit (m or rad, per second...).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AxisLimits {
    /// Lowest allowed position.
    pub min: f64,
    /// Highest allowed position.
    pub max: f64,
    /// Highest speed (> 0).
    pub max_speed: f64,
    /// Highest acceleration (> 0).
    pub max_acceleration: f64,
}

/// The state of one axis as the HMI shows it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisView {
    /// Stable id used in URLs (`/api/axes/{id}/move`).
    pub id: String,
    /// Name for people.
    pub name: String,
    /// Device it belongs to (`ps1a@/dev/ttyUSB0:1`, `sim`...).
    pub device: String,
    /// Group it belongs to (`gantry`, `robot`, `pan_tilt`, `arm`...), if any.
    pub group: Option<String>,
    /// Unit of positions (`m`, `rad`).
    pub unit: String,
    /// Actual position.
    pub position: f64,
    /// Actual velocity.
    pub velocity: f64,
    /// Power stage on.
    pub enabled: bool,
    /// Homed (position reference valid).
    pub homed: bool,
    /// A motion is in progress.
    pub moving: bool,
    /// Fault text, if the axis is faulted.
    pub fault: Option<String>,
    /// Limits.
    pub limits: AxisLimits,
    /// Acceleration used by moves and jogs that do not state one.
    pub acceleration: f64,
    /// Speed used by group moves (robot go-to, pan-tilt target, arm joints).
    pub default_speed: f64,
}

/// One command to one axis. Numbers are in the axis's SI unit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "action", rename_all = "snake_case")]
pub enum AxisAction {
    /// Jog in `direction` (the sign: +1 or -1) at `speed` (> 0). A jog is a dead-man
    /// command: the machine stops it unless it is repeated within half a second.
    Jog {
        /// +1 or -1.
        direction: f64,
        /// Speed (> 0).
        speed: f64,
        /// Acceleration (default: the axis's).
        #[serde(default)]
        acceleration: Option<f64>,
    },
    /// Absolute move to `target` at `speed`.
    Move {
        /// Target position.
        target: f64,
        /// Speed (> 0).
        speed: f64,
        /// Acceleration (default: the axis's).
        #[serde(default)]
        acceleration: Option<f64>,
    },
    /// Homing.
    Home,
    /// Controlled stop.
    Stop,
}

impl AxisAction {
    /// Checks the numbers against `axis` (finite, positive speed within the axis's maximum,
    /// target within the position limits, direction +-1). Backends call it first.
    ///
    /// # Errors
    /// [`BackendError::Invalid`] naming the field.
    pub fn validate(&self, axis: &AxisView) -> Result<(), BackendError> {
        let lim = &axis.limits;
        let check_speed = |speed: f64, acc: Option<f64>| -> Result<(), BackendError> {
            if !speed.is_finite() || speed <= 0.0 || speed > lim.max_speed {
                return Err(BackendError::invalid(
                    "speed",
                    format!("{speed} is not in (0, {}] {}/s", lim.max_speed, axis.unit),
                ));
            }
            if let Some(a) = acc {
                if !a.is_finite() || a <= 0.0 || a > lim.max_acceleration {
                    return Err(BackendError::invalid(
                        "acceleration",
                        format!("{a} is not in (0, {}] {}/s^2", lim.max_acceleration, axis.unit),
                    ));
                }
            }
            Ok(())
        };
        match *self {
            AxisAction::Jog { direction, speed, acceleration } => {
                if direction != 1.0 && direction != -1.0 {
                    return Err(BackendError::invalid("direction", format!("{direction} is not +1 or -1")));
                }
                check_speed(speed, acceleration)
            }
            AxisAction::Move { target, speed, acceleration } => {
                if !target.is_finite() || target < lim.min || target > lim.max {
                    return Err(BackendError::invalid(
                        "target",
                        format!("{target} is outside [{}, {}] {}", lim.min, lim.max, axis.unit),
                    ));
                }
                check_speed(speed, acceleration)
            }
            AxisAction::Home | AxisAction::Stop => Ok(()),
        }
    }

    /// The peak speed and acceleration this action asks of `axis` (for the student limits),
    /// `None` for home and stop.
    #[must_use]
    pub fn demand(&self, axis: &AxisView) -> Option<motus_lab::MotionDemand> {
        match *self {
            AxisAction::Jog { speed, acceleration, .. } => {
                Some(motus_lab::MotionDemand::new(speed, acceleration.unwrap_or(axis.acceleration)))
            }
            AxisAction::Move { target, speed, acceleration } => Some(motus_lab::MotionDemand::within(
                speed,
                acceleration.unwrap_or(axis.acceleration),
                target,
                target,
            )),
            AxisAction::Home | AxisAction::Stop => None,
        }
    }

    /// The lab operation for authorisation and audit.
    #[must_use]
    pub fn op(&self) -> motus_lab::AxisOp {
        match self {
            AxisAction::Jog { .. } => motus_lab::AxisOp::Jog,
            AxisAction::Move { .. } => motus_lab::AxisOp::Move,
            AxisAction::Home => motus_lab::AxisOp::Home,
            AxisAction::Stop => motus_lab::AxisOp::Stop,
        }
    }
}

/// Configuration of the station's axis parameters an admin may change.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AxisParameters {
    /// New limits.
    pub limits: AxisLimits,
    /// Default acceleration.
    pub acceleration: f64,
}

/// A command to a group of axes (robot go-to, pan-tilt target, arm joints, gantry point).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "action", rename_all = "snake_case")]
pub enum GroupAction {
    /// Move every member axis (in [`GroupView::axes`] order) to its target together:
    /// robot `[x, y, theta]`, pan-tilt `[pan, tilt]`, arm `[j1, j2, ...]`.
    GoTo {
        /// One target per member axis.
        targets: Vec<f64>,
    },
    /// Stop every member axis.
    Stop,
    /// Load one of [`GroupView::programs`] onto the group's controller and run it (the
    /// juggler's patterns); the supervisor guards it like any motion.
    Run {
        /// The program's name.
        program: String,
    },
}

/// What a group is for (the HMI panel that commands it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GroupKind {
    /// Omnidirectional robot: `[x, y, theta]`.
    Robot,
    /// Pan-tilt head: `[pan, tilt]`.
    PanTilt,
    /// Arm joints.
    Arm,
    /// Gantry `[x, y, z]`.
    Gantry,
    /// Juggler axes.
    Juggler,
    /// Axes booked and shown together, without a controller of their own.
    Axes,
}

/// A group of axes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GroupView {
    /// Id used in URLs (`/api/groups/{id}`).
    pub id: String,
    /// Kind.
    pub kind: GroupKind,
    /// Member axis ids, in the order of [`GroupAction::GoTo`] targets.
    pub axes: Vec<String>,
    /// Programs [`GroupAction::Run`] can load onto the group's controller (empty: none).
    #[serde(default)]
    pub programs: Vec<String>,
    /// The program the group's controller runs, when it has one.
    #[serde(default)]
    pub program: Option<String>,
    /// The group has a camera (`GET /api/groups/{id}/camera.mjpg`).
    #[serde(default)]
    pub camera: bool,
}

/// Where a machine's pictures come from ([`MachineBackend::camera`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CameraFeed {
    /// Drawn by the station from the group's axes as they are.
    Simulated,
    /// An HTTP camera (MJPEG stream or JPEG image) the station fetches for each viewer.
    Http(String),
}

/// One rule's predicted reach, per axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PredictedReach {
    /// Axis id.
    pub axis: String,
    /// Where the axis would stop if stopped now.
    pub stop_position: f64,
    /// Distance left to the nearest rule limit (negative: violated).
    pub distance: f64,
}

/// The supervisor's state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SafetyView {
    /// SafeToRun as computed by the supervisor (no API can set it).
    pub safe_to_run: bool,
    /// Motion is held (latched after a trip or an E-stop) until a reset.
    pub held: bool,
    /// E-stop pressed and not reset.
    pub estop: bool,
    /// The first failing rule and why, when not safe or held.
    pub diagnosis: Option<String>,
    /// Name of the rule set in force.
    pub rules_name: String,
    /// SHA-256 (or other) fingerprint of the rule set.
    pub rules_fingerprint: String,
    /// Predicted stop positions and distances to the limits.
    pub predicted: Vec<PredictedReach>,
    /// Integrity checks of the approved configuration applied by the supervisor so far (0
    /// without a supervisor or with the check disabled): it grows while the files are watched.
    #[serde(default)]
    pub integrity_checks: u64,
}

/// A program stored on the station.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProgramInfo {
    /// Id (used in URLs).
    pub id: String,
    /// File name.
    pub name: String,
    /// Who uploaded it.
    pub owner: String,
    /// Size in bytes.
    pub size: u64,
    /// Number of lines.
    pub lines: usize,
    /// Published by an administrator: every student may see, check and run it (otherwise
    /// only its owner and administrators).
    #[serde(default)]
    pub published: bool,
}

impl ProgramInfo {
    /// True if `caller` may see (and, as a student or admin, check and run) this program:
    /// admins see every program, students their own and the published ones, viewers the
    /// published ones.
    #[must_use]
    pub fn visible_to(&self, caller: &Caller) -> bool {
        match caller.role {
            Role::Admin => true,
            Role::Student => self.published || self.owner == caller.user,
            Role::Viewer => self.published,
        }
    }
}

/// One error found when checking a program.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProgramDiagnostic {
    /// 1-based line.
    pub line: usize,
    /// 1-based column.
    pub col: usize,
    /// What is wrong.
    pub message: String,
}

/// Result of checking a program.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProgramCheck {
    /// Errors (empty: the program may run).
    pub errors: Vec<ProgramDiagnostic>,
    /// Peak motion per axis id (for the student limits).
    pub demands: Vec<(String, motus_lab::MotionDemand)>,
}

/// Program runner state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RunState {
    /// Nothing loaded or running.
    Idle,
    /// Running.
    Running,
    /// Feed hold.
    Held,
    /// Single block: stopped after a block, waiting for cycle start (resume).
    BlockStop,
    /// Finished normally.
    Done,
    /// Stopped by a user, an E-stop or the supervisor.
    Stopped,
}

/// The program runner's status.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProgramStatus {
    /// State.
    pub state: RunState,
    /// Program id, if one was run.
    pub program: Option<String>,
    /// Progress 0..=1.
    pub progress: f64,
    /// Current 1-based line (0 before the first).
    pub line: usize,
    /// Text of the current line.
    pub line_text: String,
    /// Why it stopped, if it did.
    pub message: Option<String>,
    /// Tool position X, Y, Z, mm (the set-point sent to the gantry).
    pub xyz: [f64; 3],
    /// Executed path speed, mm/min (with the override).
    pub feed: f64,
    /// Feed override, percent (0-200; students at most 100).
    pub override_percent: f64,
    /// Single-block mode.
    pub single_block: bool,
}

/// The tool path of a checked program, for the preview (machine mm, polyline).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProgramPreview {
    /// X, Y, Z points, mm; arcs as chords.
    pub points: Vec<[f64; 3]>,
    /// Least distance between points, mm (a long program's preview is thinned).
    pub spacing_mm: f64,
    /// Rapid (true) or feed (false) move ending at each point.
    pub rapid: Vec<bool>,
}

/// Points of the executed path of a run since a cursor.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ExecutedPathView {
    /// The run (a new run starts a new path).
    pub run: u64,
    /// Cursor of the first point.
    pub from: u64,
    /// Cursor to ask from next.
    pub next: u64,
    /// X, Y, Z points, mm.
    pub points: Vec<[f64; 3]>,
}

/// A traced signal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SignalView {
    /// Id (index into [`Sample::values`] is the position in [`MachineBackend::signals`]).
    pub id: String,
    /// Unit.
    pub unit: String,
}

/// One sample of every signal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Seconds since the backend started.
    pub t: f64,
    /// One value per signal, in [`MachineBackend::signals`] order.
    pub values: Vec<f64>,
}

/// Samples after a cursor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SampleBatch {
    /// Pass this to the next [`MachineBackend::samples_since`].
    pub cursor: u64,
    /// The samples, oldest first.
    pub samples: Vec<Sample>,
}

/// The omnidirectional robot in the 2-D scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotScene {
    /// Pose `[x m, y m, theta rad]`.
    pub pose: [f64; 3],
    /// Recent path, oldest first.
    pub path: Vec<[f64; 2]>,
    /// Current go-to target, if any.
    pub target: Option<[f64; 2]>,
    /// Map bounds `[xmin, ymin, xmax, ymax]`.
    pub bounds: [f64; 4],
}

/// A 2-D drawing of the simulated machines (for the live scene view).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SceneView {
    /// Robot, if the station has one.
    pub robot: Option<RobotScene>,
    /// Pan-tilt `[pan, tilt]` in rad.
    pub pan_tilt: Option<[f64; 2]>,
    /// Arm joint angles (rad) and link lengths (m).
    pub arm: Option<(Vec<f64>, Vec<f64>)>,
    /// Juggler axes `(id, position, min, max)`.
    pub juggler: Vec<(String, f64, f64, f64)>,
    /// Gantry `[x, y, z]` and its bounds `[xmax, ymax, zmax]`.
    pub gantry: Option<([f64; 3], [f64; 3])>,
}

/// Why the backend refused or failed a request.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BackendError {
    /// A field is invalid (HTTP 400).
    #[error("invalid {field}: {message}")]
    Invalid {
        /// The field.
        field: String,
        /// Why.
        message: String,
    },
    /// No such axis, group or program (HTTP 404).
    #[error("no {kind} {id:?}")]
    NotFound {
        /// `axis`, `group`, `program`.
        kind: &'static str,
        /// The id asked.
        id: String,
    },
    /// The supervisor holds motion: SafeToRun is false or latched (HTTP 409).
    #[error("motion held by the supervisor: {0}")]
    SafetyHold(String),
    /// The E-stop is pressed (HTTP 409).
    #[error("emergency stop active; reset first")]
    EStopped,
    /// The machine is not in a state for this command (HTTP 409).
    #[error("not possible now: {0}")]
    State(String),
    /// The machine failed (HTTP 500).
    #[error("machine failure: {0}")]
    Failed(String),
    /// The backend refuses this caller (HTTP 403): a student beyond the axis's student
    /// limits or on an axis students cannot move, a student resetting an emergency stop an
    /// administrator pressed. The message says why (and who pressed the stop).
    #[error("not allowed: {0}")]
    Forbidden(String),
    /// The backend has no capacity for this request now (HTTP 503): e.g. every program
    /// checker is busy. Try again later.
    #[error("busy: {0}")]
    Busy(String),
}

impl BackendError {
    /// An [`BackendError::Invalid`].
    #[must_use]
    pub fn invalid(field: &str, message: String) -> Self {
        BackendError::Invalid { field: field.to_string(), message }
    }
}

/// What the web layer needs from the machine. Every method is quick (no waiting for a
/// motion to finish); the web layer calls them from blocking-safe threads.
pub trait MachineBackend: Send + Sync {
    /// Every axis.
    fn axes(&self) -> Vec<AxisView>;
    /// Commands one axis (validated with [`AxisAction::validate`]).
    ///
    /// # Errors
    /// [`BackendError`].
    fn command(&self, caller: &Caller, axis: &str, action: AxisAction) -> Result<(), BackendError>;
    /// Changes an axis's limits (admin only: enforced by the web layer).
    ///
    /// # Errors
    /// [`BackendError`].
    fn set_axis_parameters(
        &self,
        caller: &Caller,
        axis: &str,
        params: AxisParameters,
    ) -> Result<(), BackendError>;
    /// Emergency stop of every axis (always possible).
    fn estop(&self, caller: &Caller);
    /// Resets the E-stop and the supervisor latch (if SafeToRun is true again).
    ///
    /// # Errors
    /// [`BackendError::SafetyHold`] while still unsafe.
    fn reset(&self, caller: &Caller) -> Result<(), BackendError>;
    /// The supervisor's state.
    fn safety(&self) -> SafetyView;
    /// Replaces the supervisor's rules (TOML); returns the new fingerprint.
    ///
    /// # Errors
    /// [`BackendError::Invalid`] for a rule file that does not parse.
    fn set_safety_rules(&self, caller: &Caller, toml: &str) -> Result<String, BackendError>;
    /// Stores a program.
    ///
    /// # Errors
    /// [`BackendError::Invalid`] (empty, too large, bad name).
    fn upload_program(&self, caller: &Caller, name: &str, text: &str) -> Result<ProgramInfo, BackendError>;
    /// The stored programs `caller` may see ([`ProgramInfo::visible_to`]).
    fn programs(&self, caller: &Caller) -> Vec<ProgramInfo>;
    /// Checks a program `caller` may see (errors with line:col, per-axis demands). May take
    /// up to the backend's check budget: call it from a blocking-safe thread.
    ///
    /// # Errors
    /// [`BackendError::NotFound`] (also for a program `caller` may not see: its name does
    /// not leak), [`BackendError::Forbidden`] for a viewer, [`BackendError::Busy`] when
    /// every checker is busy.
    fn check_program(&self, caller: &Caller, id: &str) -> Result<ProgramCheck, BackendError>;
    /// Runs a checked program `caller` may see.
    ///
    /// # Errors
    /// [`BackendError`] (errors in the program, busy, held...).
    fn run_program(&self, caller: &Caller, id: &str) -> Result<(), BackendError>;
    /// Publishes a program to every student, or withdraws it (`published: false`); the web
    /// layer lets only administrators call it.
    ///
    /// # Errors
    /// [`BackendError::NotFound`], [`BackendError::Forbidden`] for a non-administrator.
    fn publish_program(
        &self,
        caller: &Caller,
        id: &str,
        published: bool,
    ) -> Result<ProgramInfo, BackendError>;
    /// Feed hold.
    ///
    /// # Errors
    /// [`BackendError::State`] when nothing runs.
    fn hold_program(&self, caller: &Caller) -> Result<(), BackendError>;
    /// Resume after a hold.
    ///
    /// # Errors
    /// [`BackendError::State`] when not held.
    fn resume_program(&self, caller: &Caller) -> Result<(), BackendError>;
    /// Stops the program (motion stops).
    ///
    /// # Errors
    /// [`BackendError::State`] when nothing runs.
    fn stop_program(&self, caller: &Caller) -> Result<(), BackendError>;
    /// The runner's status.
    fn program_status(&self) -> ProgramStatus;
    /// Feed override in percent for the running program and later runs (0-200; a student
    /// at most 100: their programs were checked against the student limits at 100 %).
    ///
    /// # Errors
    /// [`BackendError::Invalid`] outside 0-200, [`BackendError::Forbidden`] above 100 for a
    /// student.
    fn set_program_override(&self, caller: &Caller, percent: f64) -> Result<(), BackendError>;
    /// Single-block mode: the program stops after each block until resumed (cycle start).
    ///
    /// # Errors
    /// [`BackendError`].
    fn set_single_block(&self, caller: &Caller, on: bool) -> Result<(), BackendError>;
    /// The preview of a program `caller` may check (from its cached check).
    ///
    /// # Errors
    /// As [`MachineBackend::check_program`].
    fn program_preview(&self, caller: &Caller, id: &str) -> Result<ProgramPreview, BackendError>;
    /// The executed path of run `run` from `cursor` on (another run: from its start).
    fn executed_path(&self, run: u64, cursor: u64) -> ExecutedPathView;
    /// Checks one MDI line as a program of one line (errors, per-axis demands).
    ///
    /// # Errors
    /// [`BackendError::Invalid`] (empty, several lines, too long), as
    /// [`MachineBackend::check_program`] otherwise.
    fn check_mdi(&self, caller: &Caller, line: &str) -> Result<ProgramCheck, BackendError>;
    /// The MDI line the runner is executing (running, held or at a block stop), if its
    /// program is one: resuming it is authorised like running the line again.
    fn running_mdi(&self) -> Option<String>;
    /// Executes one MDI line on the machine (checked again, as a program).
    ///
    /// # Errors
    /// As [`MachineBackend::run_program`].
    fn run_mdi(&self, caller: &Caller, line: &str) -> Result<(), BackendError>;
    /// The traced signals.
    fn signals(&self) -> Vec<SignalView>;
    /// Samples after `cursor` (0: everything kept).
    fn samples_since(&self, cursor: u64) -> SampleBatch;
    /// The 2-D scene.
    fn scene(&self) -> SceneView;
    /// Axis groups.
    fn groups(&self) -> Vec<GroupView>;
    /// Commands a group.
    ///
    /// # Errors
    /// [`BackendError`].
    fn group_command(&self, caller: &Caller, group: &str, action: GroupAction) -> Result<(), BackendError>;
    /// External camera URL (real machines), if configured.
    fn camera_url(&self) -> Option<String>;
    /// The camera of `group`, if it has one (`[[group]] camera` of the cell file).
    fn camera(&self, group: &str) -> Option<CameraFeed> {
        let _ = group;
        None
    }
    /// The slot of `user` ended: remove their programs and traces, bring the machine to a
    /// safe, homed state.
    fn on_slot_end(&self, user: &str);
    /// The slot of `user` on one machine (`group`) ended: bring that machine to a safe,
    /// homed state (its program stopped); `last`: the user holds no other slot now, so their
    /// programs and traces are removed too. The other machines are not touched.
    fn on_machine_slot_end(&self, group: &str, user: &str, last: bool);

    /// The cyclic task classes: cycle time, jitter, overruns, state (none by default).
    fn tasks(&self) -> Vec<TaskView> {
        Vec::new()
    }

    /// Every signal of the cyclic tasks at its full rate, as CSV (`None`: none traced).
    fn trace_csv(&self) -> Option<String> {
        None
    }
}

/// One cyclic task class as the HMI shows it (`GET /api/tasks`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TaskView {
    /// Class name.
    pub name: String,
    /// Period, microseconds.
    pub period_us: u64,
    /// `running`, `degraded: <why>`, `stalled` or `stopped`.
    pub state: String,
    /// Cycles since the last reset.
    pub cycles: u64,
    /// Overrun events.
    pub overruns: u64,
    /// Start lateness (jitter) p50 / p99 / max, microseconds.
    pub lateness_us: [u64; 3],
    /// Execution time p50 / p99 / max, microseconds.
    pub execution_us: [u64; 3],
    /// CPU load of the class thread, percent of one core.
    pub cpu_percent: f64,
}
