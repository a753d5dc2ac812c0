//! What the controller reports: the values a query reads (refreshed at the end of every
//! regulator cycle, with seeded measurement noise) and the true state a test reads.
//!
//! Status words (specs/nfv2.md, "ReadDrivesStatus bits"; levels, refreshed every cycle,
//! except the over-current latch):
//!
//! | bit | set while |
//! |---|---|
//! | 0 / 1 | LIM_POS / LIM_NEG closed |
//! | 2 | HOME active |
//! | 3 | the encoder index is under the sensor |
//! | 4 | synchronized (homed, or `SetDrivesMisc` bit 0) |
//! | 5, 6 | never (PVT is not supported) |
//! | 7 | the command watchdog zeroed a set-point, until the next motion command |
//! | 8 | position reference - counter beyond `following_error_counts` |
//! | 9 | power-stage supply below `power_stage_low_v` |
//! | 10 / 11 / 12 | a position / speed / current limit acted this cycle |
//! | 13 | over-current trip (latched until the next `SetDrivesMode`) |
//! | 14 | never (no power-stage fault is modelled) |
//! | 15 | mode ERROR, or ENABLE absent |
//!
//! `ReadDeviceStatus` (not defined by the sources) repeats the device-wide bits 7, 9, 13,
//! 14 and 15. `ReadDigitalInputs`: bit 0 LIM_POS, 1 LIM_NEG, 2 HOME (the reference), 3
//! ENABLE (ours). `ReadAnalogInputs`: AI0, AI1 in mV through a 12-bit converter over
//! 0..30 V (± 1 LSB noise). `ReadDeviceVitals`: PSUPP, +24 V, +12 V, +5 V in mV.
//! `ReadDrivesCurrent`: motor current in mA (signed, with noise).

use std::collections::VecDeque;
use std::time::Duration;

use motus_nfv2_protocol::{DriveMode, DriveStatus};
use rand::Rng;

use super::{motion::Family, Controller, Demand, TruthTrace};
use crate::inputs::ANALOG_FULL_SCALE_V;

/// ADC steps of the analog inputs (12 bits).
const ADC_STEPS: f64 = 4095.0;

/// The values queries read, as of the last regulator cycle.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct Published {
    pub(crate) status: u16,
    pub(crate) device_status: u16,
    pub(crate) position: i64,
    pub(crate) current_ma: i64,
    pub(crate) digital_inputs: u8,
    pub(crate) analog_mv: [i64; 2],
    pub(crate) vitals_mv: [i64; 4],
}

/// The simulated truth, for tests and displays (what no query can read exactly).
#[derive(Debug, Clone, PartialEq)]
pub struct TrueState {
    /// Simulated time of the last regulator cycle.
    pub time: Duration,
    /// The mode the regulators run in.
    pub mode: DriveMode,
    /// True motor position, encoder counts from the power-on position (not the counter).
    pub position_counts: f64,
    /// The position counter (`ReadDrivesPosition` before wrapping to i32).
    pub counter: i64,
    /// True motor speed, counts/s.
    pub speed_counts_per_s: f64,
    /// Measured speed, speed units (1/100 count per ms), as the speed loop sees it.
    pub measured_speed: f64,
    /// Axis angle, degrees (true position through the gear).
    pub axis_deg: f64,
    /// Axis speed, degrees per second.
    pub axis_deg_per_s: f64,
    /// True motor current, A.
    pub current_a: f64,
    /// Terminal voltage, V.
    pub voltage_v: f64,
    /// The H-bridge is switching (false: all transistors off).
    pub bridge_on: bool,
    /// Current reference of the current loop, A (`None` when it does not run).
    pub current_reference_a: Option<f64>,
    /// Position reference of the trajectory generator, counts (`None` outside the
    /// position-loop modes).
    pub position_reference: Option<f64>,
    /// Speed reference, counts/s (`None` outside the speed-loop modes).
    pub speed_reference: Option<f64>,
    /// The drive status word as published.
    pub status: DriveStatus,
    /// ENABLE input present.
    pub enable: bool,
    /// LIM_POS closed.
    pub limit_up: bool,
    /// LIM_NEG closed.
    pub limit_down: bool,
    /// HOME active.
    pub home: bool,
    /// Power-stage supply, V.
    pub power_stage_supply_v: f64,
    /// Power-stage (heat sink) temperature, °C.
    pub temperature_c: f64,
    /// GO0..GO3 (bits 0-3), +O4 (bit 4), fan (bit 5), as last set.
    pub digital_outputs: u8,
    /// AI0, AI1, V.
    pub analog_inputs_v: [f64; 2],
}

