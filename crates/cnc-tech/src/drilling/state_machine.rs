//! The drilling task: its four steps and its state machine (see the module docs of
//! [`crate::drilling`] for the sequence of each job).

use tracing::{debug, info, warn};

use super::types::{
    DrillingCmd, DrillingError, DrillingInfo, DrillingInputs, DrillingOutputs, DrillingPara, ErrorRecord,
    HoleSettings, Job, MSet, State, Technology, M_ACTIVATE_CUTTING, M_ACTIVATE_DRILLING, M_DRILL,
    M_SPINDLE_OFF, M_SPINDLE_ON,
};
use crate::setpoint::{Coupling, ZCommand};
use crate::task::{StateTimer, Task};

/// Z is "at" a target within this distance, mm (the simulated axis stops exactly on
/// its target; a real axis's in-position window belongs in its own task).
const POSITION_TOLERANCE: f64 = 1e-6;
/// The X/Y offset is "at" its target within this distance, mm.
const SHIFT_TOLERANCE: f64 = 1e-6;
/// The spindle is at standstill below this speed, rpm.
const STANDSTILL_RPM: f64 = 0.5;
/// Between pecks, the tool comes back fast to this distance above the depth reached, and
/// chip breaking retracts by it, mm (LinuxCNC's 0.010 inch).
const PECK_CLEARANCE: f64 = 0.254;

/// The drilling technology task.
#[derive(Debug, Clone, Default)]
pub struct DrillingTask {
    cmd: DrillingCmd,
    para: DrillingPara,
    info: DrillingInfo,
    inp: DrillingInputs,
    clock: f64,
    state: State,
    timer: StateTimer,
    /// Time-out of the current state, s (None: none).
    timeout: Option<f64>,
    job: Option<Job>,
    job_m: Option<u16>,
    /// Z where the switch closes over the material.
    z_switch: Option<f64>,
    search_from: f64,
    lift_clearance_set: bool,
    approach_ok: bool,
    hole: Option<HoleSettings>,
    /// Depth reached in the current hole, mm below the surface (pecking).
    drilled: f64,
    shift_target: [f64; 2],
    // outputs
    z_cmd: ZCommand,
    spindle_start: bool,
    spindle_stop: bool,
    rpm: i32,
    clamp: bool,
    coupling: Coupling,
    ack: MSet,
    abort: MSet,
}

fn m_of(job: Job) -> u16 {
    match job {
        Job::Drill => M_DRILL,
        Job::SpindleOn => M_SPINDLE_ON,
        Job::SpindleOff => M_SPINDLE_OFF,
        Job::ActivateDrilling => M_ACTIVATE_DRILLING,
        Job::ActivateCutting => M_ACTIVATE_CUTTING,
        Job::FindWorkingHeight | Job::LiftSpindle | Job::PlateToSwitch => 0,
    }
}

fn job_of_m(n: u16) -> Option<Job> {
    [Job::Drill, Job::SpindleOn, Job::SpindleOff, Job::ActivateDrilling, Job::ActivateCutting]
        .into_iter()
        .find(|&j| m_of(j) == n)
}

impl DrillingTask {
    /// An idle task with these parameters: cutting technology active, working height
    /// unknown.
    pub fn new(para: DrillingPara) -> Self {
        Self {
            para,
            rpm: para.spindle_rpm,
            coupling: Coupling { shift_speed: para.shift_speed, ..Coupling::default() },
            ..Self::default()
        }
    }

    /// The current state.
    pub fn state(&self) -> State {
        self.state
    }

    /// Z where the tool tip touches the material (from the working height).
    fn contact_z(&self, z_sw: f64) -> f64 {
        z_sw - self.para.tool_tip_height
    }
    fn tool_approach_z(&self, z_sw: f64) -> f64 {
        self.contact_z(z_sw) + self.para.tool_approach_height
    }
    fn plate_approach_z(&self, z_sw: f64) -> f64 {
        z_sw + self.para.reference_travel + self.para.plate_approach_height
    }
    fn start_z(&self) -> f64 {
        self.para.upper_limit - self.para.start_position
    }

    fn at(&self, target: f64) -> bool {
        (self.inp.z - target).abs() <= POSITION_TOLERANCE
    }

