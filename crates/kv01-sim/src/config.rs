//! Configuration of the simulated arm, with every default number in one place: per-joint
//! mechanics (gear, speed sign, resolver offset, soft limits and switches, brake, gravity,
//! speed-loop time constant), module timings, Faulhaber defaults, supply voltages, the
//! gripper's open/close motor, the simulation step and the seed.
//!
//! Times are plain numbers with a unit suffix (`_ms`, `_s`) so the JSON form (`--arm` in the
//! CLI) stays readable; [`ArmConfig::validate`] rejects values the model cannot run with.

use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::error::SimError;

/// Number of joints (and communication modules).
pub const JOINTS: usize = 6;

/// Resolver offsets of the spec's table (`specs/kv01.md`, "Joint offsets and soft limits").
pub const SPEC_OFFSETS_DEG: [f64; JOINTS] = [-81.85, 190.577, 91.962, -102.549, 252.451, 310.593];

/// Soft limits (lower, upper) of the spec's table; joints 4 and 6 have none.
pub const SPEC_SOFT_LIMITS_DEG: [Option<[f64; 2]>; JOINTS] =
    [Some([-120.0, 120.0]), Some([-90.0, 90.0]), Some([-132.0, 132.0]), None, Some([-135.0, 135.0]), None];

/// Which end of a joint's travel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    /// Towards negative joint angles.
    Lower,
    /// Towards positive joint angles.
    Upper,
}

/// Mechanics and sensors of one joint. Angles are joint angles as the spec defines them
/// (`raw * 360 / 2^bits - offset`); speeds at the motor are in rpm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct JointConfig {
    /// Motor revolutions per joint revolution.
    pub gear_ratio: f64,
    /// +1 or -1: direction of the joint angle for a positive motor speed (the source's
    /// polarity figure is lost).
    pub speed_sign: i8,
    /// Resolver offset in degrees (raw angle = joint angle + offset).
    pub resolver_offset_deg: f64,
    /// Resolver resolution: 16 bits per turn, 12 on the gripper module (right-aligned).
    pub resolver_bits: u8,
    /// Soft limits `[lower, upper]` of the spec's table, if any.
    pub soft_limits_deg: Option<[f64; 2]>,
    /// Whether limit switches guard the travel (joints 1, 2, 3, 5).
    pub limit_switch: bool,
    /// Distance from a soft limit to its switch (the switch is pressed beyond it).
    pub switch_beyond_soft_limit_deg: f64,
    /// Distance from a switch to the mechanical end stop.
    pub end_stop_beyond_switch_deg: f64,
    /// Whether the joint has an electromechanical brake (joints 1-5).
    pub brake: bool,
    /// Angular acceleration from gravity with the link horizontal (0: no gravity load).
    pub gravity_deg_s2: f64,
    /// The link's pitch adds the previous joint's pitch (joint 3 rides on joint 2).
    pub pitch_follows_previous: bool,
    /// Viscous damping of a free (disabled, unbraked) joint, 1/s: back-driven gearbox.
    pub free_damping_per_s: f64,
    /// Deceleration of a moving joint when its brake engages.
    pub brake_decel_deg_s2: f64,
    /// Time constant of the first-order speed loop.
    pub speed_loop_tau_ms: f64,
    /// Motor encoder increments per motor revolution (what `POS` counts).
    pub encoder_counts_per_rev: f64,
    /// Joint angle at the first power-on.
    pub initial_angle_deg: f64,
}

impl Default for JointConfig {
    /// Joint 1's values.
    fn default() -> Self {
        Self::spec(1)
    }
}

impl JointConfig {
    /// The default configuration of joint `joint` (1..=6; other numbers give joint 6's).
    #[must_use]
    pub fn spec(joint: u8) -> Self {
        let i = usize::from(joint.clamp(1, 6)) - 1;
        let pitch = matches!(joint, 2 | 3);
        Self {
            gear_ratio: match joint {
                1..=3 => 400.0,
                4 | 5 => 250.0,
                _ => 150.0,
            },
            speed_sign: 1,
            resolver_offset_deg: SPEC_OFFSETS_DEG.get(i).copied().unwrap_or_default(),
            resolver_bits: if joint == 6 { 12 } else { 16 },
            soft_limits_deg: SPEC_SOFT_LIMITS_DEG.get(i).copied().flatten(),
            limit_switch: matches!(joint, 1 | 2 | 3 | 5),
            switch_beyond_soft_limit_deg: 5.0,
            end_stop_beyond_switch_deg: 8.0,
            brake: joint <= 5,
            gravity_deg_s2: match joint {
                2 => 200.0,
                3 => 250.0,
                _ => 0.0,
            },
            pitch_follows_previous: joint == 3,
            free_damping_per_s: if pitch { 3.0 } else { 5.0 },
            brake_decel_deg_s2: 1500.0,
            speed_loop_tau_ms: 50.0,
            encoder_counts_per_rev: 2048.0,
            initial_angle_deg: match joint {
                2 => 15.0,
                3 => 30.0,
                _ => 0.0,
            },
        }
    }