impl Controller {
    /// The drive status word for the last cycle.
    fn status_word(&self) -> u16 {
        let s = &self.sensed;
        let f = &self.flags;
        let bits = [
            (s.limit_up, DriveStatus::LIMIT_SWITCH_UP),
            (s.limit_down, DriveStatus::LIMIT_SWITCH_DOWN),
            (s.home, DriveStatus::SYNCHRO_SWITCH),
            (s.index, DriveStatus::ENCODER_INDEX),
            (f.synchronized, DriveStatus::SYNCHRONIZED),
            (f.watchdog, DriveStatus::COMMUNICATION_FAULT),
            (f.following_error, DriveStatus::FOLLOWING_ERROR),
            (!s.power_ok, DriveStatus::POWER_STAGE_VOLTAGE_LOW),
            (f.position_limit, DriveStatus::POSITION_LIMIT),
            (f.speed_limit, DriveStatus::SPEED_LIMIT),
            (f.current_limit, DriveStatus::CURRENT_LIMIT),
            (f.overcurrent, DriveStatus::OVERCURRENT),
            (self.active_mode == DriveMode::Error || !s.enable, DriveStatus::ERROR),
        ];
        bits.iter().filter(|(on, _)| *on).fold(0, |acc, (_, bit)| acc | bit)
    }

    /// Uniform noise of amplitude `a`.
    fn noise(&mut self, a: f64) -> f64 {
        if a > 0.0 {
            self.rng.gen_range(-a..=a)
        } else {
            0.0
        }
    }

    /// Refreshes what queries read (end of a regulator cycle).
    pub(super) fn publish(&mut self) {
        let status = self.status_word();
        let device_mask = DriveStatus::COMMUNICATION_FAULT
            | DriveStatus::POWER_STAGE_VOLTAGE_LOW
            | DriveStatus::OVERCURRENT
            | DriveStatus::POWER_STAGE_FAULT
            | DriveStatus::ERROR;
        let s = self.sensed;
        let digital_inputs = u8::from(s.limit_up)
            | u8::from(s.limit_down) << 1
            | u8::from(s.home) << 2
            | u8::from(s.enable) << 3;
        let current_noise = self.noise(self.config.current_noise_ma);
        let current_ma = (self.motor.current() * 1000.0 + current_noise).round() as i64;
        let mut analog_mv = [0; 2];
        for (out, v) in analog_mv.iter_mut().zip(self.inputs.analog_v) {
            let lsb = self.noise(1.0);
            let code = (v / ANALOG_FULL_SCALE_V * ADC_STEPS + lsb).round().clamp(0.0, ADC_STEPS);
            *out = (code * ANALOG_FULL_SCALE_V * 1000.0 / ADC_STEPS).round() as i64;
        }
        let [l24, l12, l5] = self.config.logic_supplies_v;
        let mut vitals_mv = [0; 4];
        for (out, v) in vitals_mv.iter_mut().zip([s.supply_v, l24, l12, l5]) {
            let n = self.noise(self.config.voltage_noise_mv);
            *out = (v * 1000.0 + n).round().max(0.0) as i64;
        }
        self.published = Published {
            status,
            device_status: status & device_mask,
            position: self.counter,
            current_ma,
            digital_inputs,
            analog_mv,
            vitals_mv,
        };
    }

    /// Keeps the true state at the end of every regulator cycle from now on, the newest
    /// `capacity` of them ([`Controller::take_truth_trace`] collects them); `None` stops
    /// and drops what was kept.
    pub fn trace_truth(&mut self, capacity: Option<usize>) {
        self.truth_trace = capacity.map(|capacity| TruthTrace { capacity, states: VecDeque::new() });
    }

    /// The true states kept since tracing started or the last call, oldest first (empty
    /// when not tracing).
    pub fn take_truth_trace(&mut self) -> Vec<TrueState> {
        self.truth_trace.as_mut().map(|t| t.states.drain(..).collect()).unwrap_or_default()
    }

    /// The simulated truth now.
    #[must_use]
    pub fn true_state(&self) -> TrueState {
        let m = &self.config.motor;
        let counts = self.motor.counts();
        let speed = self.motor.counts_per_s();
        let deg_per_count = 360.0 / (m.encoder_counts_per_rev * m.gear_ratio);
        let family = Family::of(self.active_mode);
        let loops = family.uses_speed_loop();
        let position_loop = matches!(family, Family::Position | Family::PosIncrement | Family::Homing);
        TrueState {
            time: self.time,
            mode: self.active_mode,
            position_counts: counts,
            counter: self.counter,
            speed_counts_per_s: speed,
            measured_speed: self.measured_speed,
            axis_deg: counts * deg_per_count,
            axis_deg_per_s: speed * deg_per_count,
            current_a: self.motor.current(),
            voltage_v: self.motor.voltage(),
            bridge_on: self.bridge_on,
            current_reference_a: matches!(self.demand, Demand::Current(_)).then_some(self.current_ref_a),
            position_reference: position_loop.then_some(self.trajectory.p_ref),
            speed_reference: loops.then_some(self.trajectory.v_ref),
            status: DriveStatus(self.published.status),
            enable: self.inputs.enable,
            limit_up: self.sensed.limit_up,
            limit_down: self.sensed.limit_down,
            home: self.sensed.home,
            power_stage_supply_v: self.inputs.supply_v,
            temperature_c: self.temperature_c,
            digital_outputs: self.inputs.digital_outputs,
            analog_inputs_v: self.inputs.analog_v,
        }
    }
}
