//! The discrete PID regulator of the three loops, parameterised by the codec's
//! [`Regulator`] (`SetCurrentRegulator`, `SetSpeedRegulator`, `SetPositionRegulator`).
//!
//! Form (the reference firmware's `pid.c`, Atmel AVR221, `SCALING_FACTOR = 1000`):
//!
//! ```text
//! e = reference - measurement
//! u = (P e + I sum(e) + D (previous measurement - measurement)) / 1000
//! ```
//!
//! evaluated once per regulator period (the sum and the difference are per sample, so the
//! gains depend on the loop's rate). The output is clamped to the loop's limit; the sum
//! only integrates while the output is not saturated in the direction of the error
//! (conditional integration, no wind-up). `T`, the fourth parameter, is stored but not
//! used, as in the reference firmware.

use motus_nfv2_protocol::Regulator;

/// Gains are integers scaled by this factor.
pub(crate) const SCALING: f64 = 1000.0;

/// One PID loop.
#[derive(Debug, Clone)]
pub(crate) struct Pid {
    gains: Regulator,
    sum: f64,
    last_measurement: Option<f64>,
}

/// One regulator output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PidOutput {
    /// The clamped output.
    pub(crate) value: f64,
    /// The unclamped output exceeded the limit.
    pub(crate) saturated: bool,
}

impl Pid {
    /// A regulator with `gains` and an empty history.
    pub(crate) fn new(gains: Regulator) -> Self {
        Pid { gains, sum: 0.0, last_measurement: None }
    }

    /// The gains in use.
    pub(crate) fn gains(&self) -> Regulator {
        self.gains
    }

    /// New gains; the history is cleared (the reference's `PID_Init`).
    pub(crate) fn set_gains(&mut self, gains: Regulator) {
        self.gains = gains;
        self.reset();
    }

    /// Clears the integral and the derivative history.
    pub(crate) fn reset(&mut self) {
        self.sum = 0.0;
        self.last_measurement = None;
    }

    /// One sample: the output for `reference` and `measurement`, clamped to `+-limit`.
    pub(crate) fn update(&mut self, reference: f64, measurement: f64, limit: f64) -> PidOutput {
        let g = self.gains;
        let e = reference - measurement;
        let p = f64::from(g.p) * e;
        let d = match self.last_measurement {
            Some(last) => f64::from(g.d) * (last - measurement),
            None => 0.0,
        };
        self.last_measurement = Some(measurement);
        let sum = self.sum + e;
        let raw = (p + f64::from(g.i) * sum + d) / SCALING;
        let limit = limit.max(0.0);
        let saturated = raw.abs() > limit;
        let value = raw.clamp(-limit, limit);
        // Integrate unless that pushes further into saturation.
        if !saturated || raw.signum() != e.signum() {
            self.sum = sum;
        }
        PidOutput { value, saturated }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn proportional_and_integral_by_hand() {
        let mut pid = Pid::new(Regulator { p: 2000, i: 500, d: 0, t: 0 });
        // e = 3: (2000 x 3 + 500 x 3) / 1000 = 7.5
        assert_eq!(pid.update(3.0, 0.0, 100.0).value, 7.5);
        // e = 3 again: (6000 + 500 x 6) / 1000 = 9
        assert_eq!(pid.update(3.0, 0.0, 100.0).value, 9.0);
    }

    #[test]
    fn derivative_on_measurement() {
        let mut pid = Pid::new(Regulator { p: 0, i: 0, d: 1000, t: 0 });
        assert_eq!(pid.update(0.0, 1.0, 100.0).value, 0.0);
        // measurement rose by 2: D x (1 - 3) / 1000 = -2
        assert_eq!(pid.update(0.0, 3.0, 100.0).value, -2.0);
    }

    #[test]
    fn no_windup_while_saturated() {
        let mut pid = Pid::new(Regulator { p: 0, i: 1000, d: 0, t: 0 });
        for _ in 0..100 {
            let out = pid.update(10.0, 0.0, 5.0);
            assert!(out.value <= 5.0);
        }
        // The sum stopped at the first sample beyond the limit: it unwinds at once.
        assert!(pid.update(-10.0, 0.0, 5.0).value < 5.0);
    }
}
