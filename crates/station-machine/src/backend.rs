//! [`MachineBackend`] for the [`StationMachine`].

use std::sync::atomic::Ordering;
use std::sync::PoisonError;
use std::time::Instant;

use motus_axis::{AxisCommand, AxisError, Direction, MotionProfile};
use motus_cell::{GroupHandle, Pattern};
use motus_station::scheduler::ClassState;
use motus_station_web::{
    AxisAction, AxisLimits, AxisParameters, AxisView, BackendError, Caller, CameraFeed, ExecutedPathView,
    GroupAction, GroupKind, GroupView, MachineBackend, PredictedReach, ProgramCheck, ProgramInfo,
    ProgramPreview, ProgramStatus, RobotScene, RunState, SafetyView, Sample, SampleBatch, SceneView,
    SignalView, TaskView,
};

use motus_lab::Role;
use motus_station::config::StudentLimits;

use crate::jog::{JogDecision, JogSpec};
use crate::{lock, StationMachine};

/// How long an E-stop reset waits for the juggler's supervisor to apply it and decide (it
/// passes every cycle, 1 ms in the demo); the E-stop shows held meanwhile.
const SUPERVISOR_RESET_WAIT: std::time::Duration = std::time::Duration::from_millis(250);

fn failed(e: impl std::fmt::Display) -> BackendError {
    BackendError::Failed(e.to_string())
}

/// A device's refusal is the caller's conflict (409), its failure the machine's (500).
fn axis_error(e: AxisError) -> BackendError {
    match e {
        AxisError::InvalidArgument { .. } => BackendError::invalid("command", e.to_string()),
        AxisError::NotHomed { .. }
        | AxisError::BeyondLimit { .. }
        | AxisError::NotEnabled { .. }
        | AxisError::Unsupported { .. }
        | AxisError::Refused { .. } => BackendError::State(e.to_string()),
        other => failed(other),
    }
}

/// Callers below an administrator (students; viewers never get this far) are held to the
/// student limits.
fn restricted(caller: &Caller) -> bool {
    caller.role < Role::Admin
}

impl StationMachine {
    pub(crate) fn view(&self, id: &str) -> Result<AxisView, BackendError> {
        self.shared
            .views
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .iter()
            .find(|v| v.id == id)
            .cloned()
            .ok_or_else(|| BackendError::NotFound { kind: "axis", id: id.to_owned() })
    }

    fn entry(&self, id: &str) -> Result<&crate::AxisEntry, BackendError> {
        self.shared
            .axes
            .iter()
            .find(|a| a.view.id == id)
            .ok_or_else(|| BackendError::NotFound { kind: "axis", id: id.to_owned() })
    }

    /// Executes `command` under the axis's lock. A motion or stop command that the device
    /// accepted ends the axis's jog lease (it replaced the jog); one it refused leaves the
    /// lease, so the watchdog still stops a running jog.
    fn execute(&self, id: &str, command: &AxisCommand) -> Result<(), BackendError> {
        let entry = self.entry(id)?;
        let mut axis = lock(&entry.axis);
        axis.execute(command).map_err(axis_error)?;
        if !matches!(command, AxisCommand::Enable | AxisCommand::FaultReset) {
            lock(&self.shared.jogs).end(id);
        }
        Ok(())
    }

    /// The student limits of an axis: refused (fail closed) when the cell file gives it none.
    fn student_limits(&self, axis: &str) -> Result<StudentLimits, BackendError> {
        self.shared.config.axis(axis).and_then(|c| c.student).ok_or_else(|| {
            BackendError::Forbidden(format!(
                "axis {axis} has no student limits in the cell file: students cannot move it"
            ))
        })
    }

    /// Defence in depth (the lab checked first): a student's command stays within the axis's
    /// student limits — a move's target in the student range, speed and acceleration within
    /// the student maxima; an axis without student limits refuses every student command but
    /// stop. Administrators are held to the machine limits only ([`AxisAction::validate`]).
    fn check_student(
        &self,
        caller: &Caller,
        view: &AxisView,
        action: &AxisAction,
    ) -> Result<(), BackendError> {
        if !restricted(caller) || matches!(action, AxisAction::Stop) {
            return Ok(());
        }
        let s = self.student_limits(&view.id)?;
        let (speed, acceleration) = match *action {
            AxisAction::Move { target, speed, acceleration } => {
                // NaN fails every comparison: refused.
                if !(target >= s.limits.min && target <= s.limits.max) {
                    return Err(BackendError::Forbidden(format!(
                        "axis {}: target {target} is outside the student range [{}, {}] {}",
                        view.id, s.limits.min, s.limits.max, view.unit
                    )));
                }
                (speed, acceleration)
            }
            AxisAction::Jog { speed, acceleration, .. } => (speed, acceleration),
            AxisAction::Home | AxisAction::Stop => return Ok(()),
        };
        let acceleration = acceleration.unwrap_or(view.acceleration);
        if speed.is_nan() || speed.abs() > s.max_velocity {
            return Err(BackendError::Forbidden(format!(
                "axis {}: speed {speed} exceeds the student limit {} {}/s",
                view.id, s.max_velocity, view.unit
            )));
        }
        if acceleration.is_nan() || acceleration.abs() > s.max_acceleration {
            return Err(BackendError::Forbidden(format!(
                "axis {}: acceleration {acceleration} exceeds the student limit {} {}/s^2",
                view.id, s.max_acceleration, view.unit
            )));
        }
        Ok(())
    }

