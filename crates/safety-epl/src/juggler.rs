//! The simulated juggler on a POWERLINK segment: drive parameters and motion patterns derived
//! from a rules file (the shipped `juggler.toml`), so `motus sim epl --config juggler.toml`
//! runs the machine the supervisor guards.
//!
//! Each `[[axis]]` becomes the drive CN whose node ID is the axis `id`. Drive units are the
//! raw units of the PRes (`unit * raw_per_unit`); acceleration is the axis's worst-case
//! acceleration and the quick-stop deceleration its guaranteed braking (the smaller of up and
//! down), so the simulated drives are exactly as strong as the supervisor assumes.

use std::str::FromStr;
use std::time::Duration;

use motus_epl::sim::{CamAxis, CamProgram, DriveParams};
use motus_epl_protocol::{ValueMap, ValueSpec, ValueType};
use motus_safety::RuleSet;

/// Largest speed of the simulated drives in units/s (the juggler's arms: 5000 deg/s).
pub const MAX_SPEED_UNITS: f64 = 50_000.0;

/// A motion pattern for the simulated juggler.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pattern {
    /// The juggling cam: every axis moves, nothing comes near a rule (SafeToRun stays true).
    Juggle,
    /// A student error: the thrower's cam aims beyond its upper limit (the seed's test of an
    /// axis passing its limit).
    Limit,
    /// A student error: the arms swing inwards while the verticals cross.
    Collide,
}

impl Pattern {
    /// Every pattern, in the order the HMI lists them.
    pub const ALL: [Pattern; 3] = [Pattern::Juggle, Pattern::Limit, Pattern::Collide];

    /// The pattern's name (what [`FromStr`] reads).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Pattern::Juggle => "juggle",
            Pattern::Limit => "limit",
            Pattern::Collide => "collide",
        }
    }
}

impl FromStr for Pattern {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "juggle" => Ok(Pattern::Juggle),
            "limit" => Ok(Pattern::Limit),
            "collide" => Ok(Pattern::Collide),
            other => Err(format!("unknown pattern {other:?} (known: juggle, limit, collide)")),
        }
    }
}

/// Cam of each axis in algorithm units, by axis name: (center, amplitude, phase).
fn cam_units(pattern: Pattern, name: &str) -> (f64, f64, f64) {
    match (pattern, name) {
        (Pattern::Collide, "arm_left" | "arm_right") => (500.0, 300.0, 0.0),
        (_, "arm_left") => (-500.0, 300.0, 0.0),
        (_, "arm_right") => (-500.0, 300.0, 0.5),
        (_, "vertical_left") => (3000.0, 2000.0, 0.0),
        (Pattern::Collide, "vertical_right") => (4000.0, 3000.0, 0.5),
        (_, "vertical_right") => (14_000.0, 2000.0, 0.5),
        (Pattern::Limit, "thrower") => (0.0, 5000.0, 0.75),
        (_, "thrower") => (-3500.0, 2500.0, 0.25),
        _ => (0.0, 0.0, 0.0),
    }
}

/// Period of every cam (s).
pub const CAM_PERIOD: f64 = 2.0;

/// The cam program (raw drive units, axes in rules order).
pub fn program(rules: &RuleSet, pattern: Pattern) -> CamProgram {
    CamProgram::new(
        rules
            .axes()
            .iter()
            .map(|a| {
                let (c, amp, phase) = cam_units(pattern, &a.name);
                CamAxis {
                    center: c * a.raw_per_unit,
                    amplitude: amp * a.raw_per_unit,
                    period: CAM_PERIOD,
                    phase,
                }
            })
            .collect(),
    )
}

/// Node ID and drive parameters per axis (rules order), starting at the pattern's position
/// at t = 0; `lease_timeout` makes the drives require the supervisor's safety lease.
pub fn drives(rules: &RuleSet, pattern: Pattern, lease_timeout: Option<Duration>) -> Vec<(u8, DriveParams)> {
    let cam = program(rules, pattern);
    rules
        .axes()
        .iter()
        .zip(&cam.axes)
        .map(|(a, c)| {
            let k = a.raw_per_unit;
            let params = DriveParams {
                max_speed: MAX_SPEED_UNITS * k,
                max_accel: a.acceleration.up.min(a.acceleration.down) * k,
                brake_decel: a.braking.up.min(a.braking.down) * k,
                initial_position: c.at(0.0),
                lease_timeout,
                safety_node: None,
                soc_loss_tolerance: None,
            };
            (u8::try_from(a.id).unwrap_or(0), params)
        })
        .collect()
}

