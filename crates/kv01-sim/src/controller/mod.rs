//! The Faulhaber motion controller behind a module (`specs/faulhaber.md`): it parses the
//! text the module forwards (node prefix, case and spaces as §1.5 says), executes it, and
//! answers like a controller: `OK` only in answer mode 2, a value for every query, an error
//! string for a bad command. It also computes the speed demand each step: the `V` target or
//! the positioning loop (`LA`/`LR`/`M`), through the `AC`/`DEC` ramp, and runs the
//! limit-switch program (`ENPROG`/`DIPROG`) that zeroes the speed while the switch is pressed.
//!
//! Assumptions (the spec's \[U\] facts, decided here): errors are only reported in answer
//! mode 2 (a module then gets no answer and replies "TIMEOUT"); a node prefix other than
//! the controller's own number gets no answer; `EN`/`DI` reset the speed target to 0;
//! `SP` limits `V` too; `NP`/`NV` are accepted but never notify (the module could not
//! forward an asynchronous answer); `U` (voltage mode) is "Command not available"; `BAUD`
//! answers at the old rate, after which the module (fixed at its own rate) cannot reach
//! the controller until a power cycle.

mod commands;
mod query;

use crate::config::ControllerConfig;

/// Default position range limit (increments).
const POSITION_RANGE: i32 = 1_800_000_000;
/// Largest current setting, mA.
const MAX_CURRENT_MA: i32 = 12_000;
/// Largest acceleration / deceleration setting, rev/s².
const MAX_ACCELERATION: i32 = 30_000;

/// The settings `SAVE` stores and a power-on restores.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Settings {
    answer_mode: u8,
    max_speed: i32,
    acceleration: i32,
    deceleration: i32,
    peak_current: i32,
    continuous_current: i32,
    upper_limit: i32,
    lower_limit: i32,
    limits_active: bool,
    velocity_source: i32,
    node: u8,
    baud: u32,
    program_enabled: bool,
}

impl Settings {
    fn from_config(c: &ControllerConfig) -> Self {
        Self {
            answer_mode: c.answer_mode.min(2),
            max_speed: c.max_speed_rpm.clamp(0, c.rpm_range.max(0)),
            acceleration: c.acceleration.clamp(1, MAX_ACCELERATION),
            deceleration: c.deceleration.clamp(1, MAX_ACCELERATION),
            peak_current: c.peak_current_ma.clamp(0, MAX_CURRENT_MA),
            continuous_current: c.continuous_current_ma.clamp(0, MAX_CURRENT_MA),
            upper_limit: POSITION_RANGE,
            lower_limit: -POSITION_RANGE,
            limits_active: false,
            velocity_source: 0,
            node: c.node,
            baud: c.baud,
            program_enabled: c.program_enabled,
        }
    }
}

/// Velocity or positioning mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Velocity,
    Position,
}

/// What the controller sees of its motor at the time of a command or step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Drive {
    /// Motor encoder position, increments (before `HO`).
    pub(crate) counts: f64,
    /// Motor speed, rpm.
    pub(crate) rpm: f64,
    /// Motor current, mA.
    pub(crate) current_ma: f64,
    /// The limit switch input is high.
    pub(crate) switch: bool,
}

/// One simulated Faulhaber controller.
#[derive(Debug, Clone)]
pub(crate) struct Controller {
    settings: Settings,
    saved: Settings,
    rpm_range: i32,
    corridor: i64,
    version: String,
    type_name: String,
    serial: u32,
    /// Positioning loop gain, rpm per increment of error.
    position_gain: f64,
    enabled: bool,
    mode: Mode,
    target_rpm: i32,
    ramp_rpm: f64,
    loaded: i64,
    target_position: i64,
    home_offset: f64,
    program_running: bool,
}

impl Controller {
    /// A controller at its first power-on (settings from the configuration).
    pub(crate) fn new(config: &ControllerConfig, position_gain: f64, serial: u32) -> Self {
        let settings = Settings::from_config(config);
        let mut c = Self {
            saved: settings.clone(),
            settings,
            rpm_range: config.rpm_range.max(0),
            corridor: i64::from(config.corridor.max(0)),
            version: config.version.clone(),
            type_name: config.type_name.clone(),
            serial,
            position_gain,
            enabled: false,
            mode: Mode::Velocity,
            target_rpm: 0,
            ramp_rpm: 0.0,
            loaded: 0,
            target_position: 0,
            home_offset: 0.0,
            program_running: false,
        };
        c.power_cycle(0.0);
        c
    }

