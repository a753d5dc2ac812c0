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

mod query;

use motus_kv01_protocol::faulhaber::{Command, ControllerError, Reply, Request};

use crate::config::ControllerConfig;

/// Baud rates a controller accepts (`specs/faulhaber.md` §1.1).
const BAUD_RATES: [i32; 9] = [600, 1200, 2400, 4800, 9600, 19_200, 38_400, 57_600, 115_200];
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

    fn ok(&self) -> Option<String> {
        (self.settings.answer_mode == 2).then(|| Reply::Ok.to_string())
    }

    fn error(&self, e: ControllerError) -> Option<String> {
        (self.settings.answer_mode == 2).then(|| e.text().to_owned())
    }

    /// Executes one command text (without terminator); the answer, or `None` when the
    /// controller stays silent.
    pub(crate) fn execute(&mut self, text: &str, drive: &Drive) -> Option<String> {
        let request = match Request::parse(text) {
            Ok(r) => r,
            Err(e) => return (self.settings.answer_mode == 2).then(|| e.controller_reply().to_string()),
        };
        if request.node.is_some_and(|n| n != self.settings.node) {
            return None;
        }
        let invalid = || Err(ControllerError::InvalidParameter);
        let in_range = |n: i32, lo: i32, hi: i32| if (lo..=hi).contains(&n) { Ok(()) } else { invalid() };
        let result: Result<(), ControllerError> = match request.command {
            Command::Query(q) => return Some(self.query(q, drive)),
            Command::AnalogInput(i) => {
                return match i {
                    1..=5 => Some("0".to_owned()),
                    _ => self.error(ControllerError::InvalidParameter),
                };
            }
            Command::Save | Command::EepSave => {
                self.saved = self.settings.clone();
                return Some(Reply::EepromWritingDone.to_string());
            }
            Command::Unknown(_) => Err(ControllerError::UnknownCommand),
            Command::Voltage(_) => Err(ControllerError::CommandNotAvailable),
            Command::Enable | Command::Disable => {
                self.enabled = request.command == Command::Enable;
                self.target_rpm = 0;
                self.mode = Mode::Velocity;
                self.ramp_rpm = drive.rpm;
                Ok(())
            }
            Command::Velocity(n) => in_range(n, -self.rpm_range, self.rpm_range).map(|()| {
                self.mode = Mode::Velocity;
                self.target_rpm = n.clamp(-self.settings.max_speed, self.settings.max_speed);
            }),
            Command::LoadAbsolute(n) => {
                self.loaded = i64::from(n);
                Ok(())
            }
            Command::LoadRelative(n) => {
                self.loaded = self.loaded.saturating_add(i64::from(n));
                Ok(())
            }
            Command::Move => {
                let (lo, hi) = (i64::from(self.settings.lower_limit), i64::from(self.settings.upper_limit));
                self.target_position = if self.settings.limits_active {
                    self.loaded.clamp(lo, hi)
                } else {
                    self.loaded
                };
                self.mode = Mode::Position;
                Ok(())
            }
            Command::Home(n) => {
                let new = n.unwrap_or(0);
                let shift = self.position(drive) - i64::from(new);
                self.home_offset = drive.counts - f64::from(new);
                self.target_position = self.target_position.saturating_sub(shift);
                self.loaded = self.loaded.saturating_sub(shift);
                Ok(())
            }
            Command::NotifyPosition(_)
            | Command::NotifyPositionOff
            | Command::NotifyVelocity(_)
            | Command::NotifyVelocityOff => Ok(()),
            Command::EnableProgram | Command::Resume => {
                self.program_running = true;
                self.settings.program_enabled = true;
                Ok(())
            }
            Command::DisableProgram => {
                self.program_running = false;
                self.settings.program_enabled = false;
                Ok(())
            }
            Command::AnswerMode(n) => in_range(n, 0, 2).map(|()| {
                self.settings.answer_mode = u8::try_from(n).unwrap_or(2);
            }),
            Command::VelocitySource(n) => in_range(n, 0, 3).map(|()| self.settings.velocity_source = n),
            Command::MaxSpeed(n) => in_range(n, 0, self.rpm_range).map(|()| self.settings.max_speed = n),
            Command::Acceleration(n) => {
                in_range(n, 1, MAX_ACCELERATION).map(|()| self.settings.acceleration = n)
            }
            Command::Deceleration(n) => {
                in_range(n, 1, MAX_ACCELERATION).map(|()| self.settings.deceleration = n)
            }
            Command::PositionLimit(n) => {
                if n >= 0 {
                    self.settings.upper_limit = n;
                } else {
                    self.settings.lower_limit = n;
                }
                Ok(())
            }
            Command::ActivatePositionLimits(n) => {
                in_range(n, 0, 1).map(|()| self.settings.limits_active = n == 1)
            }
            Command::PeakCurrent(n) => in_range(n, 0, MAX_CURRENT_MA).map(|()| self.settings.peak_current = n),
            Command::ContinuousCurrent(n) => {
                in_range(n, 0, MAX_CURRENT_MA).map(|()| self.settings.continuous_current = n)
            }
            Command::Baud(n) => match u32::try_from(n) {
                Ok(b) if BAUD_RATES.contains(&n) => {
                    // Answered at the old rate; later traffic needs the new one.
                    let answer = self.ok();
                    self.settings.baud = b;
                    return answer;
                }
                _ => invalid(),
            },
            Command::NodeAddress(n) => match u8::try_from(n) {
                Ok(node) => {
                    self.settings.node = node;
                    Ok(())
                }
                Err(_) => invalid(),
            },
        };
        match result {
            Ok(()) => self.ok(),
            Err(e) => self.error(e),
        }
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
    fn answers_like_answer_mode_2() {
        let mut c = controller();
        let d = Drive::default();
        assert_eq!(c.execute("EN", &d).as_deref(), Some("OK"));
        assert!(c.enabled());
        assert_eq!(c.execute("v 320", &d).as_deref(), Some("OK"));
        assert_eq!(c.target_rpm(), 320);
        assert_eq!(c.execute("V99999", &d).as_deref(), Some("Invalid parameter"));
        assert_eq!(c.execute("V", &d).as_deref(), Some("Invalid parameter"));
        assert_eq!(c.execute("FOO", &d).as_deref(), Some("Unknown command"));
        assert_eq!(c.execute("12", &d).as_deref(), Some("Unknown command"));
        assert_eq!(c.execute("U100", &d).as_deref(), Some("Command not available"));
        assert_eq!(c.execute("0POS", &d).as_deref(), Some("0"));
        assert_eq!(c.execute("3POS", &d), None, "another node's prefix: silent");
        assert_eq!(c.execute("ANSW0", &d), None);
        assert_eq!(c.execute("V100", &d), None, "no confirmation in answer mode 0");
        assert_eq!(c.execute("FOO", &d), None, "no error string in answer mode 0");
        assert_eq!(c.execute("GV", &d).as_deref(), Some("100"), "queries always answer");
        assert_eq!(c.execute("SAVE", &d).as_deref(), Some("EEPROM writing done"));
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

    #[test]
    fn save_survives_power_cycle_and_baud_change_isolates() {
        let mut c = controller();
        let d = Drive::default();
        c.execute("DIPROG", &d);
        c.execute("SAVE", &d);
        c.execute("ENPROG", &d);
        c.power_cycle(0.0);
        assert!(!c.program_running(), "the saved DIPROG state comes back");
        assert_eq!(c.execute("BAUD19200", &d).as_deref(), Some("OK"));
        assert!(!c.listens_at(9600));
        c.power_cycle(0.0);
        assert!(c.listens_at(9600), "BAUD was not saved");
    }
}
