//! Machine limits and planner settings.

use crate::error::ConfigError;
use serde::{Deserialize, Serialize};

/// Limits of one axis in CNC units (mm or degrees) and seconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AxisLimits {
    /// Maximum speed (units/s), also the rapid rate of this axis.
    pub velocity: f64,
    /// Maximum acceleration and deceleration (units/s²).
    pub acceleration: f64,
}

/// Settings of the planner and the executor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Config<const N: usize> {
    /// Per-axis limits, never exceeded by the executed set-points.
    #[serde(with = "limits_array")]
    pub axes: [AxisLimits; N],
    /// Allowed deviation of the blended path from the programmed corner points (units).
    /// Zero gives exact stops at every corner.
    pub path_tolerance: f64,
    /// Allowed chord error when arcs are split into lines (units).
    pub chord_tolerance: f64,
    /// Share (0.05..=0.95) of a blend's acceleration budget given to the centripetal part;
    /// the rest is left for speeding up or slowing down inside the blend.
    pub blend_centripetal_share: f64,
    /// Maximum number of planned pieces ahead of the executor; `push` refuses beyond it.
    pub buffer_capacity: usize,
    /// Number of executed pieces kept for backward motion.
    pub history: usize,
}

impl<const N: usize> Config<N> {
    /// Configuration with the given limits and the default tolerances
    /// (path 0.05, chord 0.01, centripetal share 0.8, 100 000 pieces ahead, 10 000 behind).
    pub fn new(axes: [AxisLimits; N]) -> Self {
        Self {
            axes,
            path_tolerance: 0.05,
            chord_tolerance: 0.01,
            blend_centripetal_share: 0.8,
            buffer_capacity: 100_000,
            history: 10_000,
        }
    }

    /// Checks every value.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if N == 0 {
            return Err(ConfigError::NoAxes);
        }
        for (axis, l) in self.axes.iter().enumerate() {
            if !(l.velocity.is_finite() && l.velocity > 0.0) {
                return Err(ConfigError::Velocity { axis, value: l.velocity });
            }
            if !(l.acceleration.is_finite() && l.acceleration > 0.0) {
                return Err(ConfigError::Acceleration { axis, value: l.acceleration });
            }
        }
        if !(self.path_tolerance.is_finite() && self.path_tolerance >= 0.0) {
            return Err(ConfigError::PathTolerance(self.path_tolerance));
        }
        if !(self.chord_tolerance.is_finite() && self.chord_tolerance > 0.0) {
            return Err(ConfigError::ChordTolerance(self.chord_tolerance));
        }
        if !(0.05..=0.95).contains(&self.blend_centripetal_share) {
            return Err(ConfigError::CentripetalShare(self.blend_centripetal_share));
        }
        if self.buffer_capacity < 4 {
            return Err(ConfigError::BufferCapacity(self.buffer_capacity));
        }
        Ok(())
    }
}

/// Serde support for `[AxisLimits; N]`.
mod limits_array {
    use super::AxisLimits;
    use serde::de::Error as _;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer, const N: usize>(v: &[AxisLimits; N], s: S) -> Result<S::Ok, S::Error> {
        v.as_slice().serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<[AxisLimits; N], D::Error> {
        let v = Vec::<AxisLimits>::deserialize(d)?;
        let len = v.len();
        v.try_into().map_err(|_| D::Error::custom(format!("expected {N} axes, got {len}")))
    }
}