    /// Power off and on: saved settings back, drive disabled, position counter at 0 for
    /// the motor position `counts`.
    pub(crate) fn power_cycle(&mut self, counts: f64) {
        self.settings = self.saved.clone();
        self.program_running = self.settings.program_enabled;
        self.enabled = false;
        self.mode = Mode::Velocity;
        self.target_rpm = 0;
        self.ramp_rpm = 0.0;
        self.home_offset = counts;
        self.loaded = 0;
        self.target_position = 0;
    }

    /// Whether the power stage is enabled.
    pub(crate) fn enabled(&self) -> bool {
        self.enabled
    }

    /// Disables the drive (the module does this on a limit switch or the safety time-out).
    pub(crate) fn disable(&mut self) {
        self.enabled = false;
        self.target_rpm = 0;
        self.mode = Mode::Velocity;
    }

    /// Whether the limit-switch program runs.
    pub(crate) fn program_running(&self) -> bool {
        self.program_running
    }

    /// The answer mode (`ANSW`).
    pub(crate) fn answer_mode(&self) -> u8 {
        self.settings.answer_mode
    }

    /// The speed target (`GV`), rpm.
    pub(crate) fn target_rpm(&self) -> i32 {
        self.target_rpm
    }

    /// Whether a module talking at `baud` reaches this controller.
    pub(crate) fn listens_at(&self, baud: u32) -> bool {
        self.settings.baud == baud
    }

    /// Peak and continuous current limits, mA.
    pub(crate) fn current_limits(&self) -> (f64, f64) {
        (f64::from(self.settings.peak_current), f64::from(self.settings.continuous_current))
    }

    fn position(&self, drive: &Drive) -> i64 {
        (drive.counts - self.home_offset).round() as i64
    }

    /// One step of `dt` seconds: runs the limit-switch program and returns the speed demand
    /// to the speed loop (`None` while the power stage is off).
    pub(crate) fn demand(&mut self, dt: f64, drive: &Drive) -> Option<f64> {
        if self.program_running && drive.switch {
            self.target_rpm = 0;
            self.mode = Mode::Velocity;
        }
        if !self.enabled {
            self.ramp_rpm = drive.rpm;
            return None;
        }
        let max = f64::from(self.settings.max_speed);
        let target = match self.mode {
            _ if self.settings.velocity_source != 0 => 0.0,
            Mode::Velocity => f64::from(self.target_rpm),
            Mode::Position => {
                let error = (self.target_position - self.position(drive)) as f64;
                (error * self.position_gain).clamp(-max, max)
            }
        };
        let accelerating = target.abs() > self.ramp_rpm.abs() && target * self.ramp_rpm >= 0.0;
        let rate = if accelerating { self.settings.acceleration } else { self.settings.deceleration };
        let step = f64::from(rate) * 60.0 * dt;
        self.ramp_rpm += (target - self.ramp_rpm).clamp(-step, step);
        Some(self.ramp_rpm)
    }

    /// Whether positioning has reached its target (within the corridor).
    fn target_reached(&self, drive: &Drive) -> bool {
        self.mode == Mode::Position && (self.target_position - self.position(drive)).abs() <= self.corridor
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn controller() -> Controller {
        Controller::new(&ControllerConfig::default(), 0.1, 7)
    }

    #[test]
    fn ramp_follows_ac_and_dec() {
        let mut c = controller();
        let d = Drive::default();
        c.execute("EN", &d);
        c.execute("V3000", &d);
        // AC 500 rev/s² = 30000 rpm/s: 1 ms -> 30 rpm.
        assert_eq!(c.demand(0.001, &d), Some(30.0));
        c.execute("DI", &d);
        assert_eq!(c.demand(0.001, &d), None);
    }

    #[test]
    fn program_zeroes_speed_while_switch_pressed() {
        let mut c = controller();
        let pressed = Drive { switch: true, ..Drive::default() };
        c.execute("EN", &pressed);
        c.execute("V300", &pressed);
        c.demand(0.001, &pressed);
        assert_eq!(c.target_rpm(), 0);
        c.execute("DIPROG", &pressed);
        c.execute("V300", &pressed);
        c.demand(0.001, &pressed);
        assert_eq!(c.target_rpm(), 300);
        assert!(!c.program_running());
    }
}
