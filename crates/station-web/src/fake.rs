//! [`FakeBackend`]: an in-memory machine for tests and the `fake_station` example.
//!
//! Eleven axes in four groups (gantry `x y z`, robot `robot_x robot_y robot_theta`, pan-tilt
//! `pan tilt`, arm `j1 j2 j3`) move toward their targets on a 10 ms background tick with a
//! trapezoid-like law (speed limited, acceleration limited). A fake supervisor evaluates
//! rules `axis <= max` / `axis >= min` on the predicted stop position
//! (`p + v|v| / 2a`): when one fails it stops every axis and latches *held* with the
//! rule's diagnosis until a reset. Programs are a tiny G-code subset (`G0/G1 X Y Z F`, mm
//! and mm/min) run line by line on the gantry.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serde::Deserialize;

use crate::backend::{
    AxisAction, AxisLimits, AxisParameters, AxisView, BackendError, Caller, GroupAction, GroupKind,
    GroupView, MachineBackend, PredictedReach, ProgramCheck, ProgramInfo, ProgramStatus, RobotScene,
    RunState, SafetyView, Sample, SampleBatch, SceneView, SignalView,
};
use crate::gcode::{check_gcode, FakeBlock};

/// Period of the simulation tick.
pub const TICK: Duration = Duration::from_millis(10);
/// A jog stops unless repeated within this time.
pub const JOG_DEADMAN: Duration = Duration::from_millis(500);
/// Samples kept for [`MachineBackend::samples_since`].
const SAMPLES_KEPT: usize = 3000;
/// Robot path points kept.
const PATH_KEPT: usize = 500;

/// The default rule file of the fake supervisor: gantry X must stay below 0.4 m.
pub const DEFAULT_RULES: &str = r#"name = "fake-rules"

