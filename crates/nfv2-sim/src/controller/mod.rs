//! One simulated 1209A axis controller: its communication buffer, regulators, inputs and
//! the motor it drives. Sans-IO: time is injected.
//!
//! [`Controller::advance_to`] runs whole **1 ms regulator cycles** up to the `now` it is
//! given; each cycle samples the inputs and the encoder, applies the safety rules, runs
//! the speed and position regulators of the active mode ([`motion`]) and then **20
//! current-loop substeps of 50 µs** (20 kHz) that drive the motor model. At the end of the
//! cycle the values a query reads are published (like the firmware's `MOTOR_Proc`
//! refreshing its communication buffer), so an answer reports the last cycle.
//! [`Controller::handle`] advances first, applies the frame's set-points (they take
//! effect at the next cycle) and answers its queries ([`commands`]).
//!
//! Safety rules, every cycle:
//! - ENABLE absent: the bridge is off from the next substep on, the mode becomes ERROR and
//!   stays ERROR while ENABLE is absent (`SetDrivesMode` is ignored meanwhile).
//! - A limit switch closing (rising edge): mode ERROR. Setting a mode again leaves ERROR;
//!   while a switch stays closed, motion towards it is blocked in every mode.
//! - Over-current (beyond `overcurrent_trip_ma`): bridge off at once, status bit 13
//!   latched, mode ERROR until the next `SetDrivesMode`.
//! - No power-stage supply: bridge off, status bit 9; everything else keeps working.
//!
//! The true state of every cycle can be kept ([`Controller::trace_truth`]): whoever
//! advances the controller (a serve loop, an in-process link running ahead to a request's
//! arrival, a test), no cycle is missed.

use std::collections::VecDeque;
use std::time::Duration;

use motus_axis::profile::Plan;
use motus_nfv2_protocol::{AddressPlan, DriveMode, Regulator, Revision};
use rand::rngs::SmallRng;
use rand::SeedableRng;

use crate::config::ControllerConfig;
use crate::error::SimError;
use crate::inputs::{Inputs, LimitSwitch, Sensed};
use crate::motor::Motor;
use crate::regulator::Pid;

mod commands;
mod hooks;
mod motion;
mod publish;

pub use publish::TrueState;

/// Regulator period (speed and position loops, trajectory generator): 1 kHz.
pub const REGULATOR_PERIOD: Duration = Duration::from_millis(1);
/// Current-loop substeps per regulator period (20 kHz).
pub const CURRENT_LOOP_SUBSTEPS: u32 = 20;

/// The communication buffer's set-points (what the host last wrote).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SetPoints {
    pub(crate) mode: DriveMode,
    pub(crate) speed: i64,
    pub(crate) current_ma: i64,
    pub(crate) position: i64,
    pub(crate) pwm: i64,
    pub(crate) max_current_ma: i64,
    pub(crate) max_speed: i64,
    pub(crate) min_position: i64,
    pub(crate) max_position: i64,
    pub(crate) max_acceleration: i64,
}

/// Conditions shown by the status bits, refreshed every cycle (except the latches).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct Flags {
    pub(crate) synchronized: bool,
    pub(crate) position_limit: bool,
    pub(crate) speed_limit: bool,
    pub(crate) current_limit: bool,
    pub(crate) following_error: bool,
    /// The command watchdog zeroed a set-point (cleared by the next motion command).
    pub(crate) watchdog: bool,
    /// Latched until the next `SetDrivesMode`.
    pub(crate) overcurrent: bool,
}

/// What the regulators ask of the power stage for one cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Demand {
    /// Bridge off.
    Off,
    /// A PWM duty, -1..=1 (PWM and MANUAL modes; zero duty switches the bridge off).
    Duty(f64),
    /// A current reference for the 20 kHz current loop, A.
    Current(f64),
}

/// The trajectory generator's state (counter coordinates).
#[derive(Debug, Clone)]
pub(crate) struct Trajectory {
    /// Position reference, counts.
    pub(crate) p_ref: f64,
    /// Speed reference, counts/s.
    pub(crate) v_ref: f64,
    /// The planned move of POSITION mode (or the stop after homing) and its progress.
    pub(crate) plan: Option<ActivePlan>,
    /// Homing progress.
    pub(crate) homing: Homing,
}

/// A planned move being followed.
#[derive(Debug, Clone)]
pub(crate) struct ActivePlan {
    pub(crate) plan: Plan,
    /// Cycles since the plan started.
    pub(crate) cycles: u64,
    /// What it was planned for: target, speed and acceleration.
    pub(crate) key: (i64, i64, i64),
}

/// Homing (CALIBRATION) phases.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Homing {
    /// Moving in this direction (+1 / -1) at the homing speed, looking for the edge.
    Seek(i8),
    /// The edge was found: holding position.
    Done,
}