    /// Joint degrees per second for one motor rpm (sign included).
    #[must_use]
    pub fn deg_s_per_rpm(&self) -> f64 {
        f64::from(self.speed_sign) * 6.0 / self.gear_ratio
    }

    /// Positions `[lower, upper]` at and beyond which the switches are pressed.
    #[must_use]
    pub fn switch_positions_deg(&self) -> Option<[f64; 2]> {
        let [lo, hi] = self.soft_limits_deg?;
        let m = self.switch_beyond_soft_limit_deg;
        self.limit_switch.then_some([lo - m, hi + m])
    }

    /// Mechanical end stops `[lower, upper]` (joints without switches turn endlessly).
    #[must_use]
    pub fn end_stops_deg(&self) -> Option<[f64; 2]> {
        let [lo, hi] = self.switch_positions_deg()?;
        let m = self.end_stop_beyond_switch_deg;
        Some([lo - m, hi + m])
    }

    fn validate(&self, joint: usize) -> Result<(), SimError> {
        let bad = |what: &str| Err(SimError::Config(format!("joint {joint}: {what}")));
        let finite = [
            self.gear_ratio,
            self.resolver_offset_deg,
            self.switch_beyond_soft_limit_deg,
            self.end_stop_beyond_switch_deg,
            self.gravity_deg_s2,
            self.free_damping_per_s,
            self.brake_decel_deg_s2,
            self.speed_loop_tau_ms,
            self.encoder_counts_per_rev,
            self.initial_angle_deg,
        ];
        if finite.iter().any(|v| !v.is_finite()) {
            return bad("every number must be finite");
        }
        if self.gear_ratio <= 0.0 || self.encoder_counts_per_rev <= 0.0 || self.speed_loop_tau_ms <= 0.0 {
            return bad("gear_ratio, encoder_counts_per_rev and speed_loop_tau_ms must be positive");
        }
        if self.speed_sign != 1 && self.speed_sign != -1 {
            return bad("speed_sign must be 1 or -1");
        }
        if self.resolver_bits != 12 && self.resolver_bits != 16 {
            return bad("resolver_bits must be 12 or 16");
        }
        if self.switch_beyond_soft_limit_deg < 0.0
            || self.end_stop_beyond_switch_deg < 0.0
            || self.free_damping_per_s < 0.0
            || self.brake_decel_deg_s2 <= 0.0
        {
            return bad("margins and damping must not be negative, brake_decel_deg_s2 must be positive");
        }
        if let Some([lo, hi]) = self.soft_limits_deg {
            if !(lo.is_finite() && hi.is_finite() && lo < 0.0 && hi > 0.0) {
                return bad("soft limits must be finite with lower < 0 < upper");
            }
        }
        if self.limit_switch && self.soft_limits_deg.is_none() {
            return bad("limit switches need soft limits");
        }
        Ok(())
    }
}

/// What a communication module does beyond forwarding: its timings and filters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CmConfig {
    /// Safety communication time-out (the spec: 700 ms).
    pub safety_timeout_ms: f64,
    /// How long the module waits for the controller's answer before replying "TIMEOUT",
    /// counted from the end of the forwarded request.
    pub controller_wait_ms: f64,
    /// Module processing time before any reply.
    pub turnaround_ms: f64,
    /// Baud rate of the module <-> controller link (the Faulhaber default, 9600).
    pub controller_baud: u32,
    /// Controller processing time between the request's CR and its answer.
    pub controller_latency_ms: f64,
    /// Largest |rpm| passed in restricted mode (the spec: 399).
    pub restricted_rpm: i32,
    /// How a D2 speed command blocked by LSSTOP/LIMVAL is answered.
    pub d2_refusal: D2Refusal,
}