    /// What every motion command needs besides its numbers: no E-stop, the axis's device
    /// connected, the juggler's supervisor not holding its axes.
    pub(crate) fn motion_allowed(&self, view: &AxisView) -> Result<(), BackendError> {
        if self.shared.estop.load(Ordering::Relaxed) {
            return Err(BackendError::EStopped);
        }
        if let Some(reason) = self.shared.faults.fault_of(&view.id) {
            return Err(BackendError::State(format!(
                "axis {}: {reason}; the station is reconnecting it, motion is refused until it is back",
                view.id
            )));
        }
        if view.group.as_deref() == Some("juggler") {
            if let Some(why) = self.juggler_blocks() {
                return Err(BackendError::SafetyHold(why));
            }
        }
        if self.is_gantry_axis(&view.id) && self.program_active() {
            return Err(BackendError::State(format!(
                "axis {} is driven by the running program: stop the program first",
                view.id
            )));
        }
        Ok(())
    }

    /// Takes the omni robot to `targets` = `[x, y]` or `[x, y, heading]` (metres, radians;
    /// see [`crate::robot`]): three synchronised wheel moves from the station's pose
    /// estimate. Every wheel move is checked (machine limits, a student's limits) before any
    /// starts, so a refusal moves nothing.
    fn robot_go_to(
        &self,
        caller: &Caller,
        g: &motus_cell::CellGroup,
        targets: &[f64],
    ) -> Result<(), BackendError> {
        let (x, y, heading) = match *targets {
            [x, y] => (x, y, None),
            [x, y, h] => (x, y, Some(h)),
            _ => {
                return Err(BackendError::invalid(
                    "targets",
                    format!("{} values: the robot takes [x, y] or [x, y, heading]", targets.len()),
                ))
            }
        };
        let estimate = self.shared.robot.as_ref().ok_or_else(|| {
            BackendError::State(format!("group {}: the robot needs three wheel axes", g.name))
        })?;
        let (travel, min_rates) = {
            let e = lock(estimate);
            (e.travel_to(x, y, heading)?, e.min_rates())
        };
        let views = g.axes.iter().map(|a| self.view(a)).collect::<Result<Vec<_>, _>>()?;
        // The slowest wheel's speed and acceleration bound the move (a student's: within the
        // student maxima).
        let mut speed = f64::INFINITY;
        let mut acceleration = f64::INFINITY;
        for v in &views {
            speed = speed.min(v.default_speed);
            acceleration = acceleration.min(v.acceleration);
            if restricted(caller) {
                let s = self.student_limits(&v.id)?;
                speed = speed.min(s.max_velocity);
                acceleration = acceleration.min(s.max_acceleration);
            }
        }
        // Relative wheel moves (a wheel is endless: it has no reference to home to); each is
        // checked as the absolute move it amounts to.
        let mut moves = Vec::new();
        for ((v, t), sync) in
            views.iter().zip(travel).zip(crate::robot::synchronised(travel, speed, acceleration, min_rates))
        {
            let Some((speed, acceleration)) = sync else { continue };
            let action = AxisAction::Move { target: v.position + t, speed, acceleration: Some(acceleration) };
            action.validate(v)?;
            self.check_student(caller, v, &action)?;
            self.motion_allowed(v)?;
            let profile =
                MotionProfile { velocity: Some(speed), acceleration: Some(acceleration), deceleration: None };
            moves.push((v, AxisCommand::MoveRelative { distance: t, profile }));
        }
        tracing::info!(user = %caller.user, group = %g.name, x, y, ?heading, ?travel, "robot go-to");
        lock(estimate).target = Some([x, y]);
        for (v, cmd) in moves {
            if !v.enabled {
                let _ = self.execute(&v.id, &AxisCommand::Enable);
            }
            if let Err(e) = self.execute(&v.id, &cmd) {
                // One wheel refused: stop the others rather than drive a wrong path.
                for v in &views {
                    let _ = self.execute(&v.id, &AxisCommand::Stop);
                }
                return Err(e);
            }
        }
        Ok(())
    }