/// The value map of the simulated drives for the rules' nodes (status at 0, position at 16,
/// speed at 20; `motus_epl::sim::pdo`).
pub fn value_map(rules: &RuleSet) -> ValueMap {
    use motus_epl::sim::pdo::{PRES_POSITION_OFFSET, PRES_SPEED_OFFSET};
    let v = |name: &str, offset, ty| ValueSpec { name: name.into(), offset, ty };
    ValueMap {
        nodes: rules
            .axes()
            .iter()
            .map(|a| motus_epl_protocol::NodeValues {
                node: u8::try_from(a.id).unwrap_or(0),
                label: Some(a.name.clone()),
                values: vec![
                    v("status", 0, ValueType::U16),
                    v("position", PRES_POSITION_OFFSET, ValueType::I32),
                    v("speed", PRES_SPEED_OFFSET, ValueType::I32),
                ],
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use motus_safety::{CycleInput, Mode, Sample, Supervisor, JUGGLER_TOML};

    /// Evaluates the pattern's ideal trajectory (positions and speeds by finite differences)
    /// every 400 us over two periods; returns the first unsafe diagnosis.
    fn first_unsafe(pattern: Pattern) -> Option<(f64, String)> {
        let rules = RuleSet::from_toml(JUGGLER_TOML).unwrap();
        let cam = program(&rules, pattern);
        let mut sup = Supervisor::new(rules.clone());
        let dt = 0.0004;
        for k in 0..(2.0 * CAM_PERIOD / dt) as u64 {
            let t = k as f64 * dt;
            let samples: Vec<Option<Sample>> = rules
                .axes()
                .iter()
                .zip(&cam.axes)
                .map(|(a, c)| {
                    let p = c.at(t) / a.raw_per_unit;
                    let v = (c.at(t + 1e-6) - c.at(t)) / 1e-6 / a.raw_per_unit;
                    Some(Sample { position: p, speed: v, cycle: k, homed: true })
                })
                .collect();
            let input = CycleInput {
                now: Duration::from_secs_f64(t),
                cycle: k,
                mode: Mode::Normal,
                samples: &samples,
                params_ok: true,
            };
            let d = sup.evaluate(&input);
            if !d.safe_to_run() {
                return Some((t, d.diagnosis().map(ToString::to_string).unwrap_or_default()));
            }
        }
        None
    }

    #[test]
    fn juggle_is_safe_and_the_student_errors_are_not() {
        assert_eq!(first_unsafe(Pattern::Juggle), None);
        let (t, why) = first_unsafe(Pattern::Limit).unwrap();
        assert!(why.contains("limits_thrower"), "{t}: {why}");
        let (t, why) = first_unsafe(Pattern::Collide).unwrap();
        assert!(why.starts_with("rule "), "{t}: {why}");
    }

    #[test]
    fn drives_follow_the_axis_models() {
        let rules = RuleSet::from_toml(JUGGLER_TOML).unwrap();
        let d = drives(&rules, Pattern::Juggle, None);
        assert_eq!(d.iter().map(|(n, _)| *n).collect::<Vec<_>>(), [1, 2, 3, 4, 5]);
        // thrower: 2 000 000 units/s² at 10 raw per unit.
        assert_eq!(d[4].1.brake_decel, 20_000_000.0);
        assert_eq!(d[0].1.max_accel, 500_000.0);
        // thrower starts at -4000 + 3000 sin(π/2) = -1000 units = -10 000 raw.
        assert!((d[4].1.initial_position + 10_000.0).abs() < 1e-6);
    }

    /// The shipped drive-parameter file describes these simulated drives: node ids from the
    /// rules, a_stop their braking and the acceleration limits their acceleration (raw units),
    /// encoder scaling the axis's raw_per_unit.
    #[test]
    fn the_shipped_drive_parameters_are_the_simulated_drives() {
        let rules = RuleSet::from_toml(JUGGLER_TOML).unwrap();
        let file = motus_safety::DrivesFile::from_toml(motus_safety::JUGGLER_DRIVES_TOML).unwrap();
        let sim = drives(&rules, Pattern::Juggle, None);
        assert_eq!(file.drive.len(), sim.len());
        for ((axis, (node, params)), d) in rules.axes().iter().zip(&sim).zip(&file.drive) {
            assert_eq!(d.axis, axis.name);
            assert_eq!(d.node_id, u32::from(*node));
            assert_eq!(d.a_stop, params.brake_decel, "{}", d.axis);
            assert_eq!(d.accel_limits, [params.max_accel; 4], "{}", d.axis);
            assert_eq!(d.encoder_scaling, axis.raw_per_unit, "{}", d.axis);
        }
    }
}
