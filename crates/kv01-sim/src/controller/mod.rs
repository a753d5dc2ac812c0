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
//! forward an asynchronous answer); `U` (voltage mode) is "Command not available".

mod query;

use motus_kv01_protocol::faulhaber::{Command, ControllerError, Reply, Request};

use crate::config::ControllerConfig;

/// Baud rates a controller accepts (`specs/faulhaber.md` §1.1).
const BAUD_RATES: [i32; 9] = [600, 1200, 2400, 4800, 9600, 19_200, 38_400, 57_600, 115_200];
/// Default position range limit (increments).
const POSITION_RANGE: i32 = 1_800_000_000;

/// The settings `SAVE` stores and a power-on restores.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Settings {
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
            max_speed: c.max_speed_rpm,
            acceleration: c.acceleration,
            deceleration: c.deceleration,
            peak_current: c.peak_current_ma,
            continuous_current: c.continuous_current_ma,
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
    corridor: i32,
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
    /// A controller powered on with its saved settings (the configuration's at first).
    pub(crate) fn power_on(config: &ControllerConfig, position_gain: f64, serial: u32) -> Self {
        let settings = Settings::from_config(config);
        Self {
            saved: settings.clone(),
            program_running: settings.program_enabled,
            settings,
            rpm_range: config.rpm_range.max(0),
            corridor: config.corridor.max(0),
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
            program_running_placeholder_unused: (),
        }
    }
}
