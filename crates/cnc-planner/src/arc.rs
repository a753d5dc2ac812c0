//! Arc linearisation within a chord tolerance.
//!
//! The chord of a circle of radius `r` over the angle `θ` deviates from the arc by the
//! sagitta `r (1 - cos(θ/2))`; the step angle is therefore `2 acos(1 - ε/r)` for a chord
//! tolerance `ε`. A radius that differs between start and end is interpolated linearly with
//! the angle (a flat spiral), as are the helix axis and every axis outside the plane.

use crate::item::{ArcDirection, Plane};
use crate::vector::{get, set};
use std::f64::consts::TAU;

/// Relative plus absolute radius difference accepted between start and end.
const RADIUS_MISMATCH_REL: f64 = 0.01;
const RADIUS_MISMATCH_ABS: f64 = 0.01;

/// An arc to split, with its start point.
pub(crate) struct ArcSpec<const N: usize> {
    pub start: [f64; N],
    pub end: [f64; N],
    pub centre: [f64; 2],
    pub plane: Plane,
    pub direction: ArcDirection,
    pub extra_turns: u32,
}

/// Points after the start (the last one is exactly `end`) such that every chord stays within
/// `tolerance` of the arc.
pub(crate) fn linearise<const N: usize>(
    arc: &ArcSpec<N>,
    tolerance: f64,
) -> Result<Vec<[f64; N]>, &'static str> {
    if N < 3 {
        return Err("arcs need at least three axes (X, Y, Z)");
    }
    let (i, j, _) = arc.plane.axes();
    let [ci, cj] = arc.centre;
    if !(ci.is_finite() && cj.is_finite()) {
        return Err("centre not finite");
    }
    let (si, sj) = (get(&arc.start, i) - ci, get(&arc.start, j) - cj);
    let (ei, ej) = (get(&arc.end, i) - ci, get(&arc.end, j) - cj);
    let r0 = si.hypot(sj);
    let r1 = ei.hypot(ej);
    if r0 < 1e-9 || r1 < 1e-9 {
        return Err("zero radius");
    }
    if (r0 - r1).abs() > RADIUS_MISMATCH_REL * r0.max(r1) + RADIUS_MISMATCH_ABS {
        return Err("start and end radii differ");
    }
    let a0 = sj.atan2(si);
    let a1 = ej.atan2(ei);
    // Angle swept in the programmed direction, in (0, 2 pi]: equal start and end angles
    // make a full circle.
    let base = match arc.direction {
        ArcDirection::CounterClockwise => (a1 - a0).rem_euclid(TAU),
        ArcDirection::Clockwise => (a0 - a1).rem_euclid(TAU),
    };
    let base = if base < 1e-12 { TAU } else { base };
    let magnitude = base + f64::from(arc.extra_turns) * TAU;
    let sweep = match arc.direction {
        ArcDirection::CounterClockwise => magnitude,
        ArcDirection::Clockwise => -magnitude,
    };
    let r = r0.max(r1);
    let step = if tolerance < r { 2.0 * (1.0 - tolerance / r).acos() } else { std::f64::consts::FRAC_PI_2 };
    let step = step.clamp(1e-6, std::f64::consts::FRAC_PI_2);
    let n = (sweep.abs() / step).ceil().max(1.0);
    let count = n as usize; // bounded: sweep/step, step >= 1e-6
    let mut out = Vec::with_capacity(count);
    for k in 1..count {
        let f = k as f64 / n;
        let phi = a0 + sweep * f;
        let rad = r0 + (r1 - r0) * f;
        let mut p = arc.start;
        p.iter_mut().zip(&arc.end).for_each(|(p, e)| *p += (e - *p) * f);
        set(&mut p, i, ci + rad * phi.cos());
        set(&mut p, j, cj + rad * phi.sin());
        out.push(p);
    }
    out.push(arc.end);
    Ok(out)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    fn spec(end: [f64; 3], dir: ArcDirection) -> ArcSpec<3> {
        ArcSpec {
            start: [10.0, 0.0, 0.0],
            end,
            centre: [0.0, 0.0],
            plane: Plane::Xy,
            direction: dir,
            extra_turns: 0,
        }
    }

    #[test]
    fn quarter_circle_chord_count_and_error() {
        // r = 10, tol = 0.01: step = 2 acos(0.999) = 0.089448 rad (hand computation);
        // a quarter turn (1.570796) needs ceil(17.56) = 18 chords.
        let pts = linearise(&spec([0.0, 10.0, 0.0], ArcDirection::CounterClockwise), 0.01).unwrap();
        assert_eq!(pts.len(), 18);
        let mut prev = [10.0, 0.0, 0.0];
        for p in &pts {
            assert!((p[0].hypot(p[1]) - 10.0).abs() < 1e-9);
            let mid = [(p[0] + prev[0]) / 2.0, (p[1] + prev[1]) / 2.0];
            let sag = 10.0 - mid[0].hypot(mid[1]);
            assert!(sag <= 0.01 + 1e-12 && sag > 0.005, "sagitta {sag}");
            assert!(p[1] >= prev[1]); // counter-clockwise from +X: Y grows
            prev = *p;
        }
        assert_eq!(pts.last().unwrap(), &[0.0, 10.0, 0.0]);
    }

    #[test]
    fn clockwise_goes_the_long_way_to_plus_y() {
        // From (10,0) clockwise to (0,10) is three quarters of a turn: 3 * 17.56 -> 53 chords.
        let pts = linearise(&spec([0.0, 10.0, 0.0], ArcDirection::Clockwise), 0.01).unwrap();
        assert_eq!(pts.len(), 53);
        assert!(pts[0][1] < 0.0); // first step goes towards -Y
    }

    #[test]
    fn helix_full_turn_moves_z_linearly() {
        let mut s = spec([10.0, 0.0, 6.0], ArcDirection::CounterClockwise);
        s.extra_turns = 1; // two full turns in total
        let pts = linearise(&s, 0.01).unwrap();
        // 4 pi / 0.089448 = 140.5 -> 141 chords
        assert_eq!(pts.len(), 141);
        let mid = pts[70];
        assert!((mid[2] - 6.0 * 71.0 / 141.0).abs() < 1e-9);
    }

    #[test]
    fn mismatched_radius_refused() {
        let r = linearise(&spec([0.0, 12.0, 0.0], ArcDirection::Clockwise), 0.01);
        assert_eq!(r, Err("start and end radii differ"));
    }
}
