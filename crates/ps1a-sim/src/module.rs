//! One simulated PS1A module: EEPROM parameters, status bits, the DDA and homing.
//!
//! Choices where the source is silent (documented in `docs/decisions.md`):
//! * The acceleration number is the speed change per DDA cycle (see
//!   `motus_ps1a_protocol::units`).
//! * After reset the speed and acceleration of later moves are VNRB/ANRB until a
//!   command 3 sets them.
//! * Command 10 runs the whole homing (reference switch on the minus side, then the
//!   encoder zero pulse, which zeroes the counter); command 2 with D2 / D3 runs one
//!   stage each. LBS bit 0 (after reset) is cleared when the zero pulse is reached.
//! * Motion commands are refused with LBS bit 4 while the EEPROM holds no parameter set
//!   (factory state); a speed of 0 starts no motion.
//! * Stop (9) stops any motion, not only a jog. Switching the power stage off aborts motion.

use crate::machine::MachineConfig;
use motus_axis::profile::Plan;
use motus_ps1a_protocol::units::{acceleration_units_per_s2, velocity_units_per_s};
use motus_ps1a_protocol::{Acceleration, Command, HighStatus, LowStatus, Parameters, StatusReply, U24};
use std::time::Duration;

/// What the running motion is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Purpose {
    Move,
    Jog,
    /// Homing: leave the reference switch upwards first.
    LeaveSwitch,
    /// Homing: search the reference switch downwards.
    SeekSwitch,
    /// Homing: search the zero pulse upwards.
    SeekZero,
}

#[derive(Debug, Clone)]
struct Motion {
    plan: Plan,
    t: f64,
    purpose: Purpose,
    /// The plan is the stop after the purpose's event; what to do when at rest.
    stopping: bool,
    then_zero: bool,
}

/// One simulated module.
#[derive(Debug, Clone)]
pub struct Module {
    params: Parameters,
    programmed: bool,
    machine: MachineConfig,
    /// Power-on time and cycles run since.
    epoch: Duration,
    cycles: u64,
    commanded: f64,
    commanded_velocity: f64,
    actual: f64,
    counter_zero: f64,
    speed: u16,
    accel: Acceleration,
    power_stage: bool,
    interpolation_blocking: bool,
    low: u8,
    high: u8,
    motion: Option<Motion>,
    limit_pressed: (bool, bool),
    eeprom_dirty: bool,
    last_move: (f64, f64),
}

impl Module {
    /// Powers a module on at time `now`, with EEPROM contents `params` (`programmed` =
    /// a parameter set was ever stored) and the machine at `machine_position`.
    pub fn power_on(
        params: Parameters,
        programmed: bool,
        machine: MachineConfig,
        machine_position: f64,
        now: Duration,
    ) -> Module {
        let mut m = Module {
            params,
            programmed,
            machine,
            epoch: now,
            cycles: 0,
            commanded: machine_position,
            commanded_velocity: 0.0,
            actual: machine_position,
            counter_zero: machine_position,
            speed: params.vnrb.into(),
            accel: params.anrb,
            power_stage: false,
            interpolation_blocking: false,
            low: LowStatus::AFTER_RESET,
            high: 0,
            motion: None,
            limit_pressed: (false, false),
            eeprom_dirty: false,
            last_move: (machine_position, machine_position),
        };
        m.limit_pressed = m.limits_at(m.actual);
        m
    }

    /// The module's current address (from its parameters).
    pub fn address(&self) -> u8 {
        self.params.address
    }

    /// The parameters in EEPROM.
    pub fn parameters(&self) -> Parameters {
        self.params
    }

    /// True if a parameter set was ever stored.
    pub fn programmed(&self) -> bool {
        self.programmed
    }

    /// The machine position (for persistence and tests).
    pub fn machine_position(&self) -> f64 {
        self.actual
    }

    /// The DDA's commanded position in counter units (not rounded).
    pub fn commanded_position(&self) -> f64 {
        self.commanded - self.counter_zero
    }

    /// The actual position in counter units (not rounded).
    pub fn actual_position(&self) -> f64 {
        self.actual - self.counter_zero
    }