    /// A jog, as a lease renewed by repeated requests (see [`crate::jog`]).
    ///
    /// What the drive is commanded:
    /// - a student's jog is a `MoveAbsolute` toward the student limit in the jog direction
    ///   (within the current machine limits) at the jog's speed, so it stops at the student
    ///   range however long it is renewed; it is refused on an axis that is not homed (its
    ///   position, hence the range, is unknown);
    /// - an administrator's jog on a homed axis is likewise a `MoveAbsolute` toward the
    ///   machine's soft limit (the cell file's, or the narrower ones set through the API);
    ///   on an axis that is not homed, the device's native jog;
    /// - when the device refuses that end as beyond its own limit (narrower than the cell
    ///   file's: e.g. the KV-01's joint soft limits), the device's native jog, which stops at
    ///   that limit, inside the range.
    ///
    /// Either way the watchdog stops it with `AxisCommand::Stop` when it is not renewed
    /// within [`crate::jog::JOG_LEASE`].
    fn jog(
        &self,
        caller: &Caller,
        view: &AxisView,
        direction: f64,
        speed: f64,
        acceleration: f64,
    ) -> Result<(), BackendError> {
        let positive = direction > 0.0;
        let target = if restricted(caller) {
            if !view.homed {
                return Err(BackendError::State(format!(
                    "axis {} is not homed: its position is unknown, so a student's jog cannot be kept \
                     within the student range; home it first",
                    view.id
                )));
            }
            let s = self.student_limits(&view.id)?;
            Some(if positive { s.limits.max.min(view.limits.max) } else { s.limits.min.max(view.limits.min) })
        } else if view.homed {
            Some(if positive { view.limits.max } else { view.limits.min })
        } else {
            None
        };
        let profile =
            MotionProfile { velocity: Some(speed), acceleration: Some(acceleration), deceleration: None };
        let native = AxisCommand::Jog {
            direction: if positive { Direction::Positive } else { Direction::Negative },
            profile,
        };
        let cmd = match target {
            Some(target) => AxisCommand::MoveAbsolute { target, profile },
            None => native.clone(),
        };
        let spec = JogSpec { direction: if positive { 1.0 } else { -1.0 }, speed, acceleration, target };
        let entry = self.entry(&view.id)?;
        if !view.enabled {
            let _ = lock(&entry.axis).execute(&AxisCommand::Enable);
        }
        // Decided and commanded under the axis's lock (the watchdog re-checks under it too).
        let mut axis = lock(&entry.axis);
        if self.shared.estop.load(Ordering::SeqCst) {
            return Err(BackendError::EStopped);
        }
        let decision =
            lock(&self.shared.jogs).request(&view.id, spec, &caller.user, view.moving, Instant::now());
        match decision {
            JogDecision::Renewed => Ok(()),
            JogDecision::Command => {
                let result = match axis.execute(&cmd) {
                    // The device's own limit lies before the range's end: its native jog stops
                    // at that limit, inside the range.
                    Err(AxisError::BeyondLimit { .. }) if target.is_some() => axis.execute(&native),
                    r => r,
                };
                result.map_err(|e| {
                    lock(&self.shared.jogs).command_failed(&view.id);
                    axis_error(e)
                })
            }
        }
    }

    fn juggler_blocks(&self) -> Option<String> {
        let j = self.shared.juggler.as_ref()?;
        let s = j.snapshot();
        (s.safe_to_run != Some(true)).then(|| s.diagnosis.unwrap_or_else(|| "SafeToRun is false".into()))
    }
}

impl MachineBackend for StationMachine {
    fn axes(&self) -> Vec<AxisView> {
        self.shared.views.read().unwrap_or_else(PoisonError::into_inner).clone()
    }

    fn command(&self, caller: &Caller, axis: &str, action: AxisAction) -> Result<(), BackendError> {
        let view = self.view(axis)?;
        if matches!(action, AxisAction::Stop) && self.is_gantry_axis(axis) {
            // A stop of one gantry axis stops the program that drives it (else its next
            // set-point would move the axis again).
            self.programs.service.stop();
        }
        action.validate(&view)?;
        self.check_student(caller, &view, &action)?;
        if !matches!(action, AxisAction::Stop) {
            self.motion_allowed(&view)?;
        }
        tracing::info!(user = %caller.user, axis, ?action, "axis command");
        let profile = |speed: f64, acc: Option<f64>| MotionProfile {
            velocity: Some(speed),
            acceleration: Some(acc.unwrap_or(view.acceleration)),
            deceleration: None,
        };
        let cmd = match action {
            AxisAction::Jog { direction, speed, acceleration } => {
                return self.jog(caller, &view, direction, speed, acceleration.unwrap_or(view.acceleration));
            }
            AxisAction::Move { target, speed, acceleration } => {
                AxisCommand::MoveAbsolute { target, profile: profile(speed, acceleration) }
            }
            AxisAction::Home => {
                if !view.enabled {
                    // Switch the drive on first; a device without enable reports so and homes anyway.
                    let _ = self.execute(axis, &AxisCommand::Enable);
                }
                AxisCommand::Home
            }
            AxisAction::Stop => AxisCommand::Stop,
        };
        if matches!(cmd, AxisCommand::MoveAbsolute { .. }) && !view.enabled {
            // Every device refuses an absolute move without its position reference: refused
            // here, before the drive is switched on, so the refusal leaves the drive off.
            if !view.homed {
                return Err(BackendError::State(format!("axis {axis} is not homed: run `home` first")));
            }
            let _ = self.execute(axis, &AxisCommand::Enable);
        }
        self.execute(axis, &cmd)
    }