[[rule]]
name = "x_max"
axis = "x"
max = 0.4
"#;

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RuleFile {
    name: String,
    #[serde(default)]
    rule: Vec<Rule>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct Rule {
    name: String,
    axis: String,
    #[serde(default)]
    max: Option<f64>,
    #[serde(default)]
    min: Option<f64>,
}

struct FakeAxis {
    view: AxisView,
    target: Option<f64>,
    speed: f64,
    accel: f64,
    jog: Option<(f64, Instant)>,
}

struct Runner {
    state: RunState,
    program: Option<String>,
    blocks: Vec<FakeBlock>,
    index: usize,
    line: usize,
    line_text: String,
    message: Option<String>,
    started_block: bool,
}

struct Machine {
    axes: Vec<FakeAxis>,
    estop: bool,
    held: bool,
    diagnosis: Option<String>,
    rules: RuleFile,
    fingerprint: String,
    predicted: Vec<PredictedReach>,
    safe: bool,
    programs: Vec<(ProgramInfo, String)>,
    next_program: u64,
    runner: Runner,
    samples: VecDeque<(u64, Sample)>,
    seq: u64,
    path: VecDeque<[f64; 2]>,
    robot_target: Option<[f64; 2]>,
    camera_url: Option<String>,
    start: Instant,
}

/// FNV-1a 64 of the rule text, as hex (a fingerprint for the fake; the real supervisor
/// uses SHA-256).
fn fingerprint(text: &str) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in text.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

fn axis(id: &str, group: &str, unit: &str, min: f64, max: f64, max_speed: f64, acc: f64) -> FakeAxis {
    FakeAxis {
        view: AxisView {
            id: id.to_string(),
            name: id.to_string(),
            device: format!("fake:{group}"),
            group: Some(group.to_string()),
            unit: unit.to_string(),
            position: 0.0,
            velocity: 0.0,
            enabled: true,
            homed: true,
            moving: false,
            fault: None,
            limits: AxisLimits { min, max, max_speed, max_acceleration: acc * 4.0 },
            acceleration: acc,
            default_speed: max_speed / 2.0,
        },
        target: None,
        speed: 0.0,
        accel: acc,
        jog: None,
    }
}

fn parse_rules(text: &str) -> Result<RuleFile, BackendError> {
    let rules: RuleFile =
        toml::from_str(text).map_err(|e| BackendError::invalid("rules", e.to_string().trim().to_string()))?;
    for r in &rules.rule {
        if r.max.is_none() && r.min.is_none() {
            return Err(BackendError::invalid("rules", format!("rule {} has neither min nor max", r.name)));
        }
        if r.max.is_some_and(|v| !v.is_finite()) || r.min.is_some_and(|v| !v.is_finite()) {
            return Err(BackendError::invalid("rules", format!("rule {}: limits must be finite", r.name)));
        }
    }
    Ok(rules)
}

impl Machine {
    fn new(rules: RuleFile, rules_text: &str) -> Self {
        let pi = std::f64::consts::PI;
        let axes = vec![
            axis("x", "gantry", "m", 0.0, 0.5, 0.2, 0.5),
            axis("y", "gantry", "m", 0.0, 0.4, 0.2, 0.5),
            axis("z", "gantry", "m", 0.0, 0.1, 0.05, 0.2),
            axis("robot_x", "robot", "m", -2.0, 2.0, 0.5, 0.5),
            axis("robot_y", "robot", "m", -1.5, 1.5, 0.5, 0.5),
            axis("robot_theta", "robot", "rad", -pi, pi, 1.5, 3.0),
            axis("pan", "pan_tilt", "rad", -2.9, 2.9, 2.0, 6.0),
            axis("tilt", "pan_tilt", "rad", -1.0, 1.0, 2.0, 6.0),
            axis("j1", "arm", "rad", -2.5, 2.5, 1.0, 3.0),
            axis("j2", "arm", "rad", -2.0, 2.0, 1.0, 3.0),
            axis("j3", "arm", "rad", -2.0, 2.0, 1.0, 3.0),
        ];
        Machine {
            axes,
            estop: false,
            held: false,
            diagnosis: None,
            rules,
            fingerprint: fingerprint(rules_text),
            predicted: Vec::new(),
            safe: true,
            programs: Vec::new(),
            next_program: 1,
            runner: Runner {
                state: RunState::Idle,
                program: None,
                blocks: Vec::new(),
                index: 0,
                line: 0,
                line_text: String::new(),
                message: None,
                started_block: false,
            },
            samples: VecDeque::new(),
            seq: 0,
            path: VecDeque::new(),
            robot_target: None,
            camera_url: None,
            start: Instant::now(),
        }
    }

    fn axis_mut(&mut self, id: &str) -> Result<&mut FakeAxis, BackendError> {
        self.axes
            .iter_mut()
            .find(|a| a.view.id == id)
            .ok_or_else(|| BackendError::NotFound { kind: "axis", id: id.to_string() })
    }

    fn position(&self, id: &str) -> Option<f64> {
        self.axes.iter().find(|a| a.view.id == id).map(|a| a.view.position)
    }

    fn ready_for_motion(&self) -> Result<(), BackendError> {
        if self.estop {
            return Err(BackendError::EStopped);
        }
        if self.held || !self.safe {
            return Err(BackendError::SafetyHold(self.diagnosis.clone().unwrap_or_else(|| "held".into())));
        }
        Ok(())
    }

    fn stop_all(&mut self) {
        for a in &mut self.axes {
            a.target = None;
            a.jog = None;
            // Stop with the axis's highest deceleration (quick stop).
            a.accel = a.view.limits.max_acceleration;
        }
        self.robot_target = None;
    }

    fn stop_runner(&mut self, message: &str) {
        if matches!(self.runner.state, RunState::Running | RunState::Held) {
            self.runner.state = RunState::Stopped;
            self.runner.message = Some(message.to_string());
        }
    }

    fn step(&mut self, dt: f64, now: Instant) {
        for a in &mut self.axes {
            let v = a.view.velocity;
            let p = a.view.position;
            let desired = match (a.target, a.jog) {
                (_, Some((dir, until))) if now < until => dir * a.speed,
                (Some(t), _) => {
                    let d = t - p;
                    let brake = (2.0 * a.accel * d.abs()).sqrt();
                    d.signum() * a.speed.min(brake)
                }
                _ => 0.0,
            };
            if a.jog.is_some_and(|(_, until)| now >= until) {
                a.jog = None;
            }
            let dv = (desired - v).clamp(-a.accel * dt, a.accel * dt);
            let mut nv = v + dv;
            let mut np = p + (v + nv) / 2.0 * dt;
            if let Some(t) = a.target {
                if (t - np).abs() < 1e-5 || (t - p).signum() != (t - np).signum() {
                    np = t;
                    nv = 0.0;
                    a.target = None;
                }
            }
            let lim = a.view.limits;
            if np <= lim.min || np >= lim.max {
                np = np.clamp(lim.min, lim.max);
                nv = 0.0;
                a.jog = None;
            }
            a.view.position = np;
            a.view.velocity = nv;
            a.view.moving = nv.abs() > 1e-6 || a.target.is_some() || a.jog.is_some();
        }
        self.supervise();
        self.run_program();
        self.record(now);
    }

    fn supervise(&mut self) {
        let mut predicted = Vec::new();
        let mut first_fail: Option<String> = None;
        for r in &self.rules.rule {
            let Some(a) = self.axes.iter().find(|a| a.view.id == r.axis) else {
                first_fail.get_or_insert_with(|| format!("rule {}: axis {} is missing", r.name, r.axis));
                continue;
            };
            let v = a.view.velocity;
            // One tick of reaction time at the current speed, then braking at the highest rate.
            let stop = a.view.position
                + v * TICK.as_secs_f64()
                + v * v.abs() / (2.0 * a.view.limits.max_acceleration);
            let mut distance = f64::INFINITY;
            if let Some(max) = r.max {
                distance = distance.min(max - stop);
                if max - stop < 0.0 {
                    first_fail.get_or_insert_with(|| {
                        format!("rule {}: {} would stop at {stop:.4} > max {max}", r.name, r.axis)
                    });
                }
            }
            if let Some(min) = r.min {
                distance = distance.min(stop - min);
                if stop - min < 0.0 {
                    first_fail.get_or_insert_with(|| {
                        format!("rule {}: {} would stop at {stop:.4} < min {min}", r.name, r.axis)
                    });
                }
            }
            predicted.push(PredictedReach { axis: r.axis.clone(), stop_position: stop, distance });
        }
        self.predicted = predicted;
        self.safe = first_fail.is_none();
        if let Some(diag) = first_fail {
            if !self.held {
                tracing::warn!(%diag, "fake supervisor: SafeToRun false, stopping every axis");
                self.stop_all();
                self.stop_runner("stopped by the supervisor");
            }
            self.held = true;
            self.diagnosis = Some(diag);
        }
    }

    fn run_program(&mut self) {
        if self.runner.state != RunState::Running {
            return;
        }
        let Some(block) = self.runner.blocks.get(self.runner.index).cloned() else {
            self.runner.state = RunState::Done;
            self.runner.message = None;
            return;
        };
        if !self.runner.started_block {
            self.runner.line = block.line;
            self.runner.line_text = block.text.clone();
            self.runner.started_block = true;
            for (id, target) in &block.targets {
                if let Ok(a) = self.axis_mut(id) {
                    a.target = Some(*target);
                    a.speed = block.speed.min(a.view.limits.max_speed);
                    a.accel = a.view.acceleration;
                }
            }
            return;
        }
        let busy =
            block.targets.iter().any(|(id, _)| self.axes.iter().any(|a| a.view.id == *id && a.view.moving));
        if !busy {
            self.runner.index += 1;
            self.runner.started_block = false;
            if self.runner.index >= self.runner.blocks.len() {
                self.runner.state = RunState::Done;
            }
        }
    }

    fn record(&mut self, now: Instant) {
        let t = now.duration_since(self.start).as_secs_f64();
        let values = self.axes.iter().flat_map(|a| [a.view.position, a.view.velocity]).collect();
        self.seq += 1;
        self.samples.push_back((self.seq, Sample { t, values }));
        while self.samples.len() > SAMPLES_KEPT {
            self.samples.pop_front();
        }
        if let (Some(x), Some(y)) = (self.position("robot_x"), self.position("robot_y")) {
            let moved = self.path.back().map_or(true, |p| (p[0] - x).hypot(p[1] - y) > 0.005);
            if moved {
                self.path.push_back([x, y]);
                while self.path.len() > PATH_KEPT {
                    self.path.pop_front();
                }
            }
        }
    }

    fn progress(&self) -> f64 {
        let n = self.runner.blocks.len();
        if n == 0 {
            return if self.runner.state == RunState::Done { 1.0 } else { 0.0 };
        }
        match self.runner.state {
            RunState::Done => 1.0,
            _ => (self.runner.index as f64 / n as f64).clamp(0.0, 1.0),
        }
    }
}

/// The in-memory machine. Dropping it stops its background thread.
pub struct FakeBackend {
    machine: Arc<Mutex<Machine>>,
    stop: Arc<AtomicBool>,
    thread: Mutex<Option<JoinHandle<()>>>,
}

impl std::fmt::Debug for FakeBackend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FakeBackend").finish_non_exhaustive()
    }
}

