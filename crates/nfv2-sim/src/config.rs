//! Configuration of one simulated 1209A and its axis, with every default number in one
//! place: the DC motor and its load, the encoder, the regulator gains the controller starts
//! with, the limits, homing, the sensors' positions, the MANUAL input mapping, supplies,
//! measurement noise, the command watchdog and the seed.
//!
//! Defaults describe one axis of the pan-tilt head (specs/nfv2.md: 24 V, up to 40 W):
//! a 24 V brushed DC motor (1.1 Ohm, 0.35 mH, 38.2 mNm/A, about 6000 rpm no-load) behind a
//! 100:1 gear, a 500-line encoder counted in quadrature (2000 counts per motor turn).
//!
//! Device units on the wire (our reading of the reference firmware `ptbldc`, `motor.c`):
//! positions in encoder counts; speeds in **1/100 count per 1 ms regulator cycle**
//! (`PRECISE_INCREMENT_UNIT = 100`, i.e. one unit is 10 counts/s); currents in mA; PWM
//! duty in 1/1000 (`MAX_PWM = 1000` is 100 %); acceleration in counts/s².

use serde::{Deserialize, Serialize};

use motus_nfv2_protocol::Regulator;

use crate::error::SimError;

/// Counts per second of one speed unit (1/100 count per 1 ms cycle).
pub const COUNTS_PER_S_PER_SPEED_UNIT: f64 = 10.0;

/// The DC motor and the load it drives, seen at the motor shaft.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MotorConfig {
    /// Winding resistance (terminal to terminal), ohm.
    pub resistance_ohm: f64,
    /// Winding inductance, millihenry (electrical time constant L/R = 0.32 ms).
    pub inductance_mh: f64,
    /// Torque constant, N·m/A; also the back-EMF constant in V·s/rad (SI units).
    pub torque_constant_nm_per_a: f64,
    /// Rotor plus load inertia reflected to the motor shaft, kg·m².
    pub inertia_kg_m2: f64,
    /// Coulomb (dry) friction at the motor shaft (gear and bearings), N·m.
    pub coulomb_friction_nm: f64,
    /// Viscous friction at the motor shaft, N·m per rad/s.
    pub viscous_friction_nm_s_per_rad: f64,
    /// Encoder counts per motor revolution (lines x 4).
    pub encoder_counts_per_rev: f64,
    /// Motor revolutions per axis revolution (only for the axis angle in [`crate::TrueState`]).
    pub gear_ratio: f64,
}

impl Default for MotorConfig {
    fn default() -> Self {
        Self {
            resistance_ohm: 1.1,
            inductance_mh: 0.35,
            torque_constant_nm_per_a: 0.0382,
            inertia_kg_m2: 6.0e-6,
            coulomb_friction_nm: 0.01,
            viscous_friction_nm_s_per_rad: 3.0e-6,
            encoder_counts_per_rev: 2000.0,
            gear_ratio: 100.0,
        }
    }
}

/// How MANUAL mode maps the voltage on AI0 to a PWM duty (direction and power, as the
/// seed says: 0 V full reverse, `zero_v` stop, `zero_v + span_v` full forward).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ManualConfig {
    /// AI0 voltage for zero duty (a joystick potentiometer across +24 V centres at 12 V).
    pub zero_v: f64,
    /// Voltage difference from `zero_v` giving 100 % duty.
    pub span_v: f64,
    /// Dead band around `zero_v` giving zero duty, volts.
    pub deadband_v: f64,
}

impl Default for ManualConfig {
    fn default() -> Self {
        Self { zero_v: 12.0, span_v: 12.0, deadband_v: 0.3 }
    }
}