    fn set_axis_parameters(
        &self,
        caller: &Caller,
        axis: &str,
        params: AxisParameters,
    ) -> Result<(), BackendError> {
        let entry = self
            .shared
            .axes
            .iter()
            .find(|a| a.view.id == axis)
            .ok_or_else(|| BackendError::NotFound { kind: "axis", id: axis.to_owned() })?;
        if entry.view.group.as_deref() == Some("juggler") {
            return Err(BackendError::State(format!(
                "axis {axis} is supervised: its limits are in the safety rules (PUT /api/safety/rules)"
            )));
        }
        check_parameters(&entry.view.limits, &params)?;
        tracing::warn!(admin = %caller.user, axis, ?params, "axis parameters changed");
        self.shared.overrides.write().unwrap_or_else(PoisonError::into_inner).insert(axis.to_owned(), params);
        if let Some(v) = self
            .shared
            .views
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .iter_mut()
            .find(|v| v.id == axis)
        {
            apply_parameters(v, &params);
        }
        Ok(())
    }

    fn estop(&self, caller: &Caller) {
        tracing::warn!(user = %caller.user, role = caller.role.as_str(), "EMERGENCY STOP");
        lock(&self.shared.estop_owners).press(crate::stops::Press {
            user: caller.user.clone(),
            role: caller.role,
            at: std::time::SystemTime::now(),
        });
        self.shared.estop.store(true, Ordering::SeqCst);
        lock(&self.shared.jogs).end_all();
        self.programs.service.stop();
        if let Some(j) = self.shared.juggler.as_ref() {
            j.stop_all();
        }
        self.quick_stoppers.stop_all(&self.shared);
    }

    fn reset(&self, caller: &Caller) -> Result<(), BackendError> {
        let releasing = &self.shared.estop_releasing;
        let was_estop = {
            // Decided and cleared together: a press in between is not lost.
            let mut owners = lock(&self.shared.estop_owners);
            let was_estop = self.shared.estop.load(Ordering::SeqCst);
            if was_estop {
                if let Err(why) = owners.may_reset(caller.role) {
                    tracing::warn!(user = %caller.user, "reset refused: {why}");
                    return Err(BackendError::Forbidden(why));
                }
                // Until the supervisor has decided, the juggler's hold is the E-stop's, not
                // a trip (see `safety`).
                releasing.fetch_add(1, Ordering::SeqCst);
            }
            tracing::info!(user = %caller.user, "reset");
            owners.clear();
            self.shared.estop.store(false, Ordering::SeqCst);
            was_estop
        };
        if let Some(j) = self.shared.juggler.as_ref() {
            if was_estop {
                if !j.reset_and_wait(SUPERVISOR_RESET_WAIT) {
                    tracing::warn!(
                        "reset: the juggler's supervisor did not decide within {SUPERVISOR_RESET_WAIT:?}"
                    );
                }
            } else {
                j.reset();
            }
        }
        if was_estop {
            releasing.fetch_sub(1, Ordering::SeqCst);
        }
        for a in &self.shared.axes {
            let _ = lock(&a.axis).execute(&AxisCommand::FaultReset);
        }
        // A task class degraded by overruns is recoverable from here (the web), always.
        self.resume_tasks();
        Ok(())
    }

