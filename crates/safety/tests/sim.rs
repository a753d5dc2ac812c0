#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! The supervisor in the loop of a simulated juggler.
//!
//! Loop delays: the supervisor sees the state 8 cycles old and its output reaches the
//! quick-stop input 16 cycles later: 24 cycles x 400 us = 9.6 ms = the seed's Tp.

use motus_safety::sim::{run, LoopDelays, Program, Segment, SetPoint};
use motus_safety::*;
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use std::cell::Cell;

const DELAYS: LoopDelays = LoopDelays { input_delay: 8, output_delay: 16 };

fn lift_rules(expr: &str) -> RuleSet {
    RuleSet::from_toml(&format!(
        r#"
[supervisor]
reaction_time = 0.0096
cycle_time = 0.0004
max_sample_age = 3
lease_time = 0.0004

[[axis]]
name = "lift"
id = 2
unit = "0.1mm"
limits = {{ min = -1000, max = 20000 }}
acceleration = {{ up = 1_000_000, down = 1_000_000 }}
braking = {{ up = 1_300_000, down = 1_300_000 }}

[[rule]]
name = "seed_test"
expr = "{expr}"
"#
    ))
    .unwrap()
}

fn lift_program() -> Program {
    Program {
        start: vec![5000.0],
        segments: vec![Segment {
            set_points: vec![SetPoint { target: 19_000.0, speed: 10_000.0, accel: 1_000_000.0 }],
            cycles: 3000,
        }],
        dropped_samples: vec![],
        skipped_evaluations: vec![],
    }
}

/// The seed's test (chapter 4.7): rule "stop when position > 10 000", Tp = 9.6 ms.
#[test]
fn seed_test_stop_above_10000() {
    let rules = lift_rules("position(lift) < 10000");
    let r = run(&rules, &lift_program(), DELAYS, true, true, &|_| None);
    let stop = r.stopped_at.expect("must stop");
    // First state above 10 000 is the state at the start of cycle j + 1.
    let j = r.history.iter().position(|s| s[0].position > 10_000.0).unwrap() as u64;
    assert_eq!(stop - (j + 1), 24, "stop must act 24 cycles = 9.6 ms after the crossing");
    assert!(r.stop_reason.unwrap().starts_with("rule seed_test failed: position(lift) < 10000.0 margin"));
    // Hand computation: at 10 000 units/s (1 m/s) the axis runs v*Tp = 96 units (+ up to
    // one cycle, 4 units, of crossing phase) and then brakes v^2/(2b) = 1e8/2.6e6 = 38.46.
    let end = r.history.last().unwrap()[0];
    assert_eq!(end.speed, 0.0);
    assert!(
        end.position > 10_000.0 + 96.0 + 38.46 - 1e-6 && end.position < 10_000.0 + 100.0 + 38.47,
        "{end:?}"
    );
}

/// The same limit as a predictive rule: the axis stops before 10 000.
#[test]
fn seed_test_predictive_stops_before_10000() {
    let rules = lift_rules("below(lift, 10000)");
    let r = run(&rules, &lift_program(), DELAYS, true, true, &|_| None);
    assert!(r.stopped_at.is_some());
    let max = r.history.iter().map(|s| s[0].position).fold(f64::MIN, f64::max);
    // Needed free distance at 10 000 units/s with H = 10.0 ms (Tp + lease):
    // 100 + 50 + 20000^2/2.6e6 = 303.8 -> the stop is decided at least that far ahead.
    assert!(max < 10_000.0 && max > 10_000.0 - 320.0, "{max}");
}

/// Independent statement of the juggler's hazards, written from specs/juggler-safety.md
/// (not through the rule evaluator). Positions: arm_left, vertical_left, arm_right,
/// vertical_right, thrower.
fn juggler_hazard(p: &[f64]) -> Option<String> {
    let (a1, v2, a3, v4, t5) = (p[0], p[1], p[2], p[3], p[4]);
    for (n, x, lo, hi) in [
        ("arm_left", a1, -1000.0, 1000.0),
        ("vertical_left", v2, -1000.0, 20_000.0),
        ("arm_right", a3, -1000.0, 1000.0),
        ("vertical_right", v4, -1000.0, 20_000.0),
        ("thrower", t5, -7600.0, 3400.0),
    ] {
        if x < lo || x > hi {
            return Some(format!("{n} outside its limits at {x}"));
        }
    }
    // Cups are 5 cm + 5 cm: centres closer than 1000 units collide.
    if a1 >= 380.0 && a3 >= 380.0 && (v2 - v4).abs() < 1000.0 {
        return Some(format!("arms collide: arms {a1} {a3}, verticals {v2} {v4}"));
    }
    if a1 >= 620.0 && (v2 - t5).abs() < 1000.0 {
        return Some(format!("arm_left hits the thrower: {a1} {v2} {t5}"));
    }
    if a3 >= 620.0 && (v4 - t5).abs() < 1000.0 {
        return Some(format!("arm_right hits the thrower: {a3} {v4} {t5}"));
    }
    if (5000.0..=6000.0).contains(&v2) && a1 >= 920.0 {
        return Some(format!("arm_left hits the rod mount: {a1} {v2}"));
    }
    if (5000.0..=6000.0).contains(&v4) && a3 >= 920.0 {
        return Some(format!("arm_right hits the rod mount: {a3} {v4}"));
    }
    None
}