    /// Commands a Z move and sets the state's time-out from its expected duration.
    fn move_z(&mut self, target: f64, speed: f64) {
        self.z_cmd = ZCommand::Move { target, speed };
        let expected = if speed > 0.0 { (target - self.inp.z).abs() / speed * 60.0 } else { f64::INFINITY };
        self.timeout = Some(expected * 1.5 + self.para.move_timeout_margin);
    }

    fn z_switch(&self) -> f64 {
        self.z_switch.unwrap_or(self.inp.z)
    }

    /// Enters a state and runs its entry actions.
    fn go(&mut self, next: State) {
        if next != self.state {
            debug!(from = %self.state, to = %next, job = ?self.job, "drilling state");
        }
        self.state = next;
        self.timer.restart();
        self.timeout = None;
        let z_sw = self.z_switch();
        let p = self.para;
        match next {
            State::Idle | State::Simulated | State::Error => self.z_cmd = ZCommand::Hold,
            State::SpindleStart => {
                self.spindle_start = true;
                self.timeout = Some(p.spindle_timeout);
            }
            State::SpindleStop => {
                self.spindle_stop = true;
                self.timeout = Some(p.spindle_timeout);
            }
            State::SearchLift => {
                self.lift_clearance_set = false;
                self.move_z(self.start_z(), p.rapid_speed);
            }
            State::SearchDescend => {
                self.search_from = self.inp.z;
                let target = (self.inp.z - p.max_search_travel).max(p.lower_limit);
                self.move_z(target, p.search_speed);
            }
            State::Settle => self.move_z(z_sw, p.search_speed),
            State::PlateApproach => self.move_z(self.plate_approach_z(z_sw), p.rapid_speed),
            State::ToolApproach => {
                self.approach_ok = false;
                self.move_z(self.tool_approach_z(z_sw), p.tool_approach_speed);
            }
            State::Clamp => self.clamp = true,
            State::Unclamp => self.clamp = false,
            State::Drill => {
                let (feed, depth) = self.hole.map_or((p.drilling_speed, p.drilling_depth), |h| {
                    let next = if h.peck > 0.0 { (self.drilled + h.peck).min(h.depth) } else { h.depth };
                    (h.feed, next)
                });
                self.move_z(self.contact_z(z_sw) - depth, feed);
            }
            State::PeckRetract => {
                let chip_break = self.hole.is_some_and(|h| h.chip_break);
                let target =
                    if chip_break { self.inp.z + PECK_CLEARANCE } else { self.tool_approach_z(z_sw) };
                self.move_z(target, p.retract_speed);
            }
            State::PeckReturn => {
                self.move_z(self.contact_z(z_sw) - self.drilled + PECK_CLEARANCE, p.rapid_speed);
            }
            State::Retract => self.move_z(self.tool_approach_z(z_sw), p.retract_speed),
            State::AboveMaterial => self.move_z(self.plate_approach_z(z_sw), p.rapid_speed),
            State::ReturnToStart => self.move_z(self.start_z(), p.rapid_speed),
            State::Decouple => {
                self.coupling = Coupling {
                    coupled: false,
                    offset_target: self.inp.xy_offset,
                    shift_speed: p.shift_speed,
                };
                self.timeout = Some(p.move_timeout_margin);
            }
            State::ShiftMove => {
                self.coupling.offset_target = self.shift_target;
                let ([tx, ty], [ox, oy]) = (self.shift_target, self.inp.xy_offset);
                let [dx, dy] = [tx - ox, ty - oy];
                let expected =
                    if p.shift_speed > 0.0 { dx.hypot(dy) / p.shift_speed * 60.0 } else { f64::INFINITY };
                self.timeout = Some(expected * 1.5 + p.move_timeout_margin);
            }
            State::Recouple => {
                self.coupling.coupled = true;
                self.timeout = Some(p.move_timeout_margin);
            }
            State::Stopping => {
                self.spindle_stop = true;
                self.clamp = false;
                if !self.coupling.coupled {
                    // Recouple where the axes are.
                    self.coupling.coupled = true;
                }
                self.move_z(self.start_z(), p.rapid_speed);
                self.timeout = None;
            }
        }
    }