    fn safety(&self) -> SafetyView {
        let pressed = self.shared.estop.load(Ordering::SeqCst);
        let releasing = self.shared.estop_releasing.load(Ordering::SeqCst) > 0;
        let estop = pressed || releasing;
        let estop_diagnosis = || {
            if pressed {
                lock(&self.shared.estop_owners).diagnosis()
            } else {
                "emergency stop reset: waiting for the safety supervisor's decision".to_owned()
            }
        };
        let Some(j) = self.shared.juggler.as_ref() else {
            return SafetyView {
                safe_to_run: !estop,
                held: estop,
                estop,
                diagnosis: estop.then(estop_diagnosis),
                rules_name: "none".into(),
                rules_fingerprint: String::new(),
                predicted: Vec::new(),
                integrity_checks: 0,
            };
        };
        let s = j.snapshot();
        let limits = self.shared.rule_limits.read().unwrap_or_else(PoisonError::into_inner).clone();
        // In the rules' units: the reach until standstill against the axis's end limits.
        let predicted = s
            .reaches
            .iter()
            .map(|(axis, r)| {
                let lim = limits.iter().find(|(n, _, _)| n == axis).map(|(_, lo, hi)| (*lo, *hi));
                let (stop_position, distance) = match lim {
                    Some((lo, hi)) if hi - r.hi <= r.lo - lo => (r.hi, hi - r.hi),
                    Some((lo, _)) => (r.lo, r.lo - lo),
                    None => (r.hi, f64::NAN),
                };
                PredictedReach { axis: axis.clone(), stop_position, distance }
            })
            .collect();
        let safe_to_run = s.safe_to_run == Some(true) && !s.held && !estop;
        // Why it is not safe or held; nothing while it is safe (the snapshot keeps why
        // SafeToRun fell last, e.g. "no data" from the start-up, which read as a fault beside
        // SafeToRun).
        let diagnosis = match (&s.integrity, &s.diagnosis) {
            _ if estop => Some(estop_diagnosis()),
            _ if safe_to_run => None,
            (Err(e), _) => Some(e.clone()),
            (Ok(()), d) => d.clone(),
        };
        SafetyView {
            safe_to_run,
            held: s.held || estop,
            estop,
            diagnosis,
            rules_name: self
                .shared
                .config
                .supervisor
                .as_ref()
                .map_or("none".into(), |c| c.rules.display().to_string()),
            rules_fingerprint: self
                .shared
                .rules_fingerprint
                .read()
                .unwrap_or_else(PoisonError::into_inner)
                .clone(),
            predicted,
            integrity_checks: s.integrity_checks,
        }
    }

    fn set_safety_rules(&self, caller: &Caller, toml: &str) -> Result<String, BackendError> {
        crate::rules::install(&self.shared, caller, toml)
    }

    fn upload_program(&self, caller: &Caller, name: &str, text: &str) -> Result<ProgramInfo, BackendError> {
        if name.is_empty() || name.len() > 128 {
            return Err(BackendError::invalid("name", "1 to 128 characters".into()));
        }
        if text.len() > 4 << 20 {
            return Err(BackendError::invalid("text", "program larger than 4 MiB".into()));
        }
        Ok(self.programs.add(&caller.user, name, text))
    }

    fn programs(&self, caller: &Caller) -> Vec<ProgramInfo> {
        self.programs.list(caller)
    }

    fn check_program(&self, caller: &Caller, id: &str) -> Result<ProgramCheck, BackendError> {
        let (_, _, check) = self.checked_program(caller, id)?;
        tracing::info!(user = %caller.user, id, errors = check.errors.len(), "program check");
        Ok(check)
    }

    fn run_program(&self, caller: &Caller, id: &str) -> Result<(), BackendError> {
        if self.shared.estop.load(Ordering::Relaxed) {
            return Err(BackendError::EStopped);
        }
        if self.program_active() {
            return Err(BackendError::State("a program is running".into()));
        }
        // The cached check (the checker's thread interpreted it within its budget).
        let (_, text, check) = self.checked_program(caller, id)?;
        if let Some(e) = check.errors.first() {
            return Err(BackendError::invalid("program", format!("{}:{}: {}", e.line, e.col, e.message)));
        }
        self.check_student_program(caller, &check)?;
        let start = self.gantry_ready()?;
        tracing::info!(user = %caller.user, id, demands = ?check.demands, ?start, "program run");
        *lock(&self.programs.mdi_line) = None;
        self.programs.service.run_checked_from(id, &text, start);
        *lock(&self.programs.running) = Some(id.to_owned());
        Ok(())
    }

    fn publish_program(
        &self,
        caller: &Caller,
        id: &str,
        published: bool,
    ) -> Result<ProgramInfo, BackendError> {
        if caller.role != Role::Admin {
            return Err(BackendError::Forbidden("only administrators publish programs".into()));
        }
        tracing::info!(admin = %caller.user, id, published, "program publication");
        self.programs.publish(id, published)
    }

    fn hold_program(&self, _caller: &Caller) -> Result<(), BackendError> {
        self.programs.service.hold();
        Ok(())
    }

    fn resume_program(&self, _caller: &Caller) -> Result<(), BackendError> {
        if self.shared.estop.load(Ordering::Relaxed) {
            return Err(BackendError::EStopped);
        }
        self.programs.service.resume();
        Ok(())
    }

    fn stop_program(&self, _caller: &Caller) -> Result<(), BackendError> {
        self.programs.service.stop();
        Ok(())
    }