/// Everything one simulated controller needs. JSON-friendly (`ControllerConfig::from_json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerConfig {
    /// The motor and load.
    pub motor: MotorConfig,
    /// Nominal power-stage supply (PSUPP, 15..24 V), volts.
    pub supply_v: f64,
    /// Logic supplies reported by `ReadDeviceVitals` 1..3: +24 V, +12 V, +5 V.
    pub logic_supplies_v: [f64; 3],
    /// Below this PSUPP voltage the power stage is off and status bit 9 is set.
    pub power_stage_low_v: f64,
    /// Current regulator (20 kHz) at power-on: mA error -> duty in 1/1000, gains / 1000.
    pub current_regulator: Regulator,
    /// Speed regulator (1 kHz) at power-on: speed-unit error -> mA, gains / 1000.
    pub speed_regulator: Regulator,
    /// Position regulator (1 kHz) at power-on: count error -> speed units, gains / 1000.
    pub position_regulator: Regulator,
    /// Speed limit at power-on, speed units (1/100 count per ms).
    pub max_speed: i64,
    /// Current limit at power-on, mA.
    pub max_current_ma: i64,
    /// What `SetDrivesMaxCurrent` may set at most: the 1209A's 13 A continuous rating, mA.
    pub hardware_max_current_ma: i64,
    /// Instantaneous current that trips the over-current protection (bit 13, ERROR), mA.
    pub overcurrent_trip_ma: i64,
    /// Acceleration of the trajectory generator and speed ramps at power-on, counts/s².
    pub max_acceleration: i64,
    /// Speed of the homing search, speed units.
    pub homing_speed: i64,
    /// Position counter value set at the home edge.
    pub home_position: i64,
    /// Following-error threshold (status bit 8), counts.
    pub following_error_counts: i64,
    /// Speed / PWM / current set-points are zeroed after this long without a motion
    /// command (the reference firmware's `ST_CommandWD`, 2 s); `None` disables it.
    pub command_watchdog_ms: Option<u64>,
    /// MANUAL mode's AI0 mapping.
    pub manual: ManualConfig,
    /// AI0, AI1 at power-on, volts (0..30 V).
    pub analog_inputs_v: [f64; 2],
    /// Initial true position, counts (world coordinate: 0 is where the motor was at the
    /// first power-on).
    pub initial_position_counts: f64,
    /// The HOME sensor is active at and below this true position (counts); `None`: no sensor.
    pub home_edge_counts: Option<f64>,
    /// The lower limit switch (LIM_NEG) closes at and below this true position, counts.
    pub limit_switch_down_counts: Option<f64>,
    /// The upper limit switch (LIM_POS) closes at and above this true position, counts.
    pub limit_switch_up_counts: Option<f64>,
    /// Amplitude of the uniform noise on the current reading, mA.
    pub current_noise_ma: f64,
    /// Amplitude of the uniform noise on the supply voltage readings, mV.
    pub voltage_noise_mv: f64,
    /// Ambient temperature, °C.
    pub ambient_c: f64,
    /// Power stage thermal resistance to ambient, K/W.
    pub thermal_resistance_k_per_w: f64,
    /// Power stage thermal time constant, seconds.
    pub thermal_time_constant_s: f64,
    /// Seed of the measurement noise.
    pub seed: u64,
}

impl Default for ControllerConfig {
    fn default() -> Self {
        Self {
            motor: MotorConfig::default(),
            supply_v: 24.0,
            logic_supplies_v: [24.0, 12.0, 5.0],
            power_stage_low_v: 13.0,
            current_regulator: Regulator { p: 92, i: 14, d: 0, t: 0 },
            speed_regulator: Regulator { p: 940, i: 45, d: 0, t: 0 },
            position_regulator: Regulator { p: 6000, i: 0, d: 0, t: 0 },
            max_speed: 12_000,
            max_current_ma: 5_000,
            hardware_max_current_ma: 13_000,
            overcurrent_trip_ma: 20_000,
            max_acceleration: 1_000_000,
            homing_speed: 500,
            home_position: 0,
            following_error_counts: 5_000,
            command_watchdog_ms: Some(2_000),
            manual: ManualConfig::default(),
            analog_inputs_v: [12.0, 0.0],
            initial_position_counts: 0.0,
            home_edge_counts: Some(-20_000.0),
            limit_switch_down_counts: Some(-60_000.0),
            limit_switch_up_counts: Some(60_000.0),
            current_noise_ma: 10.0,
            voltage_noise_mv: 20.0,
            ambient_c: 25.0,
            thermal_resistance_k_per_w: 5.0,
            thermal_time_constant_s: 60.0,
            seed: 0,
        }
    }
}

impl ControllerConfig {
    /// Parses a JSON configuration (missing fields take their defaults).
    ///
    /// # Errors
    /// [`SimError::Config`] for bad JSON or values [`ControllerConfig::validate`] rejects.
    pub fn from_json(json: &str) -> Result<Self, SimError> {
        let config: Self = serde_json::from_str(json).map_err(|e| SimError::Config(e.to_string()))?;
        config.validate()?;
        Ok(config)
    }