impl FakeBackend {
    /// A machine with [`DEFAULT_RULES`], all axes at 0, homed, enabled; starts its tick.
    #[must_use]
    pub fn new() -> Self {
        Self::with_rules(DEFAULT_RULES).unwrap_or_else(|_| {
            Self::start(Machine::new(RuleFile { name: "none".into(), rule: Vec::new() }, ""))
        })
    }

    /// A machine with the given supervisor rules (TOML: `name`, `[[rule]] name axis max|min`).
    ///
    /// # Errors
    /// [`BackendError::Invalid`] if the rules do not parse.
    pub fn with_rules(rules_toml: &str) -> Result<Self, BackendError> {
        let rules = parse_rules(rules_toml)?;
        Ok(Self::start(Machine::new(rules, rules_toml)))
    }

    /// Sets the external camera URL reported by [`MachineBackend::camera_url`].
    pub fn set_camera_url(&self, url: Option<String>) {
        self.lock().camera_url = url;
    }

    fn start(machine: Machine) -> Self {
        let machine = Arc::new(Mutex::new(machine));
        let stop = Arc::new(AtomicBool::new(false));
        let (m, s) = (Arc::clone(&machine), Arc::clone(&stop));
        let thread = std::thread::Builder::new()
            .name("fake-machine".into())
            .spawn(move || {
                let mut next = Instant::now();
                while !s.load(Ordering::Relaxed) {
                    next += TICK;
                    let now = Instant::now();
                    if next > now {
                        std::thread::sleep(next - now);
                    } else {
                        next = now;
                    }
                    m.lock().unwrap_or_else(PoisonError::into_inner).step(TICK.as_secs_f64(), Instant::now());
                }
            })
            .ok();
        FakeBackend { machine, stop, thread: Mutex::new(thread) }
    }

