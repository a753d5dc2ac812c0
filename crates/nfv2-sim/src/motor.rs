//! The brushed DC motor and its load, one current-loop substep (50 µs) at a time.
//!
//! - Electrical: `L di/dt = v - R i - ke w`, integrated exactly over the substep for the
//!   voltage applied and the speed at its start (the electrical time constant, 0.32 ms by
//!   default, is only six substeps).
//! - Mechanical: `J dw/dt = kt i - b w - Tc sign(w)`, with stiction: at rest the motor
//!   stays at rest while `|kt i| <= Tc`; a speed that friction would reverse stops at zero.
//! - Bridge off (ERROR, E-stop, no supply, zero duty): the current freewheels through the
//!   body diodes against the supply (`|v| = Vbus + 2 x 0.7 V`) down to zero and stays there;
//!   the motor then coasts. Regeneration above the supply voltage is not modelled.

use std::f64::consts::TAU;

use crate::config::MotorConfig;

/// Voltage drop of one body diode, volts.
const DIODE_DROP_V: f64 = 0.7;

/// What the H-bridge does during one substep.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Bridge {
    /// Switching: the average terminal voltage (clamped to the supply), volts.
    Drive(f64),
    /// All transistors off.
    Off,
}

/// Electrical and mechanical state of the motor, at the motor shaft.
#[derive(Debug, Clone)]
pub(crate) struct Motor {
    config: MotorConfig,
    /// Winding current, A.
    current: f64,
    /// Shaft speed, rad/s.
    omega: f64,
    /// Shaft angle, rad (not wrapped).
    theta: f64,
    /// Terminal voltage during the last substep, volts.
    voltage: f64,
}

impl Motor {
    /// A motor at rest at `counts` encoder counts.
    pub(crate) fn new(config: MotorConfig, counts: f64) -> Self {
        let theta = counts / config.encoder_counts_per_rev * TAU;
        Motor { config, current: 0.0, omega: 0.0, theta, voltage: 0.0 }
    }

    /// Winding current, A.
    pub(crate) fn current(&self) -> f64 {
        self.current
    }

    /// Shaft speed, rad/s.
    #[cfg(test)]
    pub(crate) fn omega(&self) -> f64 {
        self.omega
    }

    /// Terminal voltage during the last substep, volts.
    pub(crate) fn voltage(&self) -> f64 {
        self.voltage
    }

    /// True shaft position in encoder counts (fractional).
    pub(crate) fn counts(&self) -> f64 {
        self.theta / TAU * self.config.encoder_counts_per_rev
    }

    /// Shaft speed in counts per second.
    pub(crate) fn counts_per_s(&self) -> f64 {
        self.omega / TAU * self.config.encoder_counts_per_rev
    }

    /// Back-EMF at the present speed, volts.
    pub(crate) fn back_emf(&self) -> f64 {
        self.config.torque_constant_nm_per_a * self.omega
    }

    /// The terminal voltage that brings the current exactly to `target` after one substep
    /// of `dt` seconds (what a cycle-by-cycle current limiter applies at the limit).
    pub(crate) fn voltage_for_current(&self, target: f64, dt: f64) -> f64 {
        let c = &self.config;
        let r = c.resistance_ohm;
        let decay = (-dt * r / (c.inductance_mh * 1e-3)).exp();
        let steady = (target - self.current * decay) / (1.0 - decay);
        steady * r + self.back_emf()
    }

    /// Moves the shaft to `counts` at rest (test hook; the current is kept).
    pub(crate) fn place(&mut self, counts: f64) {
        self.theta = counts / self.config.encoder_counts_per_rev * TAU;
        self.omega = 0.0;
    }

    /// Runs one substep of `dt` seconds with the bridge in `bridge` on a supply of `vbus`.
    pub(crate) fn substep(&mut self, dt: f64, bridge: Bridge, vbus: f64) {
        self.electrical(dt, bridge, vbus);
        self.mechanical(dt);
    }

