//! Axis models: what the supervisor knows about each axis (units, end limits,
//! worst-case acceleration, braking deceleration, size) and their validation.
//!
//! All values are in the axis's *algorithm unit* (`unit`): positions in units,
//! speeds in units/s, accelerations in units/s^2. Raw drive values are converted with
//! `raw_per_unit` (the juggler's axis 5 publishes 100 raw units per mm and the
//! algorithm works in 0.1 mm, so `raw_per_unit = 10`; see specs/juggler-safety.md).

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Length or angle unit of an axis, as written in the config (`unit = "0.1deg"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Unit {
    /// Tenth of a degree (juggler arms: 1 deg = 10 units).
    #[serde(rename = "0.1deg")]
    TenthDegree,
    /// Degree.
    #[serde(rename = "deg")]
    Degree,
    /// Tenth of a millimetre (juggler vertical axes: 1 mm = 10 units).
    #[serde(rename = "0.1mm")]
    TenthMillimetre,
    /// Hundredth of a millimetre.
    #[serde(rename = "0.01mm")]
    HundredthMillimetre,
    /// Millimetre.
    #[serde(rename = "mm")]
    Millimetre,
    /// Micrometre.
    #[serde(rename = "um")]
    Micrometre,
}

impl Unit {
    /// Parses the config spelling of a unit.
    pub fn parse(s: &str) -> Result<Unit, ModelError> {
        Ok(match s {
            "0.1deg" => Unit::TenthDegree,
            "deg" => Unit::Degree,
            "0.1mm" => Unit::TenthMillimetre,
            "0.01mm" => Unit::HundredthMillimetre,
            "mm" => Unit::Millimetre,
            "um" => Unit::Micrometre,
            other => return Err(ModelError::UnknownUnit(other.to_string())),
        })
    }

    /// Config spelling of the unit (inverse of [`Unit::parse`]).
    pub fn as_str(self) -> &'static str {
        match self {
            Unit::TenthDegree => "0.1deg",
            Unit::Degree => "deg",
            Unit::TenthMillimetre => "0.1mm",
            Unit::HundredthMillimetre => "0.01mm",
            Unit::Millimetre => "mm",
            Unit::Micrometre => "um",
        }
    }

    /// True for angular units (rotary axes), false for linear ones.
    pub fn is_angular(self) -> bool {
        matches!(self, Unit::TenthDegree | Unit::Degree)
    }
}

/// A value given separately for the positive ("up") and negative ("down") direction,
/// like the seed's `AXIS_X_ACCELERATION_UP` / `_DOWN` pairs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UpDown {
    /// Value for the positive direction.
    pub up: f64,
    /// Value for the negative direction.
    pub down: f64,
}

impl UpDown {
    /// The same value both ways.
    pub const fn both(v: f64) -> UpDown {
        UpDown { up: v, down: v }
    }
}

/// End limits of an axis (`min < max`, in units).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Limits {
    /// Lowest allowed position.
    pub min: f64,
    /// Highest allowed position.
    pub max: f64,
}

/// Model of one supervised axis (one `[[axis]]` table of the config).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisModel {
    /// Name used in rules and diagnoses (`arm_left`).
    pub name: String,
    /// Number of the axis in the machine documentation (1..5 for the juggler); rules may
    /// refer to an axis by this number.
    pub id: u32,
    /// Algorithm unit of positions (config spelling, see [`Unit`]).
    pub unit: String,
    /// Raw drive units per algorithm unit (encoder scaling seen by the supervisor).
    #[serde(default = "one")]
    pub raw_per_unit: f64,
    /// End limits (units).
    pub limits: Limits,
    /// Worst-case acceleration the axis can reach in each direction (units/s^2).
    pub acceleration: UpDown,
    /// Guaranteed braking deceleration on quick stop in each direction (units/s^2).
    pub braking: UpDown,
    /// Size of the moving part beyond its position, each way (units), used by collision rules.
    #[serde(default = "zero_updown")]
    pub oversize: UpDown,
    /// Positions are meaningless until the axis is homed (incremental encoder).
    #[serde(default = "yes")]
    pub homing_required: bool,
    /// In homing mode, highest speed magnitude (units/s) an un-homed axis may have.
    #[serde(default)]
    pub homing_speed_max: f64,
}

fn one() -> f64 {
    1.0
}
fn yes() -> bool {
    true
}
fn zero_updown() -> UpDown {
    UpDown::both(0.0)
}

/// A problem found while validating an axis model; every variant names the axis.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ModelError {
    /// The unit string is not one of [`Unit`]'s spellings.
    #[error("unknown unit {0:?} (expected 0.1deg, deg, 0.1mm, 0.01mm, mm or um)")]
    UnknownUnit(String),
    /// A problem with a named axis.
    #[error("axis {axis:?}: {problem}")]
    Axis {
        /// Name of the axis.
        axis: String,
        /// What is wrong.
        problem: String,
    },
    /// Two axes share a name or a number.
    #[error("duplicate axis {0:?}")]
    Duplicate(String),
}

impl AxisModel {
    /// Parsed unit (validated by [`AxisModel::validate`]).
    pub fn unit(&self) -> Result<Unit, ModelError> {
        Unit::parse(&self.unit).map_err(|e| self.err(e.to_string()))
    }

    fn err(&self, problem: String) -> ModelError {
        ModelError::Axis { axis: self.name.clone(), problem }
    }

    /// Checks that the model is physically possible: finite numbers, `min < max`,
    /// accelerations >= 0, braking > 0, oversize >= 0, a known unit and a positive scale.
    pub fn validate(&self) -> Result<(), ModelError> {
        if self.name.is_empty() || !self.name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return Err(self.err("name must be non-empty [A-Za-z0-9_]".into()));
        }
        if self.name.chars().all(|c| c.is_ascii_digit()) {
            return Err(self.err("name must not be a bare number (numbers refer to ids)".into()));
        }
        self.unit()?;
        let finite = [
            ("limits.min", self.limits.min),
            ("limits.max", self.limits.max),
            ("acceleration.up", self.acceleration.up),
            ("acceleration.down", self.acceleration.down),
            ("braking.up", self.braking.up),
            ("braking.down", self.braking.down),
            ("oversize.up", self.oversize.up),
            ("oversize.down", self.oversize.down),
            ("raw_per_unit", self.raw_per_unit),
            ("homing_speed_max", self.homing_speed_max),
        ];
        for (field, v) in finite {
            if !v.is_finite() {
                return Err(self.err(format!("{field} is not a finite number ({v})")));
            }
        }
        if self.limits.min >= self.limits.max {
            return Err(
                self.err(format!("impossible limits: min {} >= max {}", self.limits.min, self.limits.max))
            );
        }
        for (field, v) in [
            ("acceleration.up", self.acceleration.up),
            ("acceleration.down", self.acceleration.down),
            ("oversize.up", self.oversize.up),
            ("oversize.down", self.oversize.down),
            ("homing_speed_max", self.homing_speed_max),
        ] {
            if v < 0.0 {
                return Err(self.err(format!("{field} must be >= 0 (got {v})")));
            }
        }
        for (field, v) in [
            ("braking.up", self.braking.up),
            ("braking.down", self.braking.down),
            ("raw_per_unit", self.raw_per_unit),
        ] {
            if v <= 0.0 {
                return Err(self.err(format!("{field} must be > 0 (got {v})")));
            }
        }
        Ok(())
    }

    /// Converts raw drive values (as read from the PRes payload) to algorithm units.
    pub fn from_raw(&self, raw: i32) -> f64 {
        f64::from(raw) / self.raw_per_unit
    }
}

/// Validates a set of axes: each valid, names and ids unique.
pub fn validate_axes(axes: &[AxisModel]) -> Result<(), ModelError> {
    for (i, a) in axes.iter().enumerate() {
        a.validate()?;
        for b in axes.iter().skip(i + 1) {
            if a.name == b.name {
                return Err(ModelError::Duplicate(a.name.clone()));
            }
            if a.id == b.id {
                return Err(ModelError::Duplicate(format!("id {} ({} and {})", a.id, a.name, b.name)));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    fn arm() -> AxisModel {
        AxisModel {
            name: "arm_left".into(),
            id: 1,
            unit: "0.1deg".into(),
            raw_per_unit: 1.0,
            limits: Limits { min: -1000.0, max: 1000.0 },
            acceleration: UpDown::both(500_000.0),
            braking: UpDown::both(1_600_000.0),
            oversize: UpDown::both(0.0),
            homing_required: true,
            homing_speed_max: 100.0,
        }
    }

    #[test]
    fn valid_arm() {
        arm().validate().unwrap();
        assert!(arm().unit().unwrap().is_angular());
    }

    #[test]
    fn swapped_limits_of_the_seed_table_are_refused() {
        // The seed's table prints LIMIT_UP = -1000, LIMIT_DOWN = 1000 (signs swapped).
        let mut a = arm();
        a.limits = Limits { min: 1000.0, max: -1000.0 };
        let e = a.validate().unwrap_err();
        assert_eq!(e.to_string(), "axis \"arm_left\": impossible limits: min 1000 >= max -1000");
    }

    #[test]
    fn non_positive_braking_and_unknown_unit() {
        let mut a = arm();
        a.braking.down = 0.0;
        assert!(a.validate().unwrap_err().to_string().contains("braking.down must be > 0"));
        let mut a = arm();
        a.unit = "inch".into();
        let e = a.validate().unwrap_err().to_string();
        assert!(e.contains("arm_left") && e.contains("unknown unit \"inch\""), "{e}");
        let mut a = arm();
        a.acceleration.up = f64::NAN;
        assert!(a.validate().unwrap_err().to_string().contains("acceleration.up is not a finite"));
    }

    #[test]
    fn duplicates() {
        let mut b = arm();
        b.name = "arm_right".into();
        assert!(matches!(validate_axes(&[arm(), b]), Err(ModelError::Duplicate(_))));
    }

    #[test]
    fn raw_scaling_of_axis_5() {
        // specs/juggler-safety.md: axis 5 has 100 raw units/mm, algorithm 10 units/mm.
        let mut a = arm();
        a.raw_per_unit = 10.0;
        assert_eq!(a.from_raw(-76_000), -7600.0);
    }
}