/// (limits, student speed limit, model acceleration) per axis. Student limits from the
/// spec: 5000 deg/s = 50 000 units/s horizontal, 10 m/s = 100 000 units/s vertical (axis 5:
/// no figure in the spec, 10 m/s assumed).
const AXES: [(f64, f64, f64, f64); 5] = [
    (-1000.0, 1000.0, 50_000.0, 500_000.0),
    (-1000.0, 20_000.0, 100_000.0, 1_000_000.0),
    (-1000.0, 1000.0, 50_000.0, 500_000.0),
    (-1000.0, 20_000.0, 100_000.0, 1_000_000.0),
    (-7600.0, 3400.0, 100_000.0, 2_000_000.0),
];

fn set_point(i: usize, adversarial: bool) -> impl Strategy<Value = SetPoint> {
    let (lo, hi, v, a) = AXES[i];
    let span = hi - lo;
    let (tlo, thi, vmax) =
        if adversarial { (lo - 0.3 * span, hi + 0.3 * span, 3.0 * v) } else { (lo, hi, v) };
    (tlo..thi, 0.05 * vmax..vmax, 0.2 * a..=a).prop_map(|(target, speed, accel)| SetPoint {
        target,
        speed,
        accel,
    })
}

fn program() -> impl Strategy<Value = (bool, Program)> {
    any::<bool>().prop_flat_map(|adv| {
        let seg = (
            (set_point(0, adv), set_point(1, adv), set_point(2, adv), set_point(3, adv), set_point(4, adv)),
            20u32..600,
        )
            .prop_map(|((a, b, c, d, e), cycles)| Segment { set_points: vec![a, b, c, d, e], cycles });
        (
            prop::collection::vec(seg, 1..6),
            prop::collection::vec(0u64..3000, 0..20),
            prop::collection::vec(0u64..3000, 0..10),
        )
            .prop_map(move |(segments, dropped_samples, skipped_evaluations)| {
                (
                    adv,
                    Program {
                        start: vec![-500.0, 1000.0, -500.0, 10_000.0, -7100.0],
                        segments,
                        dropped_samples,
                        skipped_evaluations,
                    },
                )
            })
    })
}

#[test]
fn random_programs_never_collide() {
    let rules = RuleSet::from_toml(JUGGLER_TOML).unwrap();
    let cases: u32 = std::env::var("SAFETY_SIM_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(2000);
    let mut runner = TestRunner::new(Config { cases, failure_persistence: None, ..Config::default() });
    let (programs, stops, false_stops, hazards_unsupervised) =
        (Cell::new(0u32), Cell::new(0u32), Cell::new(0u32), Cell::new(0u32));
    let (adv_programs, adv_stops, adv_false) = (Cell::new(0u32), Cell::new(0u32), Cell::new(0u32));
    runner
        .run(&program(), |(adv, p)| {
            let sup = run(&rules, &p, DELAYS, true, false, &juggler_hazard);
            prop_assert!(sup.started, "the start position must be safe");
            prop_assert!(
                sup.hazard.is_none(),
                "hazard {:?}, stop {:?} ({:?})",
                sup.hazard,
                sup.stopped_at,
                sup.stop_reason
            );
            let free = run(&rules, &p, DELAYS, false, false, &juggler_hazard);
            programs.set(programs.get() + 1);
            if adv {
                adv_programs.set(adv_programs.get() + 1);
            }
            if free.hazard.is_some() {
                hazards_unsupervised.set(hazards_unsupervised.get() + 1);
            }
            if sup.stopped_at.is_some() {
                stops.set(stops.get() + 1);
                if adv {
                    adv_stops.set(adv_stops.get() + 1);
                }
                if free.hazard.is_none() {
                    false_stops.set(false_stops.get() + 1);
                    if adv {
                        adv_false.set(adv_false.get() + 1);
                    }
                }
            } else {
                // No stop: the unsupervised run is the same motion, hence safe too.
                prop_assert!(free.hazard.is_none());
            }
            Ok(())
        })
        .unwrap();
    let n = f64::from(programs.get());
    println!(
        "sim: {} programs ({} adversarial): {} stopped ({} adversarial), {} would collide or leave a limit without the supervisor; \
         false stops {} = {:.1}% of programs, {:.1}% of stops; student programs only: {} false stops of {} ({:.1}%)",
        programs.get(),
        adv_programs.get(),
        stops.get(),
        adv_stops.get(),
        hazards_unsupervised.get(),
        false_stops.get(),
        100.0 * f64::from(false_stops.get()) / n,
        100.0 * f64::from(false_stops.get()) / f64::from(stops.get().max(1)),
        false_stops.get() - adv_false.get(),
        programs.get() - adv_programs.get(),
        100.0 * f64::from(false_stops.get() - adv_false.get()) / f64::from((programs.get() - adv_programs.get()).max(1)),
    );
    assert_eq!(programs.get(), cases);
    // Every program that would collide unsupervised was stopped (checked above as zero
    // hazards); make sure the generator actually produces dangerous programs.
    assert!(hazards_unsupervised.get() > cases / 10, "generator too tame");
}

/// The property can fail: with a horizon too short for the real loop (Tp set to 1 ms
/// while the loop takes 9.6 ms) the same generator produces collisions.
#[test]
fn too_short_horizon_is_caught() {
    let toml = JUGGLER_TOML.replace("reaction_time = 0.0096", "reaction_time = 0.001");
    let rules = RuleSet::from_toml(&toml).unwrap();
    let mut runner = TestRunner::new(Config { cases: 300, failure_persistence: None, ..Config::default() });
    let hazards = Cell::new(0u32);
    runner
        .run(&program(), |(_, p)| {
            if run(&rules, &p, DELAYS, true, false, &juggler_hazard).hazard.is_some() {
                hazards.set(hazards.get() + 1);
            }
            Ok(())
        })
        .unwrap();
    assert!(hazards.get() > 0, "a 1 ms horizon must let some collisions through");
}