/// One simulated 1209A controller with its motor and axis.
#[derive(Debug, Clone)]
pub struct Controller {
    address: u8,
    plan: AddressPlan,
    revision: Revision,
    config: ControllerConfig,
    time: Duration,
    cycles: u64,
    motor: Motor,
    inputs: Inputs,
    sensed: Sensed,
    set: SetPoints,
    active_mode: DriveMode,
    current_pid: Pid,
    speed_pid: Pid,
    position_pid: Pid,
    counter_offset: i64,
    counter: i64,
    /// Counter values of the last cycles, newest first (speed measurement window).
    history: [i64; SPEED_WINDOW + 1],
    measured_speed: f64,
    trajectory: Trajectory,
    flags: Flags,
    demand: Demand,
    current_ref_a: f64,
    bridge_on: bool,
    last_motion_command: Duration,
    temperature_c: f64,
    rng: SmallRng,
    published: publish::Published,
    /// The true states kept, one per cycle ([`Controller::trace_truth`]).
    truth_trace: Option<TruthTrace>,
}

/// The true states of the last cycles, at most `capacity`.
#[derive(Debug, Clone)]
struct TruthTrace {
    capacity: usize,
    states: VecDeque<TrueState>,
}

/// Cycles over which the speed is measured from the encoder counter.
pub(crate) const SPEED_WINDOW: usize = 4;

impl Controller {
    /// Powers on a controller at `address` with the seed's address plan (0 = gateway) and
    /// the latest protocol revision.
    ///
    /// # Errors
    /// [`SimError::Config`] if `config` does not validate.
    pub fn new(address: u8, config: &ControllerConfig) -> Result<Controller, SimError> {
        Self::with_protocol(address, AddressPlan::default(), Revision::LATEST, config)
    }

    /// Powers on a controller at `address`, interpreting frame addresses with `plan` and
    /// value widths and mode numbers with `revision`.
    ///
    /// # Errors
    /// [`SimError::Config`] if `config` does not validate.
    pub fn with_protocol(
        address: u8,
        plan: AddressPlan,
        revision: Revision,
        config: &ControllerConfig,
    ) -> Result<Controller, SimError> {
        config.validate()?;
        let motor = Motor::new(config.motor, config.initial_position_counts);
        let counter = motor.counts().floor() as i64;
        let inputs = Inputs::new(config);
        let sensed =
            inputs.sense(motor.counts(), config.motor.encoder_counts_per_rev, config.power_stage_low_v);
        let seed = config.seed ^ (u64::from(address) << 32) ^ 0x1209_a000;
        let mut c = Controller {
            address,
            plan,
            revision,
            time: Duration::ZERO,
            cycles: 0,
            motor,
            inputs,
            sensed,
            set: SetPoints {
                // Power-on: mode 0 (ERROR) until the host chooses one, as the reference's
                // zeroed communication buffer.
                mode: DriveMode::Error,
                speed: 0,
                current_ma: 0,
                position: 0,
                pwm: 0,
                max_current_ma: config.max_current_ma,
                max_speed: config.max_speed,
                min_position: 0,
                max_position: 0,
                max_acceleration: config.max_acceleration,
            },
            active_mode: DriveMode::Error,
            current_pid: Pid::new(config.current_regulator),
            speed_pid: Pid::new(config.speed_regulator),
            position_pid: Pid::new(config.position_regulator),
            counter_offset: 0,
            counter,
            history: [counter; SPEED_WINDOW + 1],
            measured_speed: 0.0,
            trajectory: Trajectory { p_ref: counter as f64, v_ref: 0.0, plan: None, homing: Homing::Done },
            flags: Flags::default(),
            demand: Demand::Off,
            current_ref_a: 0.0,
            bridge_on: false,
            last_motion_command: Duration::ZERO,
            temperature_c: config.ambient_c,
            rng: SmallRng::seed_from_u64(seed),
            published: publish::Published::default(),
            truth_trace: None,
            config: config.clone(),
        };
        c.publish();
        Ok(c)
    }

    /// The controller's bus address (its DIP switch).
    #[must_use]
    pub fn address(&self) -> u8 {
        self.address
    }

    /// How frame addresses are interpreted (gateway, broadcast).
    #[must_use]
    pub fn address_plan(&self) -> AddressPlan {
        self.plan
    }

    /// The protocol revision (value widths, mode numbers).
    #[must_use]
    pub fn revision(&self) -> Revision {
        self.revision
    }

    /// The configuration it was powered on with.
    #[must_use]
    pub fn config(&self) -> &ControllerConfig {
        &self.config
    }

    /// The regulator gains in use: current, speed, position.
    #[must_use]
    pub fn regulators(&self) -> [Regulator; 3] {
        [self.current_pid.gains(), self.speed_pid.gains(), self.position_pid.gains()]
    }

    /// Simulated time of the last completed regulator cycle.
    #[must_use]
    pub fn now(&self) -> Duration {
        self.time
    }

    /// Runs whole regulator cycles up to `now` (a `now` in the past does nothing).
    pub fn advance_to(&mut self, now: Duration) {
        while self.time + REGULATOR_PERIOD <= now {
            self.cycle();
        }
    }

