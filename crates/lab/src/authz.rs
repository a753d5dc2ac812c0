//! The one place that decides whether a user may do something.
//!
//! Rules ([`decide`]):
//! - Everyone logged in may **view** (state, camera, alarms, reservations).
//! - A **viewer** never commands and never reserves.
//! - A **student** commands a station only while holding its current reservation, not while
//!   the station is being reset after a slot, and within the student motion limits of the
//!   configuration (a move or jog must state its speed and acceleration; an axis without
//!   configured limits cannot be moved by a student: fail closed). A student reserves and
//!   cancels only for themselves.
//! - **E-stop** is allowed to every student and admin at any time, slot or not: stopping is
//!   always safe, and someone watching the camera must be able to stop a machine that is
//!   about to damage itself. (Viewers cannot: they never command.)
//! - Only an **admin** changes the safety configuration or axis parameters, manages users,
//!   ends another user's session or slot, reads the audit log; an admin may command at any
//!   time, within no student limits (the supervisor still governs).
//! - There is **no action that sets SafeToRun**, for anyone: the supervisor computes it and
//!   no interface of this layer can write it. Changing the safety configuration goes through
//!   the supervisor's own integrity approval.

use std::collections::BTreeMap;
use std::fmt;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::role::Role;
use crate::store::{ReservationFilter, Store, StoreError};
use crate::time::UnixMs;

/// Who is acting (from a valid session, or the local console).
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Actor {
    /// User name.
    pub name: String,
    /// Role at the time of the request.
    pub role: Role,
}

impl Actor {
    /// An actor.
    #[must_use]
    pub fn new(name: &str, role: Role) -> Self {
        Actor { name: name.to_string(), role }
    }
}

/// What an axis command does (for the decision and the audit log).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AxisOp {
    /// Power stage on.
    Enable,
    /// Power stage off.
    Disable,
    /// Homing.
    Home,
    /// Absolute or relative move (needs a [`MotionDemand`] from a student).
    Move,
    /// Jog (needs a [`MotionDemand`] from a student).
    Jog,
    /// Controlled stop.
    Stop,
    /// Quick stop.
    QuickStop,
    /// Fault reset.
    FaultReset,
}

impl AxisOp {
    fn as_str(self) -> &'static str {
        match self {
            AxisOp::Enable => "enable",
            AxisOp::Disable => "disable",
            AxisOp::Home => "home",
            AxisOp::Move => "move",
            AxisOp::Jog => "jog",
            AxisOp::Stop => "stop",
            AxisOp::QuickStop => "quick_stop",
            AxisOp::FaultReset => "fault_reset",
        }
    }
}

/// Peak speed and acceleration a command asks of one axis, in the axis's SI units
/// (m/s, m/s^2 or rad/s, rad/s^2; signs are ignored), and the positions it reaches.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MotionDemand {
    /// Peak speed.
    pub speed: f64,
    /// Peak acceleration (or deceleration).
    pub acceleration: f64,
    /// Lowest and highest position the motion reaches (a move: `[target, target]`; a
    /// program: its path's extent on this axis); `None` when not known in advance (a jog,
    /// which the machine stops at the limits itself).
    #[serde(default)]
    pub range: Option<[f64; 2]>,
}

impl MotionDemand {
    /// A demand without a known position range (a jog).
    #[must_use]
    pub fn new(speed: f64, acceleration: f64) -> Self {
        MotionDemand { speed, acceleration, range: None }
    }

    /// A demand that reaches positions `lowest ..= highest`.
    #[must_use]
    pub fn within(speed: f64, acceleration: f64, lowest: f64, highest: f64) -> Self {
        MotionDemand { speed, acceleration, range: Some([lowest, highest]) }
    }