    fn program_status(&self) -> ProgramStatus {
        let s = self.programs.service.status();
        ProgramStatus {
            state: match s.state {
                motus_cnc::ServiceState::Idle => RunState::Idle,
                motus_cnc::ServiceState::Running => RunState::Running,
                motus_cnc::ServiceState::Held => RunState::Held,
                motus_cnc::ServiceState::BlockStop => RunState::BlockStop,
                motus_cnc::ServiceState::Done => RunState::Done,
                motus_cnc::ServiceState::Stopped => RunState::Stopped,
            },
            program: lock(&self.programs.running).clone(),
            progress: s.progress,
            line: s.line as usize,
            line_text: s.line_text,
            message: s.message,
            xyz: s.xyz,
            feed: s.feed,
            override_percent: s.override_percent,
            single_block: s.single_block,
        }
    }

    fn set_program_override(&self, caller: &Caller, percent: f64) -> Result<(), BackendError> {
        if !(0.0..=200.0).contains(&percent) {
            return Err(BackendError::invalid("percent", format!("{percent} is outside 0-200")));
        }
        if restricted(caller) && percent > 100.0 {
            return Err(BackendError::Forbidden(format!(
                "feed override {percent} %: students may run at most 100 % (their programs are checked \
                 against the student limits at 100 %)"
            )));
        }
        tracing::info!(user = %caller.user, percent, "feed override");
        self.programs
            .service
            .set_override(percent)
            .map_err(|e| BackendError::invalid("percent", e.to_string()))
    }

    fn set_single_block(&self, caller: &Caller, on: bool) -> Result<(), BackendError> {
        tracing::info!(user = %caller.user, on, "single block");
        self.programs.service.set_single_block(on);
        Ok(())
    }

    fn program_preview(&self, caller: &Caller, id: &str) -> Result<ProgramPreview, BackendError> {
        self.programs.preview(caller, id)
    }

    fn executed_path(&self, run: u64, cursor: u64) -> ExecutedPathView {
        let b = self.programs.service.executed_path(run, cursor);
        ExecutedPathView { run: b.run, from: b.from, next: b.next, points: b.points }
    }

    fn check_mdi(&self, caller: &Caller, line: &str) -> Result<ProgramCheck, BackendError> {
        self.checked_mdi(caller, line)
    }

    fn run_mdi(&self, caller: &Caller, line: &str) -> Result<(), BackendError> {
        if self.shared.estop.load(Ordering::Relaxed) {
            return Err(BackendError::EStopped);
        }
        if self.program_active() {
            return Err(BackendError::State("a program is running: MDI waits until it ends".into()));
        }
        let check = self.checked_mdi(caller, line)?;
        if let Some(e) = check.errors.first() {
            return Err(BackendError::invalid("line", format!("{}:{}: {}", e.line, e.col, e.message)));
        }
        self.check_student_program(caller, &check)?;
        let start = self.gantry_ready()?;
        tracing::info!(user = %caller.user, line, ?start, "MDI");
        *lock(&self.programs.mdi_line) = Some(line.trim().to_owned());
        self.programs.service.run_checked_from("MDI", line.trim(), start);
        *lock(&self.programs.running) = Some("MDI".to_owned());
        Ok(())
    }

    fn running_mdi(&self) -> Option<String> {
        if self.program_active() {
            lock(&self.programs.mdi_line).clone()
        } else {
            None
        }
    }

    fn signals(&self) -> Vec<SignalView> {
        let mut v: Vec<SignalView> = self
            .shared
            .axes
            .iter()
            .map(|a| SignalView { id: format!("{}.position", a.view.id), unit: a.view.unit.clone() })
            .collect();
        if let Some(rec) = self.shared.recorder.get() {
            let rec = lock(rec);
            v.extend(rec.signals().iter().map(|s| SignalView { id: s.name.clone(), unit: s.unit.clone() }));
        }
        if self.shared.cnc_status.get().is_some() {
            v.push(SignalView { id: "cnc.feed".into(), unit: "mm/min".into() });
        }
        v
    }

    fn trace_csv(&self) -> Option<String> {
        StationMachine::trace_csv(self)
    }

    fn samples_since(&self, cursor: u64) -> SampleBatch {
        let smp = lock(&self.shared.samples);
        let end = smp.first + smp.rows.len() as u64;
        let from = cursor.max(smp.first).min(end);
        let skip = usize::try_from(from - smp.first).unwrap_or(usize::MAX);
        let samples = smp.rows.iter().skip(skip).map(|(t, v)| Sample { t: *t, values: v.clone() }).collect();
        SampleBatch { cursor: end, samples }
    }