    fn lock(&self) -> MutexGuard<'_, Machine> {
        self.machine.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl Default for FakeBackend {
    fn default() -> Self {
        Self::new()
    }
}

impl Drop for FakeBackend {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.lock().unwrap_or_else(PoisonError::into_inner).take() {
            let _ = t.join();
        }
    }
}

impl MachineBackend for FakeBackend {
    fn axes(&self) -> Vec<AxisView> {
        self.lock().axes.iter().map(|a| a.view.clone()).collect()
    }

    fn command(&self, caller: &Caller, axis: &str, action: AxisAction) -> Result<(), BackendError> {
        let mut m = self.lock();
        let view = m.axis_mut(axis)?.view.clone();
        action.validate(&view)?;
        if !matches!(action, AxisAction::Stop) {
            m.ready_for_motion()?;
        }
        tracing::debug!(user = %caller.user, axis, ?action, "fake command");
        let now = Instant::now();
        let a = m.axis_mut(axis)?;
        match action {
            AxisAction::Jog { direction, speed, acceleration } => {
                a.target = None;
                a.speed = speed;
                a.accel = acceleration.unwrap_or(a.view.acceleration);
                a.jog = Some((direction, now + JOG_DEADMAN));
            }
            AxisAction::Move { target, speed, acceleration } => {
                a.jog = None;
                a.speed = speed;
                a.accel = acceleration.unwrap_or(a.view.acceleration);
                a.target = Some(target);
            }
            AxisAction::Home => {
                a.jog = None;
                a.speed = a.view.default_speed;
                a.accel = a.view.acceleration;
                a.target = Some(0.0_f64.clamp(a.view.limits.min, a.view.limits.max));
                a.view.homed = true;
            }
            AxisAction::Stop => {
                a.jog = None;
                a.target = None;
            }
        }
        Ok(())
    }