    /// One line for the audit log: `to=0.25 speed=0.5 acc=5` (a single position),
    /// `range=[0, 0.5] speed=0.5 acc=5`, or `speed=0.5 acc=5` (no range); numbers with at
    /// most 6 significant digits.
    #[must_use]
    pub fn describe(&self) -> String {
        let motion = format!("speed={} acc={}", fmt_number(self.speed), fmt_number(self.acceleration));
        match self.range {
            // Equal bits, so NaN also prints as a range.
            Some([lo, hi]) if lo.to_bits() == hi.to_bits() => format!("to={} {motion}", fmt_number(lo)),
            Some([lo, hi]) => format!("range=[{}, {}] {motion}", fmt_number(lo), fmt_number(hi)),
            None => motion,
        }
    }
}

/// `v` with at most 6 significant digits, without trailing zeros (`0.25`, `1.15`, `87.266`,
/// `1000000`, `1.23457e-7`, `NaN`, `inf`).
fn fmt_number(v: f64) -> String {
    if !v.is_finite() {
        return v.to_string();
    }
    if v == 0.0 {
        return "0".to_string();
    }
    // Finite and non-zero: the decimal exponent is within -324..=308.
    let magnitude = v.abs().log10().floor() as i32;
    if (-4..15).contains(&magnitude) {
        // Digits after the point for 6 significant digits (none from 100 000 up).
        let decimals = usize::try_from(5 - magnitude).unwrap_or(0);
        let s = format!("{v:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        let s = format!("{v:.5e}");
        match s.split_once('e') {
            Some((mantissa, exp)) if mantissa.contains('.') => {
                format!("{}e{exp}", mantissa.trim_end_matches('0').trim_end_matches('.'))
            }
            _ => s,
        }
    }
}

/// Bounds for student motion on one axis, same units as [`MotionDemand`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionLimits {
    /// Maximum speed.
    pub max_speed: f64,
    /// Maximum acceleration.
    pub max_acceleration: f64,
    /// Lowest position a student may reach (`None`: no position bound in this layer).
    #[serde(default)]
    pub min: Option<f64>,
    /// Highest position a student may reach (`None`: no position bound in this layer).
    #[serde(default)]
    pub max: Option<f64>,
}

impl MotionLimits {
    /// Speed and acceleration bounds without a position range.
    #[must_use]
    pub fn new(max_speed: f64, max_acceleration: f64) -> Self {
        MotionLimits { max_speed, max_acceleration, min: None, max: None }
    }

    /// Speed, acceleration and position bounds.
    #[must_use]
    pub fn with_range(max_speed: f64, max_acceleration: f64, min: f64, max: f64) -> Self {
        MotionLimits { max_speed, max_acceleration, min: Some(min), max: Some(max) }
    }

    /// True when the limits bound positions.
    #[must_use]
    pub fn bounds_position(&self) -> bool {
        self.min.is_some() || self.max.is_some()
    }
}

/// Student motion limits per axis name (from the station configuration).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StudentLimits {
    /// Limits by axis name.
    pub axes: BTreeMap<String, MotionLimits>,
    /// Limits for axes not listed; with `None` students cannot move unlisted axes.
    pub default: Option<MotionLimits>,
}

impl StudentLimits {
    /// The limits that apply to `axis`.
    #[must_use]
    pub fn for_axis(&self, axis: &str) -> Option<MotionLimits> {
        self.axes.get(axis).copied().or(self.default)
    }
}

/// A command to a station.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "command", rename_all = "snake_case")]
pub enum Command {
    /// An axis command.
    Axis {
        /// Axis name.
        axis: String,
        /// What it does.
        op: AxisOp,
        /// Peak motion asked (required from students for `move` and `jog`).
        demand: Option<MotionDemand>,
    },
    /// Run a stored program; `demands` are its per-axis peaks as analysed by the station.
    RunProgram {
        /// Program name.
        name: String,
        /// Per-axis peak motion (axis name, demand).
        demands: Vec<(String, MotionDemand)>,
    },
    /// Upload a program or trace.
    Upload {
        /// File name.
        name: String,
    },
    /// Mark a program or trace exported (kept after the slot).
    Export {
        /// File name.
        name: String,
    },
    /// Delete a program or trace.
    DeleteFile {
        /// File name.
        name: String,
    },
    /// Record a trace.
    Trace,
    /// Controlled stop of all motion.
    Stop,
    /// Emergency stop (allowed to students and admins at any time).
    EStop,
    /// Acknowledge an alarm.
    AcknowledgeAlarm {
        /// Alarm id.
        id: i64,
    },
    /// Reset a fault (drives, supervisor latch).
    ResetFault,
}