    /// True while any motion runs.
    pub fn in_motion(&self) -> bool {
        self.motion.is_some()
    }

    /// True if the power stage output OSON is on.
    pub fn power_stage(&self) -> bool {
        self.power_stage
    }

    /// Takes the "EEPROM was written" flag (the line persists the state file).
    pub fn take_eeprom_dirty(&mut self) -> bool {
        std::mem::take(&mut self.eeprom_dirty)
    }

    /// The DDA cycle in seconds.
    pub fn cycle_seconds(&self) -> f64 {
        self.params.tvz.seconds()
    }

    /// Raises the encoder-error condition (fault injection): power stage off, motion aborted.
    pub fn inject_encoder_error(&mut self) {
        self.low |= LowStatus::ENCODER_ERROR;
        self.emergency();
    }

    /// Moves the machine by `delta` units without the DDA (e.g. pushed by hand).
    pub fn push_machine(&mut self, delta: f64) {
        self.actual += delta;
        if self.motion.is_none() {
            self.commanded = self.actual;
        }
    }

    /// Runs whole DDA cycles up to `now`.
    pub fn advance_to(&mut self, now: Duration) {
        let period = self.params.tvz.period().as_nanos().max(1);
        let elapsed = now.saturating_sub(self.epoch).as_nanos();
        let due = u64::try_from(elapsed / period).unwrap_or(u64::MAX);
        // Idle modules catch up in one jump: nothing moves.
        if self.motion.is_none() && (self.commanded - self.actual).abs() < 1e-9 {
            self.cycles = due;
            return;
        }
        while self.cycles < due {
            self.step();
        }
    }

    /// Runs exactly one DDA cycle.
    pub fn step(&mut self) {
        self.cycles += 1;
        let dt = self.cycle_seconds();
        if let Some(mut motion) = self.motion.take() {
            let blocked = self.interpolation_blocking && (self.commanded - self.actual).abs() > 1024.0;
            if !blocked {
                motion.t += dt;
            }
            let (p, v) = motion.plan.sample(motion.t);
            self.commanded = p;
            self.commanded_velocity = v;
            self.motion = Some(motion);
        }
        self.servo(dt);
        self.check_limits();
        self.check_following_error();
        self.homing_events();
        self.finish_motion();
    }

    fn servo(&mut self, dt: f64) {
        let before = self.actual;
        if self.power_stage {
            let alpha = 1.0 - (-self.machine.kv * dt).exp();
            self.actual += (self.commanded - self.actual) * alpha;
            if self.motion.is_none() && (self.commanded - self.actual).abs() < 0.5 {
                self.actual = self.commanded;
            }
        }
        self.last_move = (before, self.actual);
    }

    fn limits_at(&self, x: f64) -> (bool, bool) {
        (x <= self.machine.limit_negative, x >= self.machine.limit_positive)
    }

    fn check_limits(&mut self) {
        let (neg, pos) = self.limits_at(self.actual);
        let (was_neg, was_pos) = self.limit_pressed;
        let v = self.commanded_velocity;
        let hit = (neg && (!was_neg || v < 0.0)) || (pos && (!was_pos || v > 0.0));
        self.limit_pressed = (neg, pos);
        if hit && (self.power_stage || self.motion.is_some()) {
            tracing::info!(
                addr = self.params.address,
                position = self.actual,
                "limit switch crossed: power stage off"
            );
            self.low |= LowStatus::LIMIT_SWITCH;
            self.emergency();
        }
    }

    fn check_following_error(&mut self) {
        if self.motion.is_some() && (self.commanded - self.actual).abs() > self.machine.following_error_limit
        {
            self.low |= LowStatus::FOLLOWING_ERROR;
            self.abort_motion();
        }
    }

    fn homing_events(&mut self) {
        let Some(motion) = &self.motion else { return };
        if motion.stopping {
            return;
        }
        let (before, after) = self.last_move;
        match motion.purpose {
            Purpose::LeaveSwitch if !self.machine.reference_pressed(self.actual) => self.stop_for_event(),
            Purpose::SeekSwitch if self.machine.reference_pressed(self.actual) => {
                self.high |= HighStatus::REFERENCE_SWITCH;
                self.stop_for_event();
            }
            Purpose::SeekZero => {
                if let Some(x) = self.machine.zero_pulse_between(before, after) {
                    self.counter_zero = x;
                    self.high |= HighStatus::ENCODER_ZERO;
                    self.low &= !LowStatus::AFTER_RESET;
                    self.stop_for_event();
                }
            }
            _ => {}
        }
    }

