//! Synchronised wheel profiles against motus-axis's trapezoid planner (an independent
//! implementation): every wheel of a move takes the same time, within 1 ms.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_axis::profile::Plan;
use motus_omni::sync_profile::{duration_spread, synchronise, trapezoid_duration, wheel_profiles};
use motus_omni::{Geometry, Motion, Program, Ramp, Step};
use proptest::prelude::*;

fn program_travels() -> Vec<[f64; 3]> {
    let g = Geometry::default();
    let mut out = Vec::new();
    for p in [Program::line(), Program::square(), Program::octagon()] {
        for s in &p.steps {
            if let Step::Relative { x, y } = *s {
                let m = Motion::new(g.inc_to_metres(f64::from(x)), g.inc_to_metres(f64::from(y)), 0.0);
                out.push(g.inverse_inc(m));
            }
        }
    }
    out
}

/// Time a trapezoid by brute-force integration (dt = 10 us): accelerate at `a` until `v`,
/// cruise, and brake at `d` as soon as the braking distance reaches what is left.
fn simulated_duration(s: f64, v: f64, a: f64, d: f64) -> f64 {
    let dt = 1e-5;
    let (mut x, mut u, mut t) = (0.0f64, 0.0f64, 0.0f64);
    let s = s.abs();
    let mut braking = false;
    while x < s - 1e-9 {
        let left = s - x;
        braking |= u * u / (2.0 * d) >= left;
        if braking {
            u -= d * dt;
            if u <= 0.0 {
                t += dt;
                break;
            }
        } else {
            u = (u + a * dt).min(v);
        }
        x += u * dt;
        t += dt;
    }
    assert!((x - s).abs() < 0.05, "brute force ended at {x} of {s}");
    t
}

#[test]
fn asymmetric_trapezoid_against_brute_force() {
    for (s, v, a, d) in
        [(1065.0, 248.0, 1000.0, 400.0), (50.0, 500.0, 1000.0, 400.0), (532.5, 124.0, 500.0, 200.0)]
    {
        let closed = trapezoid_duration(s, v, a, d);
        let sim = simulated_duration(s, v, a, d);
        assert!((closed - sim).abs() < 2e-3, "{s} {v} {a} {d}: {closed} vs {sim}");
    }
}

#[test]
fn programs_symmetric_ramp_with_axis_planner() {
    // motus-axis plans with one acceleration for both ramps: use acc = dec.
    let base = Ramp { velocity: 248.0, acceleration: 400.0, deceleration: 400.0 };
    for travel in program_travels() {
        let prof = synchronise(travel, base);
        let durations: Vec<f64> = travel
            .iter()
            .zip(&prof)
            .filter(|(s, _)| s.abs() > 1e-9)
            .map(|(s, p)| Plan::to_target(0.0, 0.0, *s, p.velocity, p.acceleration).duration())
            .collect();
        let max = durations.iter().copied().fold(0.0, f64::max);
        let min = durations.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(max - min < 1e-3, "{travel:?}: {durations:?}");
        // And the closed form agrees with the planner.
        let longest = travel.iter().fold(0.0f64, |m, s| m.max(s.abs()));
        assert!((trapezoid_duration(longest, 248.0, 400.0, 400.0) - max).abs() < 1e-3);
    }
}

#[test]
fn programs_seed_ramp_rounded_profiles() {
    // With the drives' whole-unit profiles the wheels still finish within 40 ms of each
    // other on every demo move (seed profile 248 / 1000 / 400 and both ramps); the worst
    // is the octagon's short wheel at ramp 2: 25.68 Inc/s rounded to 26 (31 ms over 3 s).
    for base in [Ramp::SEED, Ramp::RAMP_1, Ramp::RAMP_2] {
        for travel in program_travels() {
            let profiles = wheel_profiles(travel, base);
            let (total, spread) = duration_spread(travel, &profiles);
            assert!(total > 0.5 && spread < 0.040, "{base:?} {travel:?}: {total} s, spread {spread}");
        }
    }
}

proptest! {
    #[test]
    fn scaled_profiles_finish_together(
        s in proptest::array::uniform3(-5000.0f64..5000.0),
        v in 10.0f64..600.0, a in 50.0f64..2000.0, d in 50.0f64..2000.0,
    ) {
        let base = Ramp { velocity: v, acceleration: a, deceleration: d };
        let prof = synchronise(s, base);
        let durations: Vec<f64> = s.iter().zip(&prof).filter(|(x, _)| x.abs() > 1e-6)
            .map(|(x, p)| trapezoid_duration(*x, p.velocity, p.acceleration, p.deceleration)).collect();
        let max = durations.iter().copied().fold(0.0, f64::max);
        let min = durations.iter().copied().fold(f64::INFINITY, f64::min);
        prop_assert!(durations.is_empty() || max - min < 1e-3);
        if a == d {
            // The same with motus-axis's planner.
            for (x, p) in s.iter().zip(&prof).filter(|(x, _)| x.abs() > 1e-6) {
                let t = Plan::to_target(0.0, 0.0, *x, p.velocity, p.acceleration).duration();
                prop_assert!((t - max).abs() < 1e-3);
            }
        }
    }
}