/// Something a user wants to do. There is deliberately no variant that sets SafeToRun.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "action", rename_all = "snake_case")]
pub enum Action {
    /// See a station (state, camera, alarms, reservations).
    View {
        /// Station.
        station: String,
    },
    /// Command a station.
    Command {
        /// Station.
        station: String,
        /// The command.
        command: Command,
    },
    /// Change (upload) the supervisor's safety configuration.
    ChangeSafetyConfig {
        /// Station.
        station: String,
    },
    /// Change an axis's parameters (and the reference copy the integrity check uses).
    ChangeAxisParameters {
        /// Station.
        station: String,
        /// Axis.
        axis: String,
    },
    /// Add, delete or change users.
    ManageUsers,
    /// End another user's login sessions and current slot.
    EndSession {
        /// Whose.
        user: String,
    },
    /// Book a slot.
    Reserve {
        /// Station.
        station: String,
        /// For whom.
        for_user: String,
    },
    /// Cancel (or end early) a reservation.
    CancelReservation {
        /// Station.
        station: String,
        /// The reservation's holder.
        owner: String,
    },
    /// Read the audit log.
    ViewAudit,
}

impl Action {
    /// A short dotted name for the audit log (`command.axis.move`, `change_safety_config`...).
    #[must_use]
    pub fn name(&self) -> String {
        match self {
            Action::View { .. } => "view".into(),
            Action::Command { command, .. } => match command {
                Command::Axis { op, .. } => format!("command.axis.{}", op.as_str()),
                Command::RunProgram { .. } => "command.run_program".into(),
                Command::Upload { .. } => "command.upload".into(),
                Command::Export { .. } => "command.export".into(),
                Command::DeleteFile { .. } => "command.delete_file".into(),
                Command::Trace => "command.trace".into(),
                Command::Stop => "command.stop".into(),
                Command::EStop => "command.estop".into(),
                Command::AcknowledgeAlarm { .. } => "command.ack_alarm".into(),
                Command::ResetFault => "command.reset_fault".into(),
            },
            Action::ChangeSafetyConfig { .. } => "change_safety_config".into(),
            Action::ChangeAxisParameters { .. } => "change_axis_parameters".into(),
            Action::ManageUsers => "manage_users".into(),
            Action::EndSession { .. } => "end_session".into(),
            Action::Reserve { .. } => "reserve".into(),
            Action::CancelReservation { .. } => "cancel_reservation".into(),
            Action::ViewAudit => "view_audit".into(),
        }
    }

