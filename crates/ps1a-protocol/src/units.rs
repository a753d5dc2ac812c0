//! Speed and acceleration numbers in physical units — the one place that says how.
//!
//! **Speed** (from the source): at speed value `V` the DDA adds `V * DS / 256` encoder
//! units per DDA cycle `T`, so `v = V * DS / 256 / T` units/s. With the defaults (DS = 39,
//! T = 1.54 ms) V = 1 gives 0.152 units per cycle, about 98.9 units/s (the source rounds
//! DS = 0.154 * 256 = 39.4 down to 39, so "1 mm/s at 0.01 mm" is really 0.989 mm/s).
//!
//! **Acceleration** (the source's formula was lost; this is our documented choice): the
//! acceleration number `A` (1..=10) is the change of the speed value per DDA cycle, so the
//! DDA's per-cycle increment grows by `A * DS / 256` units each cycle and
//! `a = A * DS / 256 / T^2` units/s^2. With the defaults, A = 1 is about 64 200 units/s^2
//! (0.64 m/s^2 at 0.01 mm per unit) and A = 10 about 6.4 m/s^2: the range of a typical
//! servo axis. The simulator's DDA and the driver's conversions both use these functions.

use crate::parameters::{Acceleration, DdaCycle};

/// Velocity in encoder units per second for speed value `v`.
pub fn velocity_units_per_s(v: u16, ds: u8, cycle: DdaCycle) -> f64 {
    f64::from(v) * f64::from(ds) / 256.0 / cycle.seconds()
}

/// Acceleration in encoder units per second squared for acceleration number `a`.
pub fn acceleration_units_per_s2(a: Acceleration, ds: u8, cycle: DdaCycle) -> f64 {
    let t = cycle.seconds();
    f64::from(a.get()) * f64::from(ds) / 256.0 / (t * t)
}

/// The speed value closest to `units_per_s` (clamped to 0..=65535; `None` if DS is 0).
pub fn speed_value_for(units_per_s: f64, ds: u8, cycle: DdaCycle) -> Option<u16> {
    if ds == 0 || !units_per_s.is_finite() {
        return None;
    }
    let v = (units_per_s.abs() * cycle.seconds() * 256.0 / f64::from(ds)).round();
    Some(v.clamp(0.0, f64::from(u16::MAX)) as u16)
}

/// The largest acceleration number whose acceleration does not exceed `units_per_s2`
/// (at least 1; `None` if DS is 0).
pub fn acceleration_number_for(units_per_s2: f64, ds: u8, cycle: DdaCycle) -> Option<Acceleration> {
    if ds == 0 || !units_per_s2.is_finite() {
        return None;
    }
    let per_step = acceleration_units_per_s2(Acceleration::MIN, ds, cycle);
    let n = (units_per_s2.abs() / per_step).floor().clamp(1.0, 10.0) as u8;
    Acceleration::new(n)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used)]
    use super::*;

    #[test]
    fn source_example_speed() {
        // Source: DS = 39 at T = 1.54 ms; V = 1 -> 39/256 units per cycle.
        let v = velocity_units_per_s(1, 39, DdaCycle::Ms1_54);
        assert!((v - 39.0 / 256.0 / 1.54e-3).abs() < 1e-9);
        assert!((v - 98.92).abs() < 0.01);
    }

    #[test]
    fn inverse_mappings() {
        assert_eq!(speed_value_for(98.92 * 100.0, 39, DdaCycle::Ms1_54), Some(100));
        let a = acceleration_units_per_s2(Acceleration::new(8).unwrap(), 39, DdaCycle::Ms1_54);
        assert_eq!(acceleration_number_for(a + 1.0, 39, DdaCycle::Ms1_54).map(Acceleration::get), Some(8));
        assert_eq!(speed_value_for(1.0, 0, DdaCycle::Ms1_54), None);
    }
}