    fn electrical(&mut self, dt: f64, bridge: Bridge, vbus: f64) {
        let c = &self.config;
        let r = c.resistance_ohm;
        let decay = (-dt * r / (c.inductance_mh * 1e-3)).exp();
        let emf = self.back_emf();
        match bridge {
            Bridge::Drive(v) => {
                let v = v.clamp(-vbus, vbus);
                let steady = (v - emf) / r;
                self.current = steady + (self.current - steady) * decay;
                self.voltage = v;
            }
            Bridge::Off => {
                if self.current == 0.0 {
                    self.voltage = emf;
                    return;
                }
                let sign = self.current.signum();
                let v = -sign * (vbus + 2.0 * DIODE_DROP_V);
                let steady = (v - emf) / r;
                let next = steady + (self.current - steady) * decay;
                // The diodes block a reverse current.
                self.current = if next * sign <= 0.0 { 0.0 } else { next };
                self.voltage = v;
            }
        }
    }

    fn mechanical(&mut self, dt: f64) {
        let c = &self.config;
        let drive = c.torque_constant_nm_per_a * self.current - c.viscous_friction_nm_s_per_rad * self.omega;
        let tc = c.coulomb_friction_nm;
        let before = self.omega;
        if before == 0.0 {
            if drive.abs() <= tc {
                return;
            }
            let accel = (drive - tc * drive.signum()) / c.inertia_kg_m2;
            self.omega = accel * dt;
        } else {
            let accel = (drive - tc * before.signum()) / c.inertia_kg_m2;
            let after = before + accel * dt;
            // Friction stops the shaft; it does not reverse it.
            self.omega = if after * before < 0.0 && drive.abs() <= tc { 0.0 } else { after };
        }
        self.theta += 0.5 * (before + self.omega) * dt;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 50e-6;

    fn run(m: &mut Motor, secs: f64, bridge: Bridge) {
        for _ in 0..(secs / DT).round() as usize {
            m.substep(DT, bridge, 24.0);
        }
    }

    #[test]
    fn steady_state_speed_from_the_motor_equations() {
        // Independent check: at steady state kt i = b w + Tc and V = R i + ke w, so
        // w = (kt V / R - Tc) / (kt^2 / R + b).
        let c = MotorConfig::default();
        let mut m = Motor::new(c, 0.0);
        run(&mut m, 0.3, Bridge::Drive(12.0));
        let k = c.torque_constant_nm_per_a;
        let r = c.resistance_ohm;
        let w = (k * 12.0 / r - c.coulomb_friction_nm) / (k * k / r + c.viscous_friction_nm_s_per_rad);
        assert!((m.omega() - w).abs() < 0.01 * w, "{} vs {w}", m.omega());
        let i = (12.0 - k * w) / r;
        assert!((m.current() - i).abs() < 0.01, "{} vs {i}", m.current());
    }

    #[test]
    fn stiction_holds_a_small_torque() {
        let c = MotorConfig::default();
        let mut m = Motor::new(c, 100.0);
        // 0.2 A x 38.2 mNm/A = 7.6 mNm < 10 mNm.
        run(&mut m, 0.05, Bridge::Drive(0.2 * c.resistance_ohm));
        assert_eq!(m.omega(), 0.0);
        assert!((m.counts() - 100.0).abs() < 1e-9);
    }

    #[test]
    fn bridge_off_lets_the_current_die_and_the_motor_coast_to_rest() {
        let mut m = Motor::new(MotorConfig::default(), 0.0);
        run(&mut m, 0.2, Bridge::Drive(24.0));
        let w0 = m.omega();
        assert!(w0 > 500.0);
        run(&mut m, 0.0005, Bridge::Off);
        assert_eq!(m.current(), 0.0);
        assert!(m.omega() < w0 && m.omega() > 0.0);
        run(&mut m, 2.0, Bridge::Off);
        assert_eq!(m.omega(), 0.0);
    }
}