    /// What it acts on and with which parameters, one line for the audit log:
    /// `st1/x move to=0.25 speed=0.5 acc=5`, `st1/x jog speed=-0.1 acc=2`, `st1/x home`,
    /// `st1/prog.nc axes: x range=[0, 0.5] speed=0.5 acc=5; y speed=1 acc=2`,
    /// `st1/prog.txt`, `user:bob`... Numbers have at most 6 significant digits.
    #[must_use]
    pub fn target(&self) -> String {
        match self {
            Action::View { station } | Action::ChangeSafetyConfig { station } => station.clone(),
            Action::Command { station, command } => match command {
                Command::Axis { axis, op, demand } => {
                    let mut t = format!("{station}/{axis} {}", op.as_str());
                    if let Some(d) = demand {
                        t.push(' ');
                        t.push_str(&d.describe());
                    }
                    t
                }
                Command::RunProgram { name, demands } if !demands.is_empty() => {
                    let axes: Vec<String> =
                        demands.iter().map(|(axis, d)| format!("{axis} {}", d.describe())).collect();
                    format!("{station}/{name} axes: {}", axes.join("; "))
                }
                Command::RunProgram { name, .. }
                | Command::Upload { name }
                | Command::Export { name }
                | Command::DeleteFile { name } => format!("{station}/{name}"),
                Command::AcknowledgeAlarm { id } => format!("{station}/alarm:{id}"),
                Command::Trace | Command::Stop | Command::EStop | Command::ResetFault => station.clone(),
            },
            Action::ChangeAxisParameters { station, axis } => format!("{station}/{axis}"),
            Action::ManageUsers | Action::ViewAudit => String::new(),
            Action::EndSession { user } => format!("user:{user}"),
            Action::Reserve { station, for_user } => format!("{station} for {for_user}"),
            Action::CancelReservation { station, owner } => format!("{station} of {owner}"),
        }
    }

    /// The station a command-like action concerns, if any.
    #[must_use]
    pub fn station(&self) -> Option<&str> {
        match self {
            Action::View { station }
            | Action::Command { station, .. }
            | Action::ChangeSafetyConfig { station }
            | Action::ChangeAxisParameters { station, .. }
            | Action::Reserve { station, .. }
            | Action::CancelReservation { station, .. } => Some(station),
            Action::ManageUsers | Action::EndSession { .. } | Action::ViewAudit => None,
        }
    }
}

/// Which motion quantity exceeded a limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Quantity {
    /// Speed.
    Speed,
    /// Acceleration.
    Acceleration,
}

/// Why an action was refused.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "reason", rename_all = "snake_case")]
pub enum DenyReason {
    /// The action needs a higher role.
    RoleTooLow {
        /// Lowest role allowed.
        required: Role,
        /// The actor's role.
        actual: Role,
    },
    /// A student commanded a station outside their own slot.
    NotSlotHolder {
        /// Station.
        station: String,
        /// Who holds it now, if anyone.
        holder: Option<String>,
    },
    /// The station is being reset after a slot (programs removed, homing).
    StationResetting {
        /// Station.
        station: String,
    },
    /// A motion demand exceeds the student limit (or is not a finite number).
    MotionLimit {
        /// Axis.
        axis: String,
        /// Speed or acceleration.
        quantity: Quantity,
        /// Asked.
        requested: f64,
        /// Allowed.
        limit: f64,
    },
    /// No student limits are configured for this axis.
    NoMotionLimits {
        /// Axis.
        axis: String,
    },
    /// A student's motion would leave the student position range (or states no range for an
    /// axis whose student limits bound positions).
    PositionLimit {
        /// Axis.
        axis: String,
        /// Lowest and highest position asked (`None`: not stated).
        requested: Option<[f64; 2]>,
        /// Allowed lowest position.
        min: f64,
        /// Allowed highest position.
        max: f64,
    },
    /// A move or jog by a student did not state its speed and acceleration.
    MissingMotionDemand {
        /// Axis.
        axis: String,
    },
    /// A student acted on another user's reservation.
    NotOwner {
        /// The other user.
        owner: String,
    },
}