    fn stop_for_event(&mut self) {
        let Some(purpose) = self.motion.as_ref().map(|m| m.purpose) else { return };
        let acc = self.current_accel(purpose);
        if let Some(m) = &mut self.motion {
            m.plan = Plan::stop(self.commanded, self.commanded_velocity, acc);
            m.t = 0.0;
            m.stopping = true;
        }
    }

    fn finish_motion(&mut self) {
        let Some(m) = &self.motion else { return };
        if m.t < m.plan.duration() {
            return;
        }
        let (purpose, stopping, then_zero) = (m.purpose, m.stopping, m.then_zero);
        self.commanded_velocity = 0.0;
        match (purpose, stopping) {
            (Purpose::LeaveSwitch, true) => self.start(Purpose::SeekSwitch, then_zero),
            (Purpose::SeekSwitch, true) if then_zero => self.start(Purpose::SeekZero, false),
            _ => {
                // Motion ends when the servo has settled on the DDA's end point.
                if (self.commanded - self.actual).abs() < 0.5 || !self.power_stage {
                    if self.power_stage {
                        self.actual = self.commanded;
                    }
                    self.motion = None;
                }
            }
        }
    }

    fn current_accel(&self, purpose: Purpose) -> f64 {
        let a = match purpose {
            Purpose::Move | Purpose::Jog => self.accel,
            Purpose::LeaveSwitch | Purpose::SeekSwitch => self.params.anrb,
            Purpose::SeekZero => self.params.annb,
        };
        acceleration_units_per_s2(a, self.params.ds, self.params.tvz)
    }

    fn speed_of(&self, purpose: Purpose) -> f64 {
        let v = match purpose {
            Purpose::Move | Purpose::Jog => self.speed,
            Purpose::LeaveSwitch | Purpose::SeekSwitch => self.params.vnrb.into(),
            Purpose::SeekZero => self.params.vnnb.into(),
        };
        velocity_units_per_s(v, self.params.ds, self.params.tvz)
    }

    /// Starts a homing stage (searching far in its direction until the event).
    fn start(&mut self, purpose: Purpose, then_zero: bool) {
        let far = 1.0e12;
        let target = match purpose {
            Purpose::LeaveSwitch | Purpose::SeekZero => self.commanded + far,
            _ => self.commanded - far,
        };
        self.plan_to(target, purpose);
        if let Some(m) = &mut self.motion {
            m.then_zero = then_zero;
        }
    }

    fn plan_to(&mut self, machine_target: f64, purpose: Purpose) {
        let plan = Plan::to_target(
            self.commanded,
            self.commanded_velocity,
            machine_target,
            self.speed_of(purpose),
            self.current_accel(purpose),
        );
        self.motion = Some(Motion { plan, t: 0.0, purpose, stopping: false, then_zero: false });
    }

    fn abort_motion(&mut self) {
        self.motion = None;
        self.commanded = self.actual;
        self.commanded_velocity = 0.0;
    }

    fn emergency(&mut self) {
        self.power_stage = false;
        self.abort_motion();
    }

    fn start_homing(&mut self, reference: bool, zero: bool) {
        self.high = 0;
        if reference {
            let first = if self.machine.reference_pressed(self.actual) {
                Purpose::LeaveSwitch
            } else {
                Purpose::SeekSwitch
            };
            self.start(first, zero);
        } else if zero {
            self.start(Purpose::SeekZero, false);
        }
    }

    fn max_position(&self) -> f64 {
        f64::from(self.params.max_position.get())
    }

    /// Handles a command addressed to this module at time `now` and returns the reply
    /// (reporting clears the clear-after-report bits).
    /// The reply comes from the address that received the command: a new address set by
    /// command 1 applies from the next command on.
    pub fn handle(&mut self, command: &Command, now: Duration) -> StatusReply {
        let addr = self.params.address;
        self.advance_to(now);
        self.execute(command, now);
        StatusReply { addr, ..self.report() }
    }

