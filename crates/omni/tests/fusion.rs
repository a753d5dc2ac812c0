//! Fusion against a simulated world: without slip the fused and wheel-only poses agree
//! with the truth; with 10 % slip on one wheel over a 2 m path the fused pose stays within
//! 1 cm while wheel-only odometry drifts far more.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_mouse_protocol::Calibration;
use motus_omni::{Fusion, Geometry, Motion, Pose, RobotWorld, SlipEvent, SlipTolerance};

/// A sensor with whole counts and the remainder carried, as the real converter sends.
struct Counter {
    owed: [f64; 2],
}

impl Counter {
    fn counts(&mut self, m: Motion) -> (i32, i32) {
        let cal = Calibration::default();
        self.owed[0] += cal.metres_to_counts(m.x);
        self.owed[1] += cal.metres_to_counts(m.y);
        let c = [self.owed[0].round(), self.owed[1].round()];
        self.owed[0] -= c[0];
        self.owed[1] -= c[1];
        (c[0] as i32, c[1] as i32)
    }
}

/// Drives the commanded robot-frame path `legs` (metres) open-loop in 5 mm steps, with
/// `slip`; returns (true pose, fusion, slip events).
fn drive(legs: &[(f64, f64)], slip: [f64; 3]) -> (Pose, Fusion, Vec<SlipEvent>) {
    drive_steps(legs, slip, 0.005)
}

fn drive_steps(legs: &[(f64, f64)], slip: [f64; 3], step_m: f64) -> (Pose, Fusion, Vec<SlipEvent>) {
    let mut events = Vec::new();
    let g = Geometry::default();
    let mut world = RobotWorld::new(g, Pose::default());
    world.set_slip(slip);
    let mut fusion = Fusion::new(g, Calibration::default(), SlipTolerance::default(), Pose::default());
    let mut wheels = [0.0f64; 3]; // commanded, Inc
    let mut counter = Counter { owed: [0.0; 2] };
    let read = |w: &[f64; 3]| w.map(|v| v.round() as i32);
    fusion.update(read(&wheels), None);
    for &(lx, ly) in legs {
        let n = (lx.hypot(ly) / step_m).ceil() as usize;
        let step = Motion::new(lx / n as f64, ly / n as f64, 0.0);
        let ds = g.inverse_inc(step);
        for _ in 0..n {
            let truth = world.apply_wheel_inc(ds);
            for (w, d) in wheels.iter_mut().zip(ds) {
                *w += d;
            }
            events.extend(fusion.update(read(&wheels), Some(counter.counts(truth))));
        }
    }
    (world.pose(), fusion, events)
}

fn err(a: Pose, b: Pose) -> f64 {
    a.distance_to(&b)
}

const PATH: [(f64, f64); 4] = [(0.5, 0.0), (0.0, 0.5), (-0.5, 0.0), (0.0, -0.5)];

#[test]
fn without_slip_both_agree_with_the_truth() {
    let (truth, f, events) = drive(&PATH, [0.0; 3]);
    assert!(events.is_empty());
    let s = f.state();
    assert!(err(s.pose, truth) < 0.001, "{s:?} vs {truth:?}");
    assert!(err(s.wheel_only_pose, truth) < 0.002, "{s:?} vs {truth:?}");
    assert!((s.pose.heading - truth.heading).abs() < 0.005);
    assert_eq!(s.slip_detected_count, 0);
    assert_eq!(s.suspect_wheel, None);
}

#[test]
fn ten_percent_slip_on_one_wheel() {
    for wheel in 0..3 {
        let mut slip = [0.0; 3];
        slip[wheel] = 0.1;
        let (truth, f, events) = drive(&PATH, slip);
        let s = f.state();
        let fused = err(s.pose, truth);
        let wheel_only = err(s.wheel_only_pose, truth);
        eprintln!(
            "wheel {wheel}: fused error {fused:.4} m, wheel-only {wheel_only:.4} m, {} events",
            events.len()
        );
        assert!(fused < 0.01, "wheel {wheel}: fused error {fused} m ({s:?} vs {truth:?})");
        assert!(
            wheel_only > 3.0 * fused && wheel_only > 0.02,
            "wheel {wheel}: wheel-only error {wheel_only} m"
        );
        assert!(s.slip_detected_count > 0);
        // Every attributed event names the slipping wheel. (At the end the suspicion may
        // be cleared: on a leg where that wheel does not turn it does not slip.)
        assert!(events.iter().any(|e| e.wheel == Some(wheel)), "{events:?}");
        assert!(events.iter().all(|e| e.wheel.is_none_or(|w| w == wheel)), "{events:?}");
        assert!((s.pose.heading - truth.heading).abs() < 0.01, "{} vs {}", s.pose.heading, truth.heading);
    }
}

#[test]
fn slip_that_stops_is_forgotten() {
    let g = Geometry::default();
    let mut world = RobotWorld::new(g, Pose::default());
    let mut fusion = Fusion::new(g, Calibration::default(), SlipTolerance::default(), Pose::default());
    let mut wheels = [0.0f64; 3];
    let mut counter = Counter { owed: [0.0; 2] };
    fusion.update([0; 3], None);
    let ds = g.inverse_inc(Motion::new(0.005, 0.0, 0.0));
    for i in 0..400 {
        world.set_slip(if i < 100 { [0.0, 0.1, 0.0] } else { [0.0; 3] });
        let truth = world.apply_wheel_inc(ds);
        for (w, d) in wheels.iter_mut().zip(ds) {
            *w += d;
        }
        fusion.update(wheels.map(|v| v.round() as i32), Some(counter.counts(truth)));
        if i == 99 {
            assert_eq!(fusion.state().suspect_wheel, Some(1));
        }
    }
    assert_eq!(fusion.state().suspect_wheel, None);
    assert!(err(fusion.state().pose, world.pose()) < 0.01);
}

#[test]
fn no_sensor_falls_back_to_wheels() {
    let g = Geometry::default();
    let mut fusion = Fusion::new(g, Calibration::default(), SlipTolerance::default(), Pose::default());
    fusion.update([0; 3], None);
    fusion.update([565, -283, -282], None);
    let s = fusion.state();
    assert!((s.pose.x - 1.0).abs() < 2e-3 && s.pose == s.wheel_only_pose);
}

#[test]
fn coarse_updates_with_slip() {
    // Updates every 10 cm (a controller polling slowly): still within 1 cm.
    for step in [0.02, 0.05, 0.1] {
        let (truth, f, _) = drive_steps(&PATH, [0.0, 0.1, 0.0], step);
        let e = err(f.state().pose, truth);
        eprintln!(
            "step {step}: fused error {e:.4} m, heading error {:.4}",
            f.state().pose.heading - truth.heading
        );
        assert!(e < 0.01, "step {step}: {e}");
    }
}