    fn set_axis_parameters(
        &self,
        _caller: &Caller,
        axis: &str,
        params: AxisParameters,
    ) -> Result<(), BackendError> {
        let l = params.limits;
        let finite = [l.min, l.max, l.max_speed, l.max_acceleration, params.acceleration]
            .iter()
            .all(|v| v.is_finite());
        if !finite || l.min >= l.max || l.max_speed <= 0.0 || l.max_acceleration <= 0.0 {
            return Err(BackendError::invalid("limits", "need finite min < max and positive maxima".into()));
        }
        if params.acceleration <= 0.0 || params.acceleration > l.max_acceleration {
            return Err(BackendError::invalid("acceleration", "must be in (0, max_acceleration]".into()));
        }
        let mut m = self.lock();
        let a = m.axis_mut(axis)?;
        a.view.limits = l;
        a.view.acceleration = params.acceleration;
        Ok(())
    }

    fn estop(&self, caller: &Caller) {
        let mut m = self.lock();
        tracing::warn!(user = %caller.user, "E-stop");
        m.estop = true;
        m.stop_all();
        m.stop_runner("emergency stop");
    }

    fn reset(&self, _caller: &Caller) -> Result<(), BackendError> {
        let mut m = self.lock();
        if !m.safe {
            return Err(BackendError::SafetyHold(m.diagnosis.clone().unwrap_or_default()));
        }
        m.estop = false;
        m.held = false;
        m.diagnosis = None;
        Ok(())
    }

    fn safety(&self) -> SafetyView {
        let m = self.lock();
        let diagnosis = if m.estop && m.diagnosis.is_none() {
            Some("emergency stop pressed".into())
        } else {
            m.diagnosis.clone()
        };
        SafetyView {
            safe_to_run: m.safe && !m.held && !m.estop,
            held: m.held,
            estop: m.estop,
            diagnosis,
            rules_name: m.rules.name.clone(),
            rules_fingerprint: m.fingerprint.clone(),
            predicted: m.predicted.clone(),
        }
    }

    fn set_safety_rules(&self, caller: &Caller, toml: &str) -> Result<String, BackendError> {
        let rules = parse_rules(toml)?;
        let mut m = self.lock();
        m.rules = rules;
        m.fingerprint = fingerprint(toml);
        tracing::info!(user = %caller.user, fingerprint = %m.fingerprint, "fake supervisor rules replaced");
        Ok(m.fingerprint.clone())
    }

    fn upload_program(&self, caller: &Caller, name: &str, text: &str) -> Result<ProgramInfo, BackendError> {
        let valid_name = !name.is_empty()
            && name.len() <= 64
            && name.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-'));
        if !valid_name {
            return Err(BackendError::invalid("name", "1-64 of A-Z a-z 0-9 . _ -".into()));
        }
        if text.len() > 1_000_000 {
            return Err(BackendError::invalid("text", "larger than 1 MB".into()));
        }
        let mut m = self.lock();
        let existing = m.programs.iter().position(|(p, _)| p.name == name && p.owner == caller.user);
        let id = match existing.and_then(|i| m.programs.get(i)) {
            Some((p, _)) => p.id.clone(),
            None => {
                m.next_program += 1;
                format!("p{}", m.next_program - 1)
            }
        };
        let info = ProgramInfo {
            id,
            name: name.to_string(),
            owner: caller.user.clone(),
            size: text.len() as u64,
            lines: text.lines().count(),
        };
        if let Some(i) = existing {
            m.programs.remove(i);
        }
        m.programs.push((info.clone(), text.to_string()));
        Ok(info)
    }

