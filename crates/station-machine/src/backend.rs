//! [`MachineBackend`] for the [`StationMachine`].

use std::sync::atomic::Ordering;
use std::sync::PoisonError;
use std::time::Instant;

use motus_axis::{AxisCommand, AxisError, Direction, MotionProfile};
use motus_cell::{GroupHandle, Pattern};
use motus_station::scheduler::ClassState;
use motus_station_web::{
    AxisAction, AxisLimits, AxisParameters, AxisView, BackendError, Caller, GroupAction, GroupKind,
    GroupView, MachineBackend, PredictedReach, ProgramCheck, ProgramInfo, ProgramStatus, RobotScene,
    RunState, SafetyView, Sample, SampleBatch, SceneView, SignalView, TaskView,
};

use motus_lab::Role;
use motus_station::config::StudentLimits;

use crate::jog::{JogDecision, JogSpec};
use crate::{lock, StationMachine};

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
    fn view(&self, id: &str) -> Result<AxisView, BackendError> {
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
        action.validate(&view)?;
        self.check_student(caller, &view, &action)?;
        let motion = !matches!(action, AxisAction::Stop);
        if motion && self.shared.estop.load(Ordering::Relaxed) {
            return Err(BackendError::EStopped);
        }
        if motion {
            if let Some(reason) = self.shared.faults.fault_of(axis) {
                return Err(BackendError::State(format!(
                    "axis {axis}: {reason}; the station is reconnecting it, motion is refused until it is back"
                )));
            }
        }
        if motion && view.group.as_deref() == Some("juggler") {
            if let Some(why) = self.juggler_blocks() {
                return Err(BackendError::SafetyHold(why));
            }
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
        quick_stop_all(&self.shared);
    }

    fn reset(&self, caller: &Caller) -> Result<(), BackendError> {
        {
            // Decided and cleared together: a press in between is not lost.
            let mut owners = lock(&self.shared.estop_owners);
            if self.shared.estop.load(Ordering::SeqCst) {
                if let Err(why) = owners.may_reset(caller.role) {
                    tracing::warn!(user = %caller.user, "reset refused: {why}");
                    return Err(BackendError::Forbidden(why));
                }
            }
            tracing::info!(user = %caller.user, "reset");
            owners.clear();
            self.shared.estop.store(false, Ordering::SeqCst);
        }
        if let Some(j) = self.shared.juggler.as_ref() {
            j.reset();
        }
        for a in &self.shared.axes {
            let _ = lock(&a.axis).execute(&AxisCommand::FaultReset);
        }
        // A task class degraded by overruns is recoverable from here (the web), always.
        self.resume_tasks();
        Ok(())
    }

    fn safety(&self) -> SafetyView {
        let estop = self.shared.estop.load(Ordering::Relaxed);
        let Some(j) = self.shared.juggler.as_ref() else {
            return SafetyView {
                safe_to_run: !estop,
                held: estop,
                estop,
                diagnosis: estop.then(|| lock(&self.shared.estop_owners).diagnosis()),
                rules_name: "none".into(),
                rules_fingerprint: String::new(),
                predicted: Vec::new(),
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
        let diagnosis = match (&s.integrity, &s.diagnosis) {
            (Err(e), _) => Some(e.clone()),
            (Ok(()), d) => d.clone(),
        };
        SafetyView {
            safe_to_run: s.safe_to_run == Some(true) && !s.held && !estop,
            held: s.held || estop,
            estop,
            diagnosis: if estop { Some(lock(&self.shared.estop_owners).diagnosis()) } else { diagnosis },
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
        let st = self.programs.service.status();
        if matches!(st.state, motus_cnc::ServiceState::Running | motus_cnc::ServiceState::Held) {
            return Err(BackendError::State("a program is running".into()));
        }
        // The cached check (the checker's thread interpreted it within its budget).
        let (_, text, check) = self.checked_program(caller, id)?;
        if let Some(e) = check.errors.first() {
            return Err(BackendError::invalid("program", format!("{}:{}: {}", e.line, e.col, e.message)));
        }
        self.check_student_program(caller, &check)?;
        tracing::info!(user = %caller.user, id, demands = ?check.demands, "program run");
        self.programs.service.run_checked(id, &text);
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
                motus_cnc::ServiceState::Done => RunState::Done,
                motus_cnc::ServiceState::Stopped => RunState::Stopped,
            },
            program: lock(&self.programs.running).clone(),
            progress: s.progress,
            line: s.line as usize,
            line_text: s.line_text,
            message: s.message,
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
                    if let Some(p) = o.true_pose() {
                        scene.robot = Some(RobotScene {
                            pose: [p.x, p.y, p.heading],
                            path: lock(&self.shared.robot_path).iter().copied().collect(),
                            target: None,
                            bounds: [-2.0, -2.0, 2.0, 2.0],
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
                    let s = self.programs.service.status();
                    scene.gantry =
                        Some(([s.xyz[0] / 1000.0, s.xyz[1] / 1000.0, s.xyz[2] / 1000.0], [2.0, 1.5, 0.3]));
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
            })
            .collect()
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
                if matches!(g.handle, GroupHandle::Omni(_) | GroupHandle::Juggler(_)) {
                    return Err(BackendError::State(format!(
                        "group {group}: go-to is not available here (move its axes, or use `motus robot` for the robot)"
                    )));
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

/// How long an E-stop waits for the drives' quick-stop commands to be sent before it
/// answers; a drive still busy on its bus gets its quick stop as soon as its line is free,
/// and a failure is logged.
const ESTOP_CONFIRM_WAIT: std::time::Duration = std::time::Duration::from_millis(250);

/// Quick-stops every axis at once: one short-lived thread per axis (at device priority), so
/// the slowest line does not delay the others (they used to be stopped one after another:
/// E-stop answers took p99 ~300 ms on the demo cell). Waits up to [`ESTOP_CONFIRM_WAIT`].
fn quick_stop_all(shared: &std::sync::Arc<crate::Shared>) {
    let (tx, rx) = std::sync::mpsc::channel::<(usize, Option<String>)>();
    let mut pending = 0usize;
    for i in 0..shared.axes.len() {
        let s = std::sync::Arc::clone(shared);
        let tx = tx.clone();
        let spawned = std::thread::Builder::new().name("motus-estop".into()).spawn(move || {
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Device);
            if let Some(a) = s.axes.get(i) {
                let r = lock(&a.axis).execute(&AxisCommand::QuickStop);
                let _ = tx.send((i, r.err().map(|e| e.to_string())));
            }
        });
        match spawned {
            Ok(_) => pending += 1,
            Err(e) => {
                // No thread to be had: stop it from here.
                tracing::warn!("E-stop thread: {e}; quick-stopping inline");
                if let Some(a) = shared.axes.get(i) {
                    if let Err(e) = lock(&a.axis).execute(&AxisCommand::QuickStop) {
                        tracing::warn!(axis = %a.view.id, "quick stop: {e}");
                    }
                }
            }
        }
    }
    drop(tx);
    let deadline = std::time::Instant::now() + ESTOP_CONFIRM_WAIT;
    while pending > 0 {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        match rx.recv_timeout(left) {
            Ok((i, err)) => {
                pending -= 1;
                if let (Some(e), Some(a)) = (err, shared.axes.get(i)) {
                    tracing::warn!(axis = %a.view.id, "quick stop: {e}");
                }
            }
            Err(_) => {
                tracing::warn!(
                    "E-stop: {pending} axes still sending their quick stop after {ESTOP_CONFIRM_WAIT:?}"
                );
                break;
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