    /// The job is done: acknowledge its M and go idle.
    fn finish(&mut self) {
        if let Some(m) = self.job_m.take() {
            self.ack.insert(m);
        }
        if self.job == Some(Job::Drill) {
            self.info.holes_done += 1;
        }
        info!(job = ?self.job, "drilling job done");
        self.job = None;
        self.go(State::Idle);
    }

    /// Searching (again): lift first if the switch is closed.
    fn search(&mut self) {
        if self.inp.plate_switch {
            self.go(State::SearchLift);
        } else {
            self.go(State::SearchDescend);
        }
    }

    fn remeasure(&mut self, why: &str) {
        self.info.remeasurements += 1;
        warn!(why, working_height = ?self.z_switch, "working height changed; measuring again");
        self.search();
    }

    fn hole_from_ext(&self) -> Result<HoleSettings, DrillingError> {
        let h = HoleSettings {
            rpm: i32::from(self.inp.ext_spindle_rpm),
            feed: f64::from(self.inp.ext_drilling_speed),
            depth: f64::from(self.inp.ext_drilling_depth),
            peck: f64::from(self.inp.ext_peck_increment),
            chip_break: self.inp.ext_chip_break != 0,
        };
        if !(h.peck.is_finite() && h.peck >= 0.0) {
            return Err(DrillingError::InvalidParameter { name: "EXF63 peck increment", value: h.peck });
        }
        self.check_hole(h, ["EXW60 spindle rpm", "EXF61 drilling speed", "EXF62 drilling depth"])
    }

    fn check_hole(&self, h: HoleSettings, names: [&'static str; 3]) -> Result<HoleSettings, DrillingError> {
        let [n_rpm, n_feed, n_depth] = names;
        if h.rpm <= 0 {
            return Err(DrillingError::InvalidParameter { name: n_rpm, value: f64::from(h.rpm) });
        }
        if !(h.feed.is_finite() && h.feed > 0.0) {
            return Err(DrillingError::InvalidParameter { name: n_feed, value: h.feed });
        }
        if !(h.depth.is_finite() && h.depth > 0.0 && h.depth < self.para.tool_length) {
            return Err(DrillingError::InvalidParameter { name: n_depth, value: h.depth });
        }
        Ok(h)
    }

    /// The geometry must let the plate press the material before the tool reaches it.
    fn check_geometry(&self) -> Result<(), DrillingError> {
        let p = &self.para;
        let bad = |name, value| Err(DrillingError::InvalidParameter { name, value });
        if !(p.tool_tip_height > p.tool_approach_height && p.tool_approach_height >= 0.0) {
            return bad("tool approach height (must be below the tool tip height)", p.tool_approach_height);
        }
        if !(p.height_tolerance >= 0.0 && p.height_tolerance < p.tool_tip_height - p.tool_approach_height) {
            return bad(
                "height tolerance (must be below tool tip height - approach height)",
                p.height_tolerance,
            );
        }
        for (name, v) in [
            ("search speed", p.search_speed),
            ("tool approach speed", p.tool_approach_speed),
            ("retract speed", p.retract_speed),
            ("rapid speed", p.rapid_speed),
            ("max search travel", p.max_search_travel),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(name, v);
            }
        }
        Ok(())
    }