    fn scene(&self) -> SceneView {
        let views = self.axes();
        let pos = |id: &str| views.iter().find(|v| v.id == id).map(|v| v.position);
        let mut scene = SceneView::default();
        for g in &self.shared.groups {
            match &g.handle {
                GroupHandle::Omni(o) => {
                    // The simulated robot's true pose when the wheels are simulated (what a
                    // camera over the floor shows), else the station's estimate.
                    let estimate = self.shared.robot.as_ref().map(|e| {
                        let e = lock(e);
                        (e.pose(), e.target)
                    });
                    let pose = o.true_pose().or(estimate.map(|(p, _)| p));
                    if let Some(p) = pose {
                        scene.robot = Some(RobotScene {
                            pose: [p.x, p.y, p.heading],
                            path: lock(&self.shared.robot_path).iter().copied().collect(),
                            target: estimate.and_then(|(_, t)| t),
                            bounds: crate::robot::ROBOT_AREA,
                        });
                    }
                }
                GroupHandle::PanTilt(_) => {
                    if let (Some(a), Some(b)) =
                        (g.axes.first().and_then(|a| pos(a)), g.axes.get(1).and_then(|a| pos(a)))
                    {
                        scene.pan_tilt = Some([a, b]);
                    }
                }
                GroupHandle::Arm(_) => {
                    let joints: Vec<f64> = g.axes.iter().filter_map(|a| pos(a)).collect();
                    let links = vec![0.2; joints.len()];
                    scene.arm = Some((joints, links));
                }
                GroupHandle::Juggler(_) => {
                    for a in &g.axes {
                        if let Some(v) = views.iter().find(|v| &v.id == a) {
                            scene.juggler.push((v.id.clone(), v.position, v.limits.min, v.limits.max));
                        }
                    }
                }
                GroupHandle::Axes => {
                    // Where the gantry's axes are (their drives' positions), in metres.
                    let mut at = [0.0; 3];
                    for (slot, a) in at.iter_mut().zip(&g.axes) {
                        *slot = pos(a).unwrap_or(0.0);
                    }
                    let size = g
                        .axes
                        .iter()
                        .take(3)
                        .map(|a| views.iter().find(|v| &v.id == a).map_or(1.0, |v| v.limits.max));
                    let mut extent = [2.0, 1.5, 0.3];
                    for (slot, m) in extent.iter_mut().zip(size) {
                        *slot = m;
                    }
                    scene.gantry = Some((at, extent));
                }
            }
        }
        scene
    }

    fn groups(&self) -> Vec<GroupView> {
        self.shared
            .groups
            .iter()
            .map(|g| GroupView {
                id: g.name.clone(),
                kind: match &g.handle {
                    GroupHandle::Omni(_) => GroupKind::Robot,
                    GroupHandle::PanTilt(_) => GroupKind::PanTilt,
                    GroupHandle::Arm(_) => GroupKind::Arm,
                    GroupHandle::Juggler(_) => GroupKind::Juggler,
                    GroupHandle::Axes if g.kind == motus_station::config::GroupKind::Axes => GroupKind::Axes,
                    GroupHandle::Axes => GroupKind::Gantry,
                },
                axes: g.axes.clone(),
                programs: match &g.handle {
                    GroupHandle::Juggler(j) if j.program().is_some() => {
                        Pattern::ALL.iter().map(|p| p.name().to_owned()).collect()
                    }
                    _ => Vec::new(),
                },
                program: match &g.handle {
                    GroupHandle::Juggler(j) => j.program().map(|p| p.name().to_owned()),
                    _ => None,
                },
                camera: self.camera(&g.name).is_some(),
            })
            .collect()
    }

    fn camera(&self, group: &str) -> Option<CameraFeed> {
        match self.shared.config.group(group)?.camera.as_ref()? {
            motus_station::config::Camera::Simulated => Some(CameraFeed::Simulated),
            motus_station::config::Camera::Http(url) => Some(CameraFeed::Http(url.clone())),
        }
    }

    fn group_command(&self, caller: &Caller, group: &str, action: GroupAction) -> Result<(), BackendError> {
        let g = self
            .shared
            .groups
            .iter()
            .find(|g| g.name == group)
            .ok_or_else(|| BackendError::NotFound { kind: "group", id: group.to_owned() })?;
        match action {
            GroupAction::Stop => {
                for a in &g.axes {
                    let _ = self.execute(a, &AxisCommand::Stop);
                }
                Ok(())
            }
            GroupAction::Run { program } => {
                let GroupHandle::Juggler(j) = &g.handle else {
                    return Err(BackendError::State(format!("group {group} has no programs to run")));
                };
                let pattern: Pattern =
                    program.parse().map_err(|e: String| BackendError::invalid("program", e))?;
                tracing::info!(user = %caller.user, program = pattern.name(), "juggler program");
                j.select_program(pattern).map_err(BackendError::State)
            }
            GroupAction::GoTo { targets } => {
                if matches!(g.handle, GroupHandle::Juggler(_)) {
                    return Err(BackendError::State(format!(
                        "group {group}: the juggler has no go-to (run one of its programs)"
                    )));
                }
                if matches!(g.handle, GroupHandle::Omni(_)) {
                    return self.robot_go_to(caller, g, &targets);
                }
                if targets.len() != g.axes.len() {
                    return Err(BackendError::invalid(
                        "targets",
                        format!("{} values for {} axes", targets.len(), g.axes.len()),
                    ));
                }
                // Validate every target (machine limits; a student's also against each member's
                // student range and maxima) before moving anything: a refusal moves nothing.
                let mut moves = Vec::new();
                for (a, t) in g.axes.iter().zip(&targets) {
                    let v = self.view(a)?;
                    let action = AxisAction::Move { target: *t, speed: v.default_speed, acceleration: None };
                    action.validate(&v)?;
                    self.check_student(caller, &v, &action)?;
                    moves.push((a.clone(), action));
                }
                for (a, action) in moves {
                    self.command(caller, &a, action)?;
                }
                Ok(())
            }
        }
    }

