//! Arc centre computation and checks, after LinuxCNC's `arc_data_ijk` / `arc_data_r`.
//!
//! All values are in one plane, "first" and "second" coordinate, in program units.

use crate::canon::Units;
use crate::error::ErrorKind;

/// LinuxCNC's `TOLERANCE_MM` / `TOLERANCE_INCH` (R-format reach check).
fn tolerance(units: Units) -> f64 {
    match units {
        Units::Mm => 0.005,
        Units::Inch => 0.0005,
    }
}

/// LinuxCNC's `CENTER_ARC_RADIUS_TOLERANCE_*` = 2 * sqrt(2) * (0.01 mm | 0.001 inch).
fn radius_tolerance(units: Units) -> f64 {
    match units {
        Units::Mm => 2.0 * 0.01 * std::f64::consts::SQRT_2,
        Units::Inch => 2.0 * 0.001 * std::f64::consts::SQRT_2,
    }
}

/// Centre of an I/J/K arc. `ij` are the two centre words of the plane (absolute when
/// `absolute` (G90.1), else relative to the start).
pub(crate) fn centre_ijk(
    units: Units,
    start: (f64, f64),
    end: (f64, f64),
    ij: (f64, f64),
    absolute: bool,
    axes: (char, char),
) -> Result<(f64, f64), ErrorKind> {
    let c = if absolute { ij } else { (start.0 + ij.0, start.1 + ij.1) };
    let tol = radius_tolerance(units);
    let r1 = (c.0 - start.0).hypot(c.1 - start.1);
    let r2 = (c.0 - end.0).hypot(c.1 - end.1);
    if r1 < 0.1 * tol || r2 < 0.1 * tol {
        return Err(ErrorKind::ZeroRadiusArc);
    }
    let abs_err = (r1 - r2).abs();
    let rel_err = abs_err / r1.max(r2);
    if abs_err > 100.0 * tol || (rel_err > 0.001 && abs_err > tol) {
        return Err(ErrorKind::ArcRadiusMismatch {
            axes,
            start,
            centre: c,
            end,
            r1,
            r2,
            abs_err,
            rel_err: rel_err * 100.0,
        });
    }
    Ok(c)
}

/// Centre of an R arc (`radius` < 0 asks for the arc longer than a semicircle).
pub(crate) fn centre_r(
    units: Units,
    start: (f64, f64),
    end: (f64, f64),
    radius: f64,
    clockwise: bool,
) -> Result<(f64, f64), ErrorKind> {
    if end == start {
        return Err(ErrorKind::ArcSameEndPoint);
    }
    let abs_radius = radius.abs();
    let mid = ((end.0 + start.0) / 2.0, (end.1 + start.1) / 2.0);
    let mut half_length = (mid.0 - end.0).hypot(mid.1 - end.1);
    if half_length - abs_radius > tolerance(units) {
        return Err(ErrorKind::ArcRadiusTooSmall);
    }
    if half_length / abs_radius > 1.0 - 1e-12 {
        half_length = abs_radius;
    }
    let dir = (end.1 - start.1).atan2(end.0 - start.0);
    let theta = if (clockwise && radius > 0.0) || (!clockwise && radius < 0.0) {
        dir - std::f64::consts::FRAC_PI_2
    } else {
        dir + std::f64::consts::FRAC_PI_2
    };
    let turn2 = (half_length / abs_radius).asin();
    let offset = abs_radius * turn2.cos();
    Ok((mid.0 + offset * theta.cos(), mid.1 + offset * theta.sin()))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn r_form_semicircle_and_quarter() {
        // From (0,0) to (10,0) with R5: the centre is the midpoint (5,0).
        let c = centre_r(Units::Mm, (0.0, 0.0), (10.0, 0.0), 5.0, true).unwrap();
        assert!((c.0 - 5.0).abs() < 1e-12 && c.1.abs() < 1e-12);
        // G2 from (0,0) to (1,1) R1: clockwise short arc, centre (1,0) (by hand).
        let c = centre_r(Units::Mm, (0.0, 0.0), (1.0, 1.0), 1.0, true).unwrap();
        assert!((c.0 - 1.0).abs() < 1e-12 && c.1.abs() < 1e-12, "{c:?}");
        // G3 same points: centre (0,1).
        let c = centre_r(Units::Mm, (0.0, 0.0), (1.0, 1.0), 1.0, false).unwrap();
        assert!(c.0.abs() < 1e-12 && (c.1 - 1.0).abs() < 1e-12, "{c:?}");
    }

    #[test]
    fn ijk_tolerance_rule() {
        // r1 = 10, r2 = 10.02: abs_err 0.02 < tol 0.028 -> accepted.
        assert!(centre_ijk(Units::Mm, (0.0, 0.0), (20.02, 0.0), (10.0, 0.0), false, ('X', 'Y')).is_ok());
        // r2 = 10.03: abs_err 0.03 > tol and rel_err 0.3 % > 0.1 % -> rejected.
        assert!(centre_ijk(Units::Mm, (0.0, 0.0), (20.03, 0.0), (10.0, 0.0), false, ('X', 'Y')).is_err());
        // r1 = 1000, r2 = 1000.5: rel_err 0.05 % < 0.1 % and abs_err < 100 tol -> accepted.
        assert!(centre_ijk(Units::Mm, (0.0, 0.0), (2000.5, 0.0), (1000.0, 0.0), false, ('X', 'Y')).is_ok());
    }
}