    /// Starts a job from Idle.
    fn start(&mut self, job: Job, m: Option<u16>) -> Result<(), DrillingError> {
        info!(?job, ?m, "drilling job");
        self.job = Some(job);
        self.job_m = m;
        let drilling = self.info.technology == Technology::Drilling;
        let needs_drilling =
            matches!(job, Job::Drill | Job::SpindleOn | Job::FindWorkingHeight | Job::PlateToSwitch);
        if needs_drilling && !drilling {
            return Err(DrillingError::TechnologyNotActive { job });
        }
        let sim = self.para.simulation;
        match job {
            Job::Drill => {
                let hole = if m.is_some() {
                    self.hole_from_ext()?
                } else {
                    let p = self.para;
                    let h = HoleSettings {
                        rpm: p.spindle_rpm,
                        feed: p.drilling_speed,
                        depth: p.drilling_depth,
                        peck: 0.0,
                        chip_break: false,
                    };
                    self.check_hole(h, ["spindle rpm", "drilling speed", "drilling depth"])?
                };
                self.check_geometry()?;
                self.hole = Some(hole);
                self.drilled = 0.0;
                self.info.hole = Some(hole);
                self.rpm = hole.rpm;
                self.go(if sim { State::Simulated } else { State::SpindleStart });
            }
            Job::SpindleOn => {
                let rpm = i32::from(self.inp.ext_spindle_rpm);
                if rpm <= 0 {
                    return Err(DrillingError::InvalidParameter {
                        name: "EXW60 spindle rpm",
                        value: f64::from(rpm),
                    });
                }
                self.rpm = rpm;
                self.go(if sim { State::Simulated } else { State::SpindleStart });
            }
            Job::SpindleOff => self.go(if sim { State::Simulated } else { State::SpindleStop }),
            Job::ActivateDrilling | Job::ActivateCutting => {
                let (target_tech, target) = if job == Job::ActivateDrilling {
                    let [x, y] = self.para.drill_offset;
                    (Technology::Drilling, [-x, -y])
                } else {
                    (Technology::Cutting, [0.0, 0.0])
                };
                self.shift_target = target;
                if self.info.technology == target_tech {
                    self.finish();
                } else if job == Job::ActivateCutting && !sim {
                    self.go(State::SpindleStop);
                } else {
                    self.go(State::Decouple);
                }
            }
            Job::FindWorkingHeight | Job::PlateToSwitch => {
                self.check_geometry()?;
                if sim {
                    self.go(State::Simulated);
                } else {
                    self.search();
                }
            }
            Job::LiftSpindle => self.go(if sim { State::Simulated } else { State::ReturnToStart }),
        }
        Ok(())
    }

    /// Idle: take the next request (program M-functions first, then commands).
    fn idle(&mut self) -> Result<(), DrillingError> {
        // The caller clears acknowledged bits before the next cycle, so a set bit here is
        // a new request.
        let requested = self.inp.m.iter().next();
        if let Some((job, n)) = requested.and_then(|n| job_of_m(n).map(|j| (j, n))) {
            return self.start(job, Some(n));
        }
        let c = &mut self.cmd;
        let job = if c.start_drilling.take() {
            Some(Job::Drill)
        } else if c.find_working_height.take() {
            Some(Job::FindWorkingHeight)
        } else if c.plate_to_switch.take() {
            Some(Job::PlateToSwitch)
        } else if c.lift_spindle.take() {
            Some(Job::LiftSpindle)
        } else {
            None
        };
        match job {
            Some(job) => self.start(job, None),
            None => Ok(()),
        }
    }

    fn drop_busy_commands(&mut self) {
        let c = &mut self.cmd;
        for (name, flag) in [
            ("start_drilling", &mut c.start_drilling),
            ("find_working_height", &mut c.find_working_height),
            ("plate_to_switch", &mut c.plate_to_switch),
            ("lift_spindle", &mut c.lift_spindle),
        ] {
            if flag.take() {
                warn!(command = name, state = %self.state, "command ignored: technology busy");
            }
        }
    }