    /// Answers a command whose checksum was wrong: LBS bit 1, nothing executed.
    pub fn checksum_error(&mut self, now: Duration) -> StatusReply {
        self.advance_to(now);
        self.low |= LowStatus::CHECKSUM_ERROR;
        self.report()
    }

    fn motion_allowed(&mut self) -> bool {
        if !self.programmed {
            self.low |= LowStatus::NO_PARAMETERS;
            return false;
        }
        true
    }

    fn execute(&mut self, command: &Command, now: Duration) {
        match *command {
            Command::StatusRequest => {}
            Command::SetParameters { parameters } => {
                self.params = parameters;
                self.programmed = true;
                self.eeprom_dirty = true;
                self.low &= !LowStatus::NO_PARAMETERS;
            }
            Command::ControlByte { control } => {
                self.interpolation_blocking = control.interpolation_blocking();
                if !control.power_stage() && self.power_stage {
                    self.abort_motion();
                }
                self.power_stage = control.power_stage();
                let homing = control.reference_approach() || control.encoder_zero_approach();
                if homing && self.motion_allowed() {
                    self.start_homing(control.reference_approach(), control.encoder_zero_approach());
                }
            }
            Command::SetSpeed { speed, acceleration } => {
                self.speed = speed;
                self.accel = acceleration;
            }
            Command::MoveAbsolute { target } => self.move_to(f64::from(target.get())),
            Command::MoveRelative { increment } => {
                let base = match &self.motion {
                    Some(m) if m.purpose == Purpose::Move => m.plan.target() - self.counter_zero,
                    _ => self.actual_position().round(),
                };
                self.move_to(base + f64::from(increment.get()));
            }
            Command::JogPlus | Command::JogMinus => {
                if self.motion_allowed() && self.speed > 0 {
                    let target = if matches!(command, Command::JogPlus) { self.max_position() } else { 0.0 };
                    let pos = self.commanded_position();
                    let towards =
                        if matches!(command, Command::JogPlus) { target > pos } else { target < pos };
                    if towards {
                        self.plan_to(target + self.counter_zero, Purpose::Jog);
                    }
                }
            }
            Command::Reset => {
                let (params, programmed, machine, x) =
                    (self.params, self.programmed, self.machine, self.actual);
                *self = Module::power_on(params, programmed, machine, x, now);
            }
            Command::Stop => {
                if let Some(m) = &mut self.motion {
                    let acc = match m.purpose {
                        Purpose::Move | Purpose::Jog => {
                            acceleration_units_per_s2(self.accel, self.params.ds, self.params.tvz)
                        }
                        _ => acceleration_units_per_s2(self.params.anrb, self.params.ds, self.params.tvz),
                    };
                    m.plan = Plan::stop(self.commanded, self.commanded_velocity, acc);
                    m.t = 0.0;
                    m.purpose = Purpose::Move;
                    m.stopping = true;
                }
            }
            Command::Home => {
                if self.motion_allowed() {
                    self.start_homing(true, true);
                }
            }
        }
    }

    fn move_to(&mut self, target: f64) {
        if !self.motion_allowed() {
            return;
        }
        if target < 0.0 || target > self.max_position() {
            self.low |= LowStatus::BEYOND_MAX_POSITION;
            return;
        }
        self.low &= !LowStatus::BEYOND_MAX_POSITION;
        if self.speed == 0 {
            return;
        }
        self.plan_to(target + self.counter_zero, Purpose::Move);
    }

    /// The status reply; clear-after-report bits are cleared.
    pub fn report(&mut self) -> StatusReply {
        let mut low = self.low;
        if self.motion.is_some() {
            low |= LowStatus::IN_MOTION;
        }
        self.low &= !LowStatus::CLEARED_AFTER_REPORT;
        StatusReply {
            addr: self.params.address,
            low: LowStatus(low),
            high: HighStatus(self.high),
            position: U24::wrapping(self.actual_position().round() as i64),
        }
    }
}