    fn programs(&self) -> Vec<ProgramInfo> {
        self.lock().programs.iter().map(|(p, _)| p.clone()).collect()
    }

    fn check_program(&self, id: &str) -> Result<ProgramCheck, BackendError> {
        let m = self.lock();
        let (_, text) = m
            .programs
            .iter()
            .find(|(p, _)| p.id == id)
            .ok_or_else(|| BackendError::NotFound { kind: "program", id: id.to_string() })?;
        let views: Vec<AxisView> = m.axes.iter().map(|a| a.view.clone()).collect();
        Ok(check_gcode(text, &views).0)
    }

    fn run_program(&self, caller: &Caller, id: &str) -> Result<(), BackendError> {
        let mut m = self.lock();
        m.ready_for_motion()?;
        if matches!(m.runner.state, RunState::Running | RunState::Held) {
            return Err(BackendError::State("a program is running".into()));
        }
        let (_, text) = m
            .programs
            .iter()
            .find(|(p, _)| p.id == id)
            .ok_or_else(|| BackendError::NotFound { kind: "program", id: id.to_string() })?;
        let views: Vec<AxisView> = m.axes.iter().map(|a| a.view.clone()).collect();
        let (check, blocks) = check_gcode(text, &views);
        if let Some(e) = check.errors.first() {
            return Err(BackendError::invalid("program", format!("{}:{}: {}", e.line, e.col, e.message)));
        }
        tracing::info!(user = %caller.user, id, blocks = blocks.len(), "fake program run");
        m.runner = Runner {
            state: RunState::Running,
            program: Some(id.to_string()),
            blocks,
            index: 0,
            line: 0,
            line_text: String::new(),
            message: None,
            started_block: false,
        };
        Ok(())
    }

    fn hold_program(&self, _caller: &Caller) -> Result<(), BackendError> {
        let mut m = self.lock();
        if m.runner.state != RunState::Running {
            return Err(BackendError::State("no program is running".into()));
        }
        m.runner.state = RunState::Held;
        let ids: Vec<String> = m
            .runner
            .blocks
            .get(m.runner.index)
            .map(|b| b.targets.iter().map(|(i, _)| i.clone()).collect())
            .unwrap_or_default();
        for a in m.axes.iter_mut().filter(|a| ids.contains(&a.view.id)) {
            a.target = None;
        }
        m.runner.started_block = false;
        Ok(())
    }

    fn resume_program(&self, _caller: &Caller) -> Result<(), BackendError> {
        let mut m = self.lock();
        m.ready_for_motion()?;
        if m.runner.state != RunState::Held {
            return Err(BackendError::State("the program is not held".into()));
        }
        m.runner.state = RunState::Running;
        Ok(())
    }

    fn stop_program(&self, _caller: &Caller) -> Result<(), BackendError> {
        let mut m = self.lock();
        if !matches!(m.runner.state, RunState::Running | RunState::Held) {
            return Err(BackendError::State("no program is running".into()));
        }
        m.stop_runner("stopped by the user");
        let ids: Vec<String> = m
            .runner
            .blocks
            .get(m.runner.index)
            .map(|b| b.targets.iter().map(|(i, _)| i.clone()).collect())
            .unwrap_or_default();
        for a in m.axes.iter_mut().filter(|a| ids.contains(&a.view.id)) {
            a.target = None;
        }
        Ok(())
    }

    fn program_status(&self) -> ProgramStatus {
        let m = self.lock();
        ProgramStatus {
            state: m.runner.state,
            program: m.runner.program.clone(),
            progress: m.progress(),
            line: m.runner.line,
            line_text: m.runner.line_text.clone(),
            message: m.runner.message.clone(),
        }
    }

    fn signals(&self) -> Vec<SignalView> {
        self.lock()
            .axes
            .iter()
            .flat_map(|a| {
                [
                    SignalView { id: format!("{}.position", a.view.id), unit: a.view.unit.clone() },
                    SignalView { id: format!("{}.velocity", a.view.id), unit: format!("{}/s", a.view.unit) },
                ]
            })
            .collect()
    }

