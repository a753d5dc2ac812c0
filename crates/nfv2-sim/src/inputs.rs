//! The controller's physical inputs and outputs (connector INPUT J13, OUTPUT J14, PSUPP J2)
//! and the sensors on the axis, sampled once per regulator cycle.
//!
//! - ENABLE (E-stop loop): present (>= 3 V) by default; a test removes it.
//! - LIM_POS / LIM_NEG: closed when the true position is at or beyond the configured switch
//!   positions, unless a test forces them (`Some(pressed)`).
//! - HOME: active at and below the home edge (a flag covering one side of the travel).
//! - Encoder index: one pulse per motor turn, seen while the shaft is within 4 counts of
//!   the index position (true position 0 modulo a turn).
//! - AI0 / AI1 (0..30 V), the power-stage supply PSUPP, the digital outputs GO0..GO3, +O4
//!   and the fan, as set by `SetDigitalOutputs`.

use serde::{Deserialize, Serialize};

use crate::config::ControllerConfig;

/// Width of the encoder index window, counts.
const INDEX_WIDTH_COUNTS: f64 = 4.0;

/// Full scale of the analog inputs, volts.
pub(crate) const ANALOG_FULL_SCALE_V: f64 = 30.0;

/// One of the two limit switches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LimitSwitch {
    /// LIM_POS, the upper switch (status bit 0, digital input bit 0): blocks positive motion.
    Up,
    /// LIM_NEG, the lower switch (status bit 1, digital input bit 1): blocks negative motion.
    Down,
}

/// The inputs as the test hooks set them.
#[derive(Debug, Clone)]
pub(crate) struct Inputs {
    pub(crate) enable: bool,
    pub(crate) limit_positions: [Option<f64>; 2],
    pub(crate) limit_forced: [Option<bool>; 2],
    pub(crate) home_edge: Option<f64>,
    pub(crate) analog_v: [f64; 2],
    pub(crate) supply_v: f64,
    pub(crate) digital_outputs: u8,
}

/// The inputs as the controller sees them in one cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Sensed {
    pub(crate) enable: bool,
    pub(crate) limit_up: bool,
    pub(crate) limit_down: bool,
    pub(crate) home: bool,
    pub(crate) index: bool,
    pub(crate) supply_v: f64,
    pub(crate) power_ok: bool,
}

impl Sensed {
    /// Which directions the closed switches block: `(positive, negative)`.
    pub(crate) fn blocked(&self) -> (bool, bool) {
        (self.limit_up, self.limit_down)
    }
}

impl Inputs {
    /// Power-on inputs from the configuration.
    pub(crate) fn new(config: &ControllerConfig) -> Self {
        Inputs {
            enable: true,
            limit_positions: [config.limit_switch_up_counts, config.limit_switch_down_counts],
            limit_forced: [None, None],
            home_edge: config.home_edge_counts,
            analog_v: config.analog_inputs_v,
            supply_v: config.supply_v,
            digital_outputs: 0,
        }
    }

    /// Samples every input with the axis at `counts` (true position).
    pub(crate) fn sense(&self, counts: f64, counts_per_rev: f64, low_v: f64) -> Sensed {
        let [up_at, down_at] = self.limit_positions;
        let [up_forced, down_forced] = self.limit_forced;
        let limit_up = up_forced.unwrap_or_else(|| up_at.is_some_and(|at| counts >= at));
        let limit_down = down_forced.unwrap_or_else(|| down_at.is_some_and(|at| counts <= at));
        Sensed {
            enable: self.enable,
            limit_up,
            limit_down,
            home: self.home_edge.is_some_and(|edge| counts <= edge),
            index: counts.rem_euclid(counts_per_rev) < INDEX_WIDTH_COUNTS,
            supply_v: self.supply_v,
            power_ok: self.supply_v >= low_v,
        }
    }

    /// Slot of `switch` in the arrays.
    pub(crate) fn slot(switch: LimitSwitch) -> usize {
        match switch {
            LimitSwitch::Up => 0,
            LimitSwitch::Down => 1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn switches_home_and_index_from_the_position() {
        let inputs = Inputs::new(&ControllerConfig::default());
        let s = inputs.sense(0.0, 2000.0, 13.0);
        assert!(!s.limit_up && !s.limit_down && !s.home && s.index && s.power_ok && s.enable);
        let s = inputs.sense(60_000.0, 2000.0, 13.0);
        assert!(s.limit_up && !s.limit_down);
        let s = inputs.sense(-20_000.0, 2000.0, 13.0);
        assert!(s.home && !s.limit_down);
        let s = inputs.sense(-60_000.5, 2000.0, 13.0);
        assert!(s.home && s.limit_down);
        assert!(!inputs.sense(1999.0, 2000.0, 13.0).index);
        assert!(inputs.sense(-1999.0, 2000.0, 13.0).index);
    }

    #[test]
    fn forced_switches_win() {
        let mut inputs = Inputs::new(&ControllerConfig::default());
        inputs.limit_forced = [Some(true), Some(false)];
        let s = inputs.sense(-70_000.0, 2000.0, 13.0);
        assert!(s.limit_up && !s.limit_down);
        assert_eq!(s.blocked(), (true, false));
    }
}