impl fmt::Display for DenyReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DenyReason::RoleTooLow { required, actual } => {
                write!(f, "role {actual} may not do this (needs {required})")
            }
            DenyReason::NotSlotHolder { station, holder: Some(h) } => {
                write!(f, "{station} is reserved by {h} now")
            }
            DenyReason::NotSlotHolder { station, holder: None } => {
                write!(f, "no reservation of yours on {station} now")
            }
            DenyReason::StationResetting { station } => {
                write!(f, "{station} is being reset after the previous slot")
            }
            DenyReason::MotionLimit { axis, quantity, requested, limit } => {
                write!(f, "{axis}: {quantity:?} {requested} exceeds the student limit {limit}")
            }
            DenyReason::PositionLimit { axis, requested: Some([lo, hi]), min, max } => {
                if lo == hi {
                    write!(f, "{axis}: position {lo} is outside the student range [{min}, {max}]")
                } else {
                    write!(f, "{axis}: positions {lo} ..= {hi} leave the student range [{min}, {max}]")
                }
            }
            DenyReason::PositionLimit { axis, requested: None, min, max } => {
                write!(f, "{axis}: the motion's positions are unknown; the student range is [{min}, {max}]")
            }
            DenyReason::NoMotionLimits { axis } => {
                write!(f, "{axis}: no student limits configured: students cannot move this axis")
            }
            DenyReason::MissingMotionDemand { axis } => {
                write!(f, "{axis}: a student's move must state its speed and acceleration")
            }
            DenyReason::NotOwner { owner } => write!(f, "belongs to {owner}"),
        }
    }
}

/// An action refused by [`decide`] / [`Authorizer::authorize`] (HTTP 403 at the web layer).
#[derive(Debug, Clone, PartialEq, thiserror::Error, Serialize, Deserialize)]
#[error("denied: {reason}")]
pub struct Denied {
    /// Why.
    pub reason: DenyReason,
}

impl From<DenyReason> for Denied {
    fn from(reason: DenyReason) -> Self {
        Denied { reason }
    }
}

/// What [`decide`] needs to know about the station at the time of the request.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Facts<'a> {
    /// Holder of the station's current reservation.
    pub holder: Option<&'a str>,
    /// A finished slot of this station awaits its cleanup.
    pub resetting: bool,
}

fn need(role: Role, required: Role) -> Result<(), Denied> {
    if role >= required {
        Ok(())
    } else {
        Err(DenyReason::RoleTooLow { required, actual: role }.into())
    }
}

/// Checks one demand against the student limits of `axis`. `needs_range`: the motion goes
/// to stated positions (a move, a program), so an axis whose student limits bound positions
/// refuses a demand that does not state them.
fn check_demand(
    axis: &str,
    demand: MotionDemand,
    limits: &StudentLimits,
    needs_range: bool,
) -> Result<(), Denied> {
    let Some(lim) = limits.for_axis(axis) else {
        return Err(DenyReason::NoMotionLimits { axis: axis.to_string() }.into());
    };
    if lim.bounds_position() {
        let min = lim.min.unwrap_or(f64::NEG_INFINITY);
        let max = lim.max.unwrap_or(f64::INFINITY);
        let refuse = |requested| DenyReason::PositionLimit { axis: axis.to_string(), requested, min, max };
        match demand.range {
            // NaN fails every comparison: refused.
            Some([lo, hi]) if !(lo >= min && hi <= max && lo <= hi) => {
                return Err(refuse(Some([lo, hi])).into());
            }
            None if needs_range => return Err(refuse(None).into()),
            Some(_) | None => {}
        }
    }
    for (quantity, requested, limit) in [
        (Quantity::Speed, demand.speed.abs(), lim.max_speed),
        (Quantity::Acceleration, demand.acceleration.abs(), lim.max_acceleration),
    ] {
        // Not finite (NaN, infinity; also a broken configured limit) or above it: refused.
        if !requested.is_finite() || !limit.is_finite() || requested > limit {
            return Err(DenyReason::MotionLimit { axis: axis.to_string(), quantity, requested, limit }.into());
        }
    }
    Ok(())
}

/// True for actions whose decision for a student depends on [`Facts`].
#[must_use]
pub fn needs_facts(role: Role, action: &Action) -> bool {
    role == Role::Student
        && matches!(action, Action::Command { command, .. } if !matches!(command, Command::EStop))
}

