//! Conversion between device units and SI units.

use serde::{Deserialize, Serialize};

/// Whether an axis moves along a line (SI unit: metre) or turns (SI unit: radian).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum UnitKind {
    /// Positions in metres, velocities in m/s.
    #[default]
    Linear,
    /// Positions in radians, velocities in rad/s.
    Rotary,
}

impl UnitKind {
    /// The SI unit symbol of a position of this kind (`m` or `rad`).
    pub fn symbol(self) -> &'static str {
        match self {
            UnitKind::Linear => "m",
            UnitKind::Rotary => "rad",
        }
    }
}

/// Invalid scale configuration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScaleError {
    /// The SI size of one device unit must be finite and non-zero.
    #[error("invalid scale: one device unit must be a finite, non-zero SI length or angle (got {0})")]
    InvalidUnitSize(f64),
    /// The offset must be finite.
    #[error("invalid scale: offset must be finite (got {0})")]
    InvalidOffset(f64),
}

/// Linear map between raw device units and SI: `si = raw * si_per_unit - offset_si`.
///
/// A negative `si_per_unit` inverts the direction (the per-joint sign of the KV-01).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Scale {
    kind: UnitKind,
    si_per_unit: f64,
    offset_si: f64,
}

impl Scale {
    /// One device unit is 0.01 mm (1e-5 m), no offset: a common linear encoder scale.
    pub const HUNDREDTH_MM: Scale = Scale { kind: UnitKind::Linear, si_per_unit: 1e-5, offset_si: 0.0 };

    /// A scale where one device unit is `si_per_unit` metres or radians, with no offset.
    pub fn new(kind: UnitKind, si_per_unit: f64) -> Result<Self, ScaleError> {
        Self::with_offset(kind, si_per_unit, 0.0)
    }

    /// A scale with an offset subtracted after scaling (`si = raw * k - offset`).
    pub fn with_offset(kind: UnitKind, si_per_unit: f64, offset_si: f64) -> Result<Self, ScaleError> {
        if !si_per_unit.is_finite() || si_per_unit == 0.0 {
            return Err(ScaleError::InvalidUnitSize(si_per_unit));
        }
        if !offset_si.is_finite() {
            return Err(ScaleError::InvalidOffset(offset_si));
        }
        Ok(Scale { kind, si_per_unit, offset_si })
    }

    /// Linear or rotary.
    pub fn kind(&self) -> UnitKind {
        self.kind
    }

    /// The SI size of one device unit (metres or radians, signed).
    pub fn si_per_unit(&self) -> f64 {
        self.si_per_unit
    }

    /// Raw position -> SI position.
    pub fn position_to_si(&self, raw: f64) -> f64 {
        raw * self.si_per_unit - self.offset_si
    }

    /// SI position -> raw position (not rounded).
    pub fn position_from_si(&self, si: f64) -> f64 {
        (si + self.offset_si) / self.si_per_unit
    }

    /// Raw distance, velocity or acceleration -> SI (no offset).
    pub fn rate_to_si(&self, raw: f64) -> f64 {
        raw * self.si_per_unit
    }

    /// SI distance, velocity or acceleration -> raw (no offset, not rounded).
    pub fn rate_from_si(&self, si: f64) -> f64 {
        si / self.si_per_unit
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used)]
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn rejects_zero_and_nan() {
        assert!(Scale::new(UnitKind::Linear, 0.0).is_err());
        assert!(Scale::new(UnitKind::Linear, f64::NAN).is_err());
        assert!(Scale::with_offset(UnitKind::Linear, 1.0, f64::INFINITY).is_err());
    }

    #[test]
    fn hundredth_of_a_millimetre() {
        let s = Scale::new(UnitKind::Linear, 1e-5).unwrap();
        assert!((s.position_to_si(100_000.0) - 1.0).abs() < 1e-12);
        assert!((s.rate_from_si(0.001) - 100.0).abs() < 1e-9);
    }

    proptest! {
        #[test]
        fn position_round_trip(raw in -1.0e9f64..1.0e9, k in prop_oneof![1e-9f64..1e3, -1e3f64..-1e-9], off in -1e3f64..1e3) {
            let s = Scale::with_offset(UnitKind::Rotary, k, off).unwrap();
            let back = s.position_from_si(s.position_to_si(raw));
            prop_assert!((back - raw).abs() <= 1e-6 * raw.abs().max(1.0) + off.abs() / k.abs() * 1e-12);
        }
    }
}