    /// One step of the state machine in the current state.
    fn during(&mut self) -> Result<(), DrillingError> {
        let inp = self.inp;
        let job = self.job;
        let target = match self.z_cmd {
            ZCommand::Move { target, .. } => target,
            ZCommand::Hold => inp.z,
        };
        let arrived = self.at(target);
        match self.state {
            State::Idle => self.idle()?,
            State::Error => {}
            State::Simulated => {
                if job == Some(Job::Drill) {
                    debug!("simulated hole");
                }
                self.finish();
            }
            State::SpindleStart => {
                let set = f64::from(self.rpm);
                let signed = if self.para.spindle_reverse { -set } else { set };
                if inp.spindle_ready && (inp.spindle_rpm - signed).abs() <= 1.0 {
                    match job {
                        Some(Job::Drill) if self.z_switch.is_some() => self.go(State::PlateApproach),
                        Some(Job::Drill) => self.search(),
                        _ => self.finish(),
                    }
                }
            }
            State::SpindleStop => {
                if inp.spindle_rpm.abs() < STANDSTILL_RPM {
                    if job == Some(Job::ActivateCutting) {
                        self.go(State::ReturnToStart);
                    } else {
                        self.finish();
                    }
                }
            }
            State::SearchLift => {
                if !inp.plate_switch && !self.lift_clearance_set {
                    self.lift_clearance_set = true;
                    let clear = (inp.z + self.para.reference_travel + self.para.plate_approach_height)
                        .min(self.start_z());
                    self.move_z(clear, self.para.rapid_speed);
                } else if arrived && self.lift_clearance_set {
                    self.go(State::SearchDescend);
                } else if arrived {
                    return Err(DrillingError::SwitchStuck { z: inp.z });
                }
            }
            State::SearchDescend => {
                let found = inp.switch_latch.or(inp.plate_switch.then_some(inp.z));
                if let Some(z_sw) = found {
                    info!(z_sw, "working height found");
                    self.z_switch = Some(z_sw);
                    match job {
                        Some(Job::Drill) => self.go(State::ToolApproach),
                        Some(Job::PlateToSwitch) => self.go(State::Settle),
                        _ => self.go(State::AboveMaterial),
                    }
                } else if arrived {
                    return Err(DrillingError::SwitchNotFound { travel: self.search_from - inp.z });
                }
            }
            State::Settle => {
                if arrived {
                    self.finish();
                }
            }
            State::PlateApproach => {
                if inp.plate_switch {
                    self.remeasure("switch closed during the fast plate approach");
                } else if arrived {
                    self.go(State::ToolApproach);
                }
            }
            State::ToolApproach => self.tool_approach(arrived),
            State::Clamp => self.go(State::Drill),
            State::Drill => {
                if arrived {
                    self.drilled = self.contact_z(self.z_switch()) - inp.z;
                    let depth = self.hole.map_or(self.para.drilling_depth, |h| h.depth);
                    if self.drilled < depth - POSITION_TOLERANCE {
                        self.go(State::PeckRetract);
                    } else {
                        self.go(State::Retract);
                    }
                }
            }
            State::PeckRetract => {
                if arrived {
                    self.go(State::PeckReturn);
                }
            }
            State::PeckReturn => {
                if arrived {
                    self.go(State::Drill);
                }
            }
            State::Retract => {
                if arrived {
                    self.go(State::Unclamp);
                }
            }
            State::Unclamp => {
                if self.para.hole_sequence {
                    self.go(State::AboveMaterial);
                } else {
                    self.go(State::ReturnToStart);
                }
            }
            State::AboveMaterial => {
                if arrived {
                    self.finish();
                }
            }
            State::ReturnToStart => {
                if arrived {
                    if job == Some(Job::ActivateCutting) {
                        self.go(State::Decouple);
                    } else {
                        self.finish();
                    }
                }
            }
            State::Decouple => {
                if !inp.xy_coupled {
                    self.go(State::ShiftMove);
                }
            }
            State::ShiftMove => {
                let [tx, ty] = self.shift_target;
                let [ox, oy] = inp.xy_offset;
                if (tx - ox).hypot(ty - oy) <= SHIFT_TOLERANCE {
                    self.go(State::Recouple);
                }
            }
            State::Recouple => {
                if inp.xy_coupled {
                    self.info.technology = if job == Some(Job::ActivateDrilling) {
                        Technology::Drilling
                    } else {
                        Technology::Cutting
                    };
                    self.finish();
                }
            }
            State::Stopping => {
                if inp.spindle_rpm.abs() < STANDSTILL_RPM && arrived {
                    if let Some(m) = self.job_m.take() {
                        warn!(m, "M-function aborted by stop technology");
                        self.abort.insert(m);
                    }
                    self.job = None;
                    self.go(State::Idle);
                }
            }
        }
        Ok(())
    }

    /// Tool approach with the continuous check of the working height: the switch must
    /// close within the tolerance of the known working height, else measure again.
    fn tool_approach(&mut self, arrived: bool) {
        let inp = self.inp;
        let z_sw = self.z_switch();
        let tol = self.para.height_tolerance;
        if !self.approach_ok {
            let closed_at = inp.switch_latch.or(inp.plate_switch.then_some(inp.z));
            match closed_at {
                Some(z) if (z - z_sw).abs() <= tol => self.approach_ok = true,
                Some(_) => return self.remeasure("switch closed out of tolerance"),
                None if inp.z < z_sw - tol => return self.remeasure("switch still open below the tolerance"),
                None => {}
            }
        }
        if arrived && self.approach_ok {
            self.go(State::Clamp);
        }
    }