    /// Rejects values the model cannot run with (non-positive physical constants, limits).
    ///
    /// # Errors
    /// [`SimError::Config`] naming the field.
    pub fn validate(&self) -> Result<(), SimError> {
        let m = &self.motor;
        let positive = [
            ("motor.resistance_ohm", m.resistance_ohm),
            ("motor.inductance_mh", m.inductance_mh),
            ("motor.torque_constant_nm_per_a", m.torque_constant_nm_per_a),
            ("motor.inertia_kg_m2", m.inertia_kg_m2),
            ("motor.encoder_counts_per_rev", m.encoder_counts_per_rev),
            ("motor.gear_ratio", m.gear_ratio),
            ("manual.span_v", self.manual.span_v),
            ("thermal_time_constant_s", self.thermal_time_constant_s),
        ];
        for (name, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(SimError::Config(format!("{name} must be positive, got {value}")));
            }
        }
        let non_negative = [
            ("motor.coulomb_friction_nm", m.coulomb_friction_nm),
            ("motor.viscous_friction_nm_s_per_rad", m.viscous_friction_nm_s_per_rad),
            ("supply_v", self.supply_v),
            ("current_noise_ma", self.current_noise_ma),
            ("voltage_noise_mv", self.voltage_noise_mv),
            ("manual.deadband_v", self.manual.deadband_v),
            ("thermal_resistance_k_per_w", self.thermal_resistance_k_per_w),
        ];
        for (name, value) in non_negative {
            if !(value.is_finite() && value >= 0.0) {
                return Err(SimError::Config(format!("{name} must be >= 0, got {value}")));
            }
        }
        let positive_ints = [
            ("max_speed", self.max_speed),
            ("max_current_ma", self.max_current_ma),
            ("hardware_max_current_ma", self.hardware_max_current_ma),
            ("overcurrent_trip_ma", self.overcurrent_trip_ma),
            ("max_acceleration", self.max_acceleration),
            ("homing_speed", self.homing_speed),
            ("following_error_counts", self.following_error_counts),
        ];
        for (name, value) in positive_ints {
            if value <= 0 {
                return Err(SimError::Config(format!("{name} must be positive, got {value}")));
            }
        }
        if self.max_current_ma > self.hardware_max_current_ma {
            return Err(SimError::Config(format!(
                "max_current_ma {} exceeds hardware_max_current_ma {}",
                self.max_current_ma, self.hardware_max_current_ma
            )));
        }
        if let (Some(lo), Some(hi)) = (self.limit_switch_down_counts, self.limit_switch_up_counts) {
            if lo >= hi {
                return Err(SimError::Config(format!("limit switches inverted: down {lo} >= up {hi}")));
            }
        }
        if !self.initial_position_counts.is_finite() {
            return Err(SimError::Config("initial_position_counts must be finite".into()));
        }
        Ok(())
    }

    /// Copy with `seed` for the measurement noise.
    #[must_use]
    pub fn seeded(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_about_40_w() {
        let c = ControllerConfig::default();
        assert_eq!(c.validate(), Ok(()));
        let m = c.motor;
        // No-load speed about 6000 rpm at 24 V.
        let no_load_rpm = c.supply_v / m.torque_constant_nm_per_a * 60.0 / std::f64::consts::TAU;
        assert!((5500.0..6500.0).contains(&no_load_rpm), "{no_load_rpm}");
        // Maximum mechanical power (V^2 / 4R) well above 40 W; 40 W at about 2 A.
        let at_2a = (c.supply_v - 2.0 * m.resistance_ohm) * 2.0;
        assert!((38.0..48.0).contains(&at_2a), "{at_2a}");
    }

    #[test]
    fn bad_values_are_named() {
        let mut c = ControllerConfig::default();
        c.motor.inertia_kg_m2 = 0.0;
        assert!(matches!(c.validate(), Err(SimError::Config(m)) if m.contains("inertia")));
        let json = r#"{"max_speed": 5000, "motor": {"gear_ratio": 50.0}}"#;
        let c = ControllerConfig::from_json(json);
        assert_eq!(c.as_ref().map(|c| (c.max_speed, c.motor.gear_ratio)), Ok((5000, 50.0)));
        assert!(ControllerConfig::from_json(r#"{"bogus": 1}"#).is_err());
    }
}