    fn camera_url(&self) -> Option<String> {
        self.camera_url.clone()
    }

    fn tasks(&self) -> Vec<TaskView> {
        let us = |d: std::time::Duration| u64::try_from(d.as_micros()).unwrap_or(u64::MAX);
        self.task_stats()
            .into_iter()
            .map(|c| TaskView {
                state: match &c.state {
                    ClassState::Running => "running".into(),
                    ClassState::Degraded { reason } => format!("degraded: {reason}"),
                    ClassState::Stalled => "stalled".into(),
                    ClassState::Stopped => "stopped".into(),
                },
                name: c.name.clone(),
                period_us: us(c.period),
                cycles: c.cycles,
                overruns: c.overruns,
                lateness_us: [us(c.lateness.p50), us(c.lateness.p99), us(c.lateness.max)],
                execution_us: [us(c.execution.p50), us(c.execution.p99), us(c.execution.max)],
                cpu_percent: c.cpu_percent(),
            })
            .collect()
    }

    fn on_machine_slot_end(&self, group: &str, user: &str, last: bool) {
        tracing::info!(user, group, last, "machine slot ended: stopping and homing its axes");
        let Some(g) = self.shared.config.group(group) else { return };
        // The program runner drives the gantry: its program goes with the gantry's slot.
        if g.kind == motus_station::config::GroupKind::Gantry {
            self.programs.service.stop();
        }
        if last {
            self.programs.remove_owned_by(user);
        }
        let members: Vec<&crate::AxisEntry> =
            self.shared.axes.iter().filter(|a| a.view.group.as_deref() == Some(group)).collect();
        {
            let mut jogs = lock(&self.shared.jogs);
            for a in &members {
                jogs.end(&a.view.id);
            }
        }
        for a in &members {
            let _ = lock(&a.axis).execute(&AxisCommand::Stop);
        }
        if g.kind != motus_station::config::GroupKind::Juggler {
            for a in &members {
                let _ = lock(&a.axis).execute(&AxisCommand::Home);
            }
        }
    }

    fn on_slot_end(&self, user: &str) {
        tracing::info!(user, "slot ended: removing programs, stopping and homing");
        self.programs.service.stop();
        self.programs.remove_owned_by(user);
        lock(&self.shared.jogs).end_all();
        for a in &self.shared.axes {
            let _ = lock(&a.axis).execute(&AxisCommand::Stop);
        }
        for a in &self.shared.axes {
            if a.view.group.as_deref() != Some("juggler") {
                let _ = lock(&a.axis).execute(&AxisCommand::Home);
            }
        }
    }
}

/// The cell file's limits are the machine's: the API may narrow them, never widen them.
fn check_parameters(cell: &AxisLimits, p: &AxisParameters) -> Result<(), BackendError> {
    let l = &p.limits;
    let finite =
        [l.min, l.max, l.max_speed, l.max_acceleration, p.acceleration].iter().all(|v| v.is_finite());
    if !finite || l.min >= l.max || l.max_speed <= 0.0 || l.max_acceleration <= 0.0 {
        return Err(BackendError::invalid(
            "limits",
            "need finite values, min < max and positive maxima".into(),
        ));
    }
    if l.min < cell.min || l.max > cell.max {
        return Err(BackendError::invalid(
            "limits",
            format!("[{}, {}] is outside the cell file's [{}, {}]", l.min, l.max, cell.min, cell.max),
        ));
    }
    if l.max_speed > cell.max_speed || l.max_acceleration > cell.max_acceleration {
        return Err(BackendError::invalid(
            "limits",
            format!(
                "speed {} / acceleration {} exceed the cell file's {} / {}",
                l.max_speed, l.max_acceleration, cell.max_speed, cell.max_acceleration
            ),
        ));
    }
    if p.acceleration <= 0.0 || p.acceleration > l.max_acceleration {
        return Err(BackendError::invalid("acceleration", "must be in (0, max_acceleration]".into()));
    }
    Ok(())
}

/// An administrator's parameters on an axis's view (what commands are validated against).
pub(crate) fn apply_parameters(v: &mut AxisView, p: &AxisParameters) {
    v.limits = p.limits;
    v.acceleration = p.acceleration;
    v.default_speed = v.default_speed.min(p.limits.max_speed);
}