    /// One regulator cycle.
    fn cycle(&mut self) {
        let cpr = self.config.motor.encoder_counts_per_rev;
        let previous = self.sensed;
        self.sensed = self.inputs.sense(self.motor.counts(), cpr, self.config.power_stage_low_v);
        self.measure();
        self.safety(previous);
        let mode = self.set.mode;
        if mode != self.active_mode {
            self.enter(mode);
        }
        self.watchdog();
        self.demand = self.regulate();
        self.power_stage();
        self.thermal();
        self.cycles += 1;
        self.time += REGULATOR_PERIOD;
        self.publish();
        if self.truth_trace.is_some() {
            let state = self.true_state();
            if let Some(trace) = &mut self.truth_trace {
                if trace.states.len() >= trace.capacity {
                    trace.states.pop_front();
                }
                trace.states.push_back(state);
            }
        }
    }

    /// Reads the encoder counter and measures the speed over the last cycles.
    fn measure(&mut self) {
        self.counter = self.motor.counts().floor() as i64 + self.counter_offset;
        self.history.rotate_right(1);
        if let Some(newest) = self.history.first_mut() {
            *newest = self.counter;
        }
        let oldest = self.history.last().copied().unwrap_or(self.counter);
        // counts per cycle x 100 = speed units; averaged over the window.
        self.measured_speed = (self.counter - oldest) as f64 * 100.0 / SPEED_WINDOW as f64;
    }

    /// ENABLE, limit switch edges and the over-current latch force ERROR.
    fn safety(&mut self, previous: Sensed) {
        let s = self.sensed;
        if !s.enable && self.set.mode != DriveMode::Error {
            tracing::info!(address = self.address, "ENABLE removed: drive stopped, mode ERROR");
            self.set.mode = DriveMode::Error;
        }
        let up_edge = s.limit_up && !previous.limit_up;
        let down_edge = s.limit_down && !previous.limit_down;
        if (up_edge || down_edge) && self.set.mode != DriveMode::Error {
            tracing::info!(
                address = self.address,
                up = up_edge,
                down = down_edge,
                "limit switch closed: mode ERROR"
            );
            self.set.mode = DriveMode::Error;
        }
        if self.flags.overcurrent {
            self.set.mode = DriveMode::Error;
        }
    }

    /// Mode change: regulators not used by the previous mode start afresh, the trajectory
    /// starts from where the axis is.
    fn enter(&mut self, mode: DriveMode) {
        let before = motion::Family::of(self.active_mode);
        let after = motion::Family::of(mode);
        if !before.uses_speed_loop() || !after.uses_speed_loop() {
            self.speed_pid.reset();
            self.position_pid.reset();
        }
        if !before.uses_current_loop() {
            self.current_pid.reset();
        }
        let t = &mut self.trajectory;
        t.p_ref = self.counter as f64;
        t.v_ref = self.measured_speed * crate::config::COUNTS_PER_S_PER_SPEED_UNIT;
        t.plan = None;
        if after == motion::Family::Homing {
            self.flags.synchronized = false;
            t.homing = Homing::Seek(if self.sensed.home { 1 } else { -1 });
        }
        tracing::debug!(address = self.address, from = ?self.active_mode, to = ?mode, "mode change");
        self.active_mode = mode;
    }

    /// The reference firmware's command watchdog: in a mode driven by a continuous
    /// set-point, no motion command for `command_watchdog_ms` zeroes that set-point.
    fn watchdog(&mut self) {
        let Some(ms) = self.config.command_watchdog_ms else { return };
        if self.time.saturating_sub(self.last_motion_command) < Duration::from_millis(ms) {
            return;
        }
        let zeroed = match self.active_mode {
            DriveMode::Speed | DriveMode::PosIncrement => std::mem::take(&mut self.set.speed) != 0,
            DriveMode::Pwm => std::mem::take(&mut self.set.pwm) != 0,
            DriveMode::Current => std::mem::take(&mut self.set.current_ma) != 0,
            _ => false,
        };
        if zeroed {
            tracing::info!(address = self.address, "command watchdog: set-point zeroed");
            self.flags.watchdog = true;
        }
    }

    /// Power-stage losses heat the heat sink (first order towards ambient + R_th x P).
    fn thermal(&mut self) {
        let i = self.motor.current();
        let on = self.sensed.power_ok && self.demand != Demand::Off;
        let loss_w = 0.05 * i * i + if on { 0.5 } else { 0.0 };
        let c = &self.config;
        let target = c.ambient_c + c.thermal_resistance_k_per_w * loss_w;
        let dt = REGULATOR_PERIOD.as_secs_f64();
        self.temperature_c += (target - self.temperature_c) * dt / c.thermal_time_constant_s;
    }

    /// The position limits if active (the reference disables them when min == max; we also
    /// treat min > max as disabled).
    pub(crate) fn position_limits(&self) -> Option<(i64, i64)> {
        (self.set.min_position < self.set.max_position)
            .then_some((self.set.min_position, self.set.max_position))
    }

    /// Whether `switch` is closed in the last cycle.
    #[must_use]
    pub fn limit_switch(&self, switch: LimitSwitch) -> bool {
        match switch {
            LimitSwitch::Up => self.sensed.limit_up,
            LimitSwitch::Down => self.sensed.limit_down,
        }
    }
}