    fn samples_since(&self, cursor: u64) -> SampleBatch {
        let m = self.lock();
        let samples: Vec<Sample> =
            m.samples.iter().filter(|(s, _)| *s > cursor).map(|(_, s)| s.clone()).collect();
        SampleBatch { cursor: m.seq, samples }
    }

    fn scene(&self) -> SceneView {
        let m = self.lock();
        let p = |id: &str| m.position(id).unwrap_or(0.0);
        SceneView {
            robot: Some(RobotScene {
                pose: [p("robot_x"), p("robot_y"), p("robot_theta")],
                path: m.path.iter().copied().collect(),
                target: m.robot_target,
                bounds: [-2.0, -1.5, 2.0, 1.5],
            }),
            pan_tilt: Some([p("pan"), p("tilt")]),
            arm: Some((vec![p("j1"), p("j2"), p("j3")], vec![0.3, 0.25, 0.15])),
            juggler: Vec::new(),
            gantry: Some(([p("x"), p("y"), p("z")], [0.5, 0.4, 0.1])),
        }
    }

    fn groups(&self) -> Vec<GroupView> {
        let g = |id: &str, kind, axes: &[&str]| GroupView {
            id: id.to_string(),
            kind,
            axes: axes.iter().map(|s| (*s).to_string()).collect(),
            programs: Vec::new(),
            program: None,
        };
        vec![
            g("gantry", GroupKind::Gantry, &["x", "y", "z"]),
            g("robot", GroupKind::Robot, &["robot_x", "robot_y", "robot_theta"]),
            g("pan_tilt", GroupKind::PanTilt, &["pan", "tilt"]),
            g("arm", GroupKind::Arm, &["j1", "j2", "j3"]),
        ]
    }

    fn group_command(&self, caller: &Caller, group: &str, action: GroupAction) -> Result<(), BackendError> {
        let g = self
            .groups()
            .into_iter()
            .find(|g| g.id == group)
            .ok_or_else(|| BackendError::NotFound { kind: "group", id: group.to_string() })?;
        match action {
            GroupAction::Stop => {
                for id in &g.axes {
                    self.command(caller, id, AxisAction::Stop)?;
                }
                Ok(())
            }
            GroupAction::Run { .. } => {
                Err(BackendError::State(format!("group {group} has no programs to run")))
            }
            GroupAction::GoTo { targets } => {
                if targets.len() != g.axes.len() {
                    return Err(BackendError::invalid(
                        "targets",
                        format!("{} targets for {} axes", targets.len(), g.axes.len()),
                    ));
                }
                let mut m = self.lock();
                m.ready_for_motion()?;
                // Validate every member first, so a group never starts half-way.
                for (id, t) in g.axes.iter().zip(&targets) {
                    let a = m.axis_mut(id)?;
                    AxisAction::Move { target: *t, speed: a.view.default_speed, acceleration: None }
                        .validate(&a.view)?;
                }
                for (id, t) in g.axes.iter().zip(&targets) {
                    let a = m.axis_mut(id)?;
                    a.jog = None;
                    a.speed = a.view.default_speed;
                    a.accel = a.view.acceleration;
                    a.target = Some(*t);
                }
                if g.kind == GroupKind::Robot {
                    if let (Some(x), Some(y)) = (targets.first(), targets.get(1)) {
                        m.robot_target = Some([*x, *y]);
                    }
                }
                Ok(())
            }
        }
    }

    fn camera_url(&self) -> Option<String> {
        self.lock().camera_url.clone()
    }

    fn on_slot_end(&self, user: &str) {
        let mut m = self.lock();
        m.programs.retain(|(p, _)| p.owner != user);
        m.stop_runner("slot ended");
        m.runner.program = None;
        m.stop_all();
        m.estop = false;
        if m.safe {
            m.held = false;
            m.diagnosis = None;
        }
        for a in &mut m.axes {
            a.speed = a.view.default_speed;
            a.accel = a.view.acceleration;
            a.target = Some(0.0_f64.clamp(a.view.limits.min, a.view.limits.max));
            a.view.homed = true;
        }
        tracing::info!(user, "slot ended: programs removed, axes homing");
    }
}
