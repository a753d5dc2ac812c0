//! The simulated machine behind a module: where the switches, the encoder zero pulses
//! and the limits are, and how the servo follows the DDA.

use serde::{Deserialize, Serialize};

/// Mechanics and sensors of one simulated axis, in encoder units of machine coordinates
/// (a fixed frame; the module's position counter is zeroed by homing).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MachineConfig {
    /// Machine position at the very first power-on.
    pub initial_position: f64,
    /// The reference switch IRB is pressed at and below this position (minus side).
    pub reference_switch: f64,
    /// Distance between encoder zero pulses (one encoder revolution).
    pub zero_pulse_period: f64,
    /// First zero pulse above the reference switch, relative to it.
    pub zero_pulse_offset: f64,
    /// The IL- limit switch is pressed at and below this position.
    pub limit_negative: f64,
    /// The IL+ limit switch is pressed at and above this position.
    pub limit_positive: f64,
    /// Position-loop gain of the servo (1/s): following error = velocity / kv.
    pub kv: f64,
    /// Following error (units) above which LBS bit 7 is raised and motion aborted.
    pub following_error_limit: f64,
}

impl Default for MachineConfig {
    fn default() -> Self {
        MachineConfig {
            initial_position: 5_000.0,
            reference_switch: 0.0,
            zero_pulse_period: 2_000.0,
            zero_pulse_offset: 500.0,
            limit_negative: -5_000.0,
            limit_positive: 10_000_000.0,
            kv: 50.0,
            following_error_limit: 16_384.0,
        }
    }
}

impl MachineConfig {
    /// True if the reference switch is pressed at `x`.
    pub fn reference_pressed(&self, x: f64) -> bool {
        x <= self.reference_switch
    }

    /// The first zero pulse in `(from, to]` when moving up, if any.
    pub fn zero_pulse_between(&self, from: f64, to: f64) -> Option<f64> {
        if to <= from || self.zero_pulse_period <= 0.0 {
            return None;
        }
        let base = self.reference_switch + self.zero_pulse_offset;
        let k = ((from - base) / self.zero_pulse_period).floor() + 1.0;
        let x = base + k * self.zero_pulse_period;
        (x <= to).then_some(x)
    }
}