/// The decision, as a pure function of who, what, the station's [`Facts`] and the student
/// limits. See the module documentation for the rules.
///
/// # Errors
/// [`Denied`] with the first rule that refuses.
pub fn decide(
    actor: &Actor,
    action: &Action,
    facts: Facts<'_>,
    limits: &StudentLimits,
) -> Result<(), Denied> {
    let role = actor.role;
    match action {
        Action::View { .. } => Ok(()),
        Action::ChangeSafetyConfig { .. }
        | Action::ChangeAxisParameters { .. }
        | Action::ManageUsers
        | Action::EndSession { .. }
        | Action::ViewAudit => need(role, Role::Admin),
        Action::Reserve { for_user: owner, .. } | Action::CancelReservation { owner, .. } => {
            need(role, Role::Student)?;
            if role < Role::Admin && *owner != actor.name {
                return Err(DenyReason::NotOwner { owner: owner.clone() }.into());
            }
            Ok(())
        }
        Action::Command { station, command } => {
            need(role, Role::Student)?;
            if role >= Role::Admin || matches!(command, Command::EStop) {
                return Ok(());
            }
            if facts.holder != Some(actor.name.as_str()) {
                return Err(DenyReason::NotSlotHolder {
                    station: station.clone(),
                    holder: facts.holder.map(str::to_string),
                }
                .into());
            }
            if facts.resetting {
                return Err(DenyReason::StationResetting { station: station.clone() }.into());
            }
            match command {
                Command::Axis { axis, op: op @ (AxisOp::Move | AxisOp::Jog), demand } => match demand {
                    Some(d) => check_demand(axis, *d, limits, *op == AxisOp::Move),
                    None => Err(DenyReason::MissingMotionDemand { axis: axis.clone() }.into()),
                },
                Command::Axis { axis, demand: Some(d), .. } => check_demand(axis, *d, limits, false),
                Command::RunProgram { demands, .. } => {
                    demands.iter().try_for_each(|(axis, d)| check_demand(axis, *d, limits, true))
                }
                _ => Ok(()),
            }
        }
    }
}

/// Why [`Authorizer::authorize`] could not answer or refused.
#[derive(Debug, thiserror::Error)]
pub enum AuthzError {
    /// Refused.
    #[error(transparent)]
    Denied(#[from] Denied),
    /// The facts could not be read (treat as refused).
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// [`decide`] with the facts read from the store.
pub struct Authorizer {
    store: Arc<dyn Store>,
    limits: StudentLimits,
}

impl Authorizer {
    /// An authorizer over `store` with the student motion `limits`.
    #[must_use]
    pub fn new(store: Arc<dyn Store>, limits: StudentLimits) -> Self {
        Authorizer { store, limits }
    }

    /// The student limits in force.
    #[must_use]
    pub fn limits(&self) -> &StudentLimits {
        &self.limits
    }

    /// Decides whether `user` with `role` may do `action` at `now`.
    ///
    /// # Errors
    /// [`AuthzError::Denied`], or [`AuthzError::Store`] if the reservations could not be read.
    pub fn authorize(&self, user: &str, role: Role, action: &Action, now: UnixMs) -> Result<(), AuthzError> {
        let actor = Actor::new(user, role);
        let mut holder = None;
        let mut resetting = false;
        if needs_facts(role, action) {
            if let Some(station) = action.station() {
                let current = self.store.list_reservations(&ReservationFilter {
                    station: Some(station.to_string()),
                    window: Some((now, now.plus(std::time::Duration::from_millis(1)))),
                    ..ReservationFilter::default()
                })?;
                holder = current.into_iter().next().map(|r| r.user);
                resetting = !self
                    .store
                    .list_reservations(&ReservationFilter {
                        station: Some(station.to_string()),
                        pending_cleanup_at: Some(now),
                        ..ReservationFilter::default()
                    })?
                    .is_empty();
            }
        }
        let facts = Facts { holder: holder.as_deref(), resetting };
        Ok(decide(&actor, action, facts, &self.limits)?)
    }
}