impl Default for CmConfig {
    fn default() -> Self {
        Self {
            safety_timeout_ms: 700.0,
            controller_wait_ms: 50.0,
            turnaround_ms: 0.1,
            controller_baud: 9600,
            controller_latency_ms: 1.0,
            restricted_rpm: 399,
            d2_refusal: D2Refusal::Answer,
        }
    }
}

/// How a module answers a D2 message whose speed command it blocks (the source only says
/// blocked speed commands are answered "LSSTOP"/"LIMVAL", not what a D2 reply then holds).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum D2Refusal {
    /// A D0 reply with "LSSTOP" / "LIMVAL" (the refusal is visible to the host).
    #[default]
    Answer,
    /// The usual D2 resolver reply; only the LSSTOP / restricted-mode bits tell.
    Resolver,
}

/// Power-on settings of the Faulhaber controllers (what a `SAVE` would have stored).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerConfig {
    /// `ANSW`: 2 (every command confirmed), as the KV-01 manual's "EN" -> "OK" shows.
    pub answer_mode: u8,
    /// `SP`: maximum speed, rpm (limits `V` and positioning).
    pub max_speed_rpm: i32,
    /// Largest |argument| of `V` / `SP` accepted; above it: "Invalid parameter".
    pub rpm_range: i32,
    /// `AC`: acceleration, rev/s².
    pub acceleration: i32,
    /// `DEC`: deceleration, rev/s².
    pub deceleration: i32,
    /// `LPC`: peak current, mA.
    pub peak_current_ma: i32,
    /// `LCC`: continuous current, mA.
    pub continuous_current_ma: i32,
    /// Positioning corridor (increments) for "target reached".
    pub corridor: i32,
    /// `NODEADR`: node number (0 as shipped).
    pub node: u8,
    /// Controller baud rate (must equal the module's `controller_baud` to be reachable).
    pub baud: u32,
    /// Whether the limit-switch program runs after power-on (`ENPROG` + `SAVE`).
    pub program_enabled: bool,
    /// `VER` answer.
    pub version: String,
    /// `GTYP` answer.
    pub type_name: String,
    /// `GSER` of joint 1; joint n answers this + n - 1.
    pub first_serial: u32,
}

impl Default for ControllerConfig {
    fn default() -> Self {
        Self {
            answer_mode: 2,
            max_speed_rpm: 5000,
            rpm_range: 30_000,
            acceleration: 500,
            deceleration: 500,
            peak_current_ma: 2000,
            continuous_current_ma: 700,
            corridor: 20,
            node: 0,
            baud: 9600,
            program_enabled: true,
            version: "MCDC3006S V3.05 (motus kv01-sim)".into(),
            type_name: "MCDC 3006 S".into(),
            first_serial: 1_004_201,
        }
    }
}

/// Supply voltages a module measures (D4).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SupplyConfig {
    /// 24 V rail, volts.
    pub volts_24v: f64,
    /// 5 V rail, volts.
    pub volts_5v: f64,
    /// 12 V rail, volts.
    pub volts_12v: f64,
    /// Half-width of the uniform measurement noise, volts (0: exact).
    pub noise_volts: f64,
}

impl Default for SupplyConfig {
    fn default() -> Self {
        Self { volts_24v: 24.0, volts_5v: 5.0, volts_12v: 12.0, noise_volts: 0.03 }
    }
}

/// The gripper's open/close motor, driven by module 0xE6 itself (D5).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GripperConfig {
    /// Time for a full stroke (closed <-> open) at speed 31.
    pub full_stroke_s: f64,
    /// Load (0..=31) above which the motor is over-current.
    pub over_current_load: u8,
    /// Over-current duration after which the current limitation switches the motor off.
    pub trip_after_ms: f64,
    /// Opening at the first power-on, 0 (closed) ..= 1 (open).
    pub initial_opening: f64,
    /// Opening at which closing jaws meet an object (`None`: nothing between the jaws).
    pub object_opening: Option<f64>,
    /// Whether the current limitation is on after power-on.
    pub current_limit_at_power_on: bool,
}

impl Default for GripperConfig {
    fn default() -> Self {
        Self {
            full_stroke_s: 2.0,
            over_current_load: 16,
            trip_after_ms: 2000.0,
            initial_opening: 0.5,
            object_opening: None,
            current_limit_at_power_on: true,
        }
    }
}