    fn update_info(&mut self) {
        let searching = matches!(self.state, State::SearchLift | State::SearchDescend);
        let to_switch = self.job == Some(Job::PlateToSwitch);
        let i = &mut self.info;
        i.state = self.state;
        i.job = self.job;
        i.pending_m = self.job_m;
        i.height_search_active = searching && !to_switch;
        i.plate_moving_to_switch = to_switch && (searching || self.state == State::Settle);
        i.drilling_active = self.job == Some(Job::Drill);
        i.technology_active = i.technology == Technology::Drilling;
        i.stopping = self.state == State::Stopping;
        i.zero_point_found = self.z_switch.is_some();
        i.working_height = self.z_switch;
    }
}

impl Task for DrillingTask {
    type Cmd = DrillingCmd;
    type Para = DrillingPara;
    type Info = DrillingInfo;
    type Inputs = DrillingInputs;
    type Outputs = DrillingOutputs;
    type Error = DrillingError;

    fn cmd_mut(&mut self) -> &mut DrillingCmd {
        &mut self.cmd
    }
    fn para(&self) -> &DrillingPara {
        &self.para
    }
    fn para_mut(&mut self) -> &mut DrillingPara {
        &mut self.para
    }
    fn info(&self) -> &DrillingInfo {
        &self.info
    }

    fn read_inputs(&mut self, inputs: &DrillingInputs, dt: f64) {
        self.inp = *inputs;
        self.clock += dt;
        self.timer.advance(dt);
    }

    fn detect_error(&mut self) -> Option<DrillingError> {
        let (state, inp) = (self.state, self.inp);
        if matches!(state, State::Idle | State::Error | State::Stopping) {
            return None;
        }
        if inp.z_limit {
            return Some(DrillingError::ZLimit { z: inp.z, state });
        }
        let in_hole = matches!(
            state,
            State::Clamp | State::Drill | State::PeckRetract | State::PeckReturn | State::Retract
        );
        if in_hole && !inp.spindle_ready {
            return Some(DrillingError::SpindleLost { state });
        }
        let after_s = self.timer.elapsed();
        if self.timeout.is_some_and(|t| after_s > t) {
            let p = &self.para;
            return Some(match state {
                State::SpindleStart => {
                    DrillingError::SpindleNotReady { rpm: self.rpm, timeout_s: p.spindle_timeout }
                }
                State::SpindleStop => DrillingError::SpindleNotStopped { timeout_s: p.spindle_timeout },
                State::Decouple | State::ShiftMove | State::Recouple => {
                    DrillingError::ShiftTimeout { after_s }
                }
                _ => DrillingError::MoveTimeout { state, after_s },
            });
        }
        None
    }

    fn enter_error(&mut self, error: DrillingError) {
        let record = ErrorRecord {
            error,
            state: self.state,
            job: self.job,
            m: self.job_m,
            z: self.inp.z,
            time: self.clock,
        };
        warn!(%error, state = %self.state, job = ?self.job, "drilling technology error");
        self.info.last_error = Some(record);
        self.spindle_stop = true;
        self.spindle_start = false;
        self.go(State::Error);
    }

    fn step(&mut self, _dt: f64) -> Result<(), DrillingError> {
        if self.cmd.stop_technology.take() {
            info!(state = %self.state, "stop technology");
            self.go(State::Stopping);
            return Ok(());
        }
        if self.state != State::Idle {
            self.drop_busy_commands();
        }
        self.during()
    }

    fn write_outputs(&mut self) -> DrillingOutputs {
        self.update_info();
        DrillingOutputs {
            z: self.z_cmd,
            spindle_start: std::mem::take(&mut self.spindle_start),
            spindle_stop: std::mem::take(&mut self.spindle_stop),
            spindle_rpm: self.rpm,
            spindle_reverse: self.para.spindle_reverse,
            clamp: self.clamp,
            coupling: self.coupling,
            acknowledge: std::mem::take(&mut self.ack),
            abort: std::mem::take(&mut self.abort),
        }
    }
}