/// The whole arm.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArmConfig {
    /// Joints 1..=6 (a joint given in JSON takes joint 1's values for missing fields).
    pub joints: [JointConfig; JOINTS],
    /// Communication modules (all six alike).
    pub cm: CmConfig,
    /// Faulhaber controllers (all six alike).
    pub controller: ControllerConfig,
    /// Supply voltages.
    pub supply: SupplyConfig,
    /// Gripper open/close motor.
    pub gripper: GripperConfig,
    /// Fixed simulation step, microseconds.
    pub step_us: u64,
    /// Seed of the measurement noise.
    pub seed: u64,
}

impl Default for ArmConfig {
    fn default() -> Self {
        Self {
            joints: [1, 2, 3, 4, 5, 6].map(JointConfig::spec),
            cm: CmConfig::default(),
            controller: ControllerConfig::default(),
            supply: SupplyConfig::default(),
            gripper: GripperConfig::default(),
            step_us: 1000,
            seed: 0,
        }
    }
}

impl ArmConfig {
    /// Parses the JSON form (missing fields take their defaults) and validates it.
    pub fn from_json(json: &str) -> Result<Self, SimError> {
        let config: Self = serde_json::from_str(json).map_err(|e| SimError::Config(e.to_string()))?;
        config.validate()?;
        Ok(config)
    }

    /// The simulation step.
    #[must_use]
    pub fn step(&self) -> Duration {
        Duration::from_micros(self.step_us)
    }

    /// Checks that the model can run with these numbers.
    pub fn validate(&self) -> Result<(), SimError> {
        for (i, j) in self.joints.iter().enumerate() {
            j.validate(i + 1)?;
        }
        if !(1..=100_000).contains(&self.step_us) {
            return Err(SimError::Config("step_us must be 1..=100000".into()));
        }
        let cm = &self.cm;
        let times = [
            cm.safety_timeout_ms,
            cm.controller_wait_ms,
            cm.turnaround_ms,
            cm.controller_latency_ms,
            self.gripper.trip_after_ms,
        ];
        if times.iter().any(|t| !t.is_finite() || *t < 0.0) || cm.controller_baud == 0 {
            return Err(SimError::Config("module times must be >= 0 and controller_baud > 0".into()));
        }
        let s = &self.supply;
        if [s.volts_24v, s.volts_5v, s.volts_12v, s.noise_volts].iter().any(|v| !v.is_finite() || *v < 0.0) {
            return Err(SimError::Config("supply voltages and noise must be finite and >= 0".into()));
        }
        let g = &self.gripper;
        let opening_ok = |x: f64| (0.0..=1.0).contains(&x);
        let stroke_ok = g.full_stroke_s.is_finite() && g.full_stroke_s > 0.0;
        if !(stroke_ok && opening_ok(g.initial_opening) && g.object_opening.map_or(true, opening_ok)) {
            return Err(SimError::Config("gripper: full_stroke_s > 0, openings within 0..=1".into()));
        }
        Ok(())
    }
}

/// A duration of `ms` milliseconds (0 for negative or non-finite input).
#[must_use]
pub(crate) fn millis(ms: f64) -> Duration {
    Duration::try_from_secs_f64(ms / 1000.0).unwrap_or(Duration::ZERO)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn defaults_follow_the_spec_table() {
        let c = ArmConfig::default();
        assert!(c.validate().is_ok());
        assert_eq!(c.joints[1].resolver_offset_deg, 190.577);
        assert_eq!(c.joints[0].switch_positions_deg(), Some([-125.0, 125.0]));
        assert_eq!(c.joints[3].switch_positions_deg(), None);
        assert_eq!(c.joints[5].resolver_bits, 12);
        // 400:1 gear: 1 rpm = 6 / 400 deg/s, 399 rpm = 5.985 deg/s.
        assert!((c.joints[0].deg_s_per_rpm() * 399.0 - 5.985).abs() < 1e-12);
    }

    #[test]
    fn json_round_trip_and_validation() {
        let c = ArmConfig::default();
        let json = serde_json::to_string(&c).unwrap();
        assert_eq!(ArmConfig::from_json(&json).unwrap(), c);
        assert!(ArmConfig::from_json(r#"{"step_us": 0}"#).is_err());
        assert!(ArmConfig::from_json(r#"{"bogus": 1}"#).is_err());
        let partial = ArmConfig::from_json(r#"{"supply": {"volts_24v": 23.5}}"#).unwrap();
        assert_eq!(partial.supply.volts_24v, 23.5);
        assert_eq!(partial.supply.volts_5v, 5.0);
    }
}
