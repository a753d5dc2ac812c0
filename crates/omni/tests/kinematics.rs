//! Kinematics against the spec's numbers and by property: forward(inverse(m)) == m, world
//! <-> robot frame, the arc of a combined move.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_omni::kinematics::{robot_to_world, world_to_robot, wrap_angle, SQRT3};
use motus_omni::{Geometry, Motion, Pose};
use proptest::prelude::*;

#[test]
fn spec_scale_1065_inc_is_188_cm() {
    // specs/omni-robot.md: 1065 Inc = 5 wheel revolutions = 188.4 cm (5 x 37.7 = 188.5 cm;
    // 565 Inc/m gives 188.50 cm).
    let g = Geometry::default();
    assert!((g.inc_per_metre - 565.0).abs() < 0.02); // 564.99
    let m = g.inc_to_metres(1065.0);
    assert!((m - 1.884).abs() < 0.0011, "{m}");
    // 1 cm = 5.65 Inc.
    assert!((g.metres_to_inc(0.01) - 5.65).abs() < 0.001);
}

#[test]
fn spec_wheel_travels_for_the_line_move() {
    // The line program's first move, (+1065, 0) Inc, no rotation. By hand from the
    // corrected formulas: s1 = 1065, s2 = s3 = -532.5.
    let g = Geometry::default();
    let s = g.inverse_inc(Motion::new(g.inc_to_metres(1065.0), 0.0, 0.0));
    assert!((s[0] - 1065.0).abs() < 1e-9 && (s[1] + 532.5).abs() < 1e-9 && (s[2] + 532.5).abs() < 1e-9);
    // The octagon's first move (536, -230) Inc: s2 = -268 + 0.8660 * 230 = -68.81,
    // s3 = -268 - 199.19 = -467.19 (by hand, sqrt(3)/2 = 0.866025).
    let s = g.inverse_inc(Motion::new(g.inc_to_metres(536.0), g.inc_to_metres(-230.0), 0.0));
    assert!((s[0] - 536.0).abs() < 1e-9);
    assert!((s[1] + 68.814).abs() < 1e-3, "{s:?}");
    assert!((s[2] + 467.186).abs() < 1e-3, "{s:?}");
    // The seed's sqrt(3/2) = 1.2247 would give s2 = -268 + 281.7: visibly wrong.
    assert!((SQRT3 / 2.0 - 0.866_025).abs() < 1e-6);
}

#[test]
fn seed_example_move_of_0x855_inc() {
    // Seed example (section 5, RPDO2 to 0x302, 0x303, 0x304, all `1F 00 55 08 00 00`):
    // relative target 0x00000855 = 2133 Inc on every wheel (10.0 wheel revolutions; the
    // seed's "8 otáček" does not match). Equal travel on all three wheels is a pure
    // rotation: dtheta = 2133 / 565 / R (0.2 m) = 18.876 rad (3.0 robot turns), no
    // translation.
    let g = Geometry::default();
    let m = g.forward_inc([2133.0; 3]);
    assert!(m.x.abs() < 1e-12 && m.y.abs() < 1e-12);
    assert!((m.theta - 2133.0 / 565.0 / 0.2).abs() < 1e-2, "{}", m.theta);
    // Rotation: each wheel travels R * dtheta.
    let s = g.inverse(Motion::new(0.0, 0.0, 1.0));
    assert!(s.iter().all(|v| (v - 0.2).abs() < 1e-12));
}

#[test]
fn frames() {
    // Robot heading 90 deg: robot x is world y.
    let (wx, wy) = robot_to_world(1.0, 0.0, std::f64::consts::FRAC_PI_2);
    assert!(wx.abs() < 1e-12 && (wy - 1.0).abs() < 1e-12);
    let (rx, ry) = world_to_robot(0.0, 1.0, std::f64::consts::FRAC_PI_2);
    assert!((rx - 1.0).abs() < 1e-12 && ry.abs() < 1e-12);
    assert!((wrap_angle(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
}

#[test]
fn combined_move_follows_an_arc() {
    // 1 m forward while turning 90 deg: a quarter circle of radius 2/pi = 0.6366 m, ending
    // at (0.6366, 0.6366) heading 90 deg (by hand).
    let p = Pose::default().advance(Motion::new(1.0, 0.0, std::f64::consts::FRAC_PI_2));
    let r = 2.0 / std::f64::consts::PI;
    assert!((p.x - r).abs() < 1e-12 && (p.y - r).abs() < 1e-12);
    // The same by integrating 10000 tiny steps.
    let mut q = Pose::default();
    for _ in 0..10_000 {
        q = q.advance(Motion::new(1e-4, 0.0, std::f64::consts::FRAC_PI_2 / 10_000.0));
    }
    assert!((q.x - p.x).abs() < 1e-9 && (q.y - p.y).abs() < 1e-9);
}

proptest! {
    #[test]
    fn forward_inverse_round_trip(x in -5.0f64..5.0, y in -5.0f64..5.0, th in -7.0f64..7.0, r in 0.05f64..1.0) {
        let g = Geometry { radius: r, ..Geometry::default() };
        let m = g.forward(g.inverse(Motion::new(x, y, th)));
        prop_assert!((m.x - x).abs() < 1e-9 && (m.y - y).abs() < 1e-9 && (m.theta - th).abs() < 1e-9);
        let s = [x, y, th];
        let back = g.inverse(g.forward(s));
        for i in 0..3 {
            prop_assert!((back[i] - s[i]).abs() < 1e-9);
        }
        // Sum of wheel travels is 3 R dtheta.
        let w = g.inverse(Motion::new(x, y, th));
        prop_assert!((w.iter().sum::<f64>() - 3.0 * r * th).abs() < 1e-9);
    }

    #[test]
    fn motion_to_inverts_advance(x in -3.0f64..3.0, y in -3.0f64..3.0, th in -3.0f64..3.0, h in -4.0f64..4.0) {
        let start = Pose::new(0.3, -0.2, h);
        let end = start.advance(Motion::new(x, y, th));
        let m = start.motion_to(end);
        prop_assert!((m.x - x).abs() < 1e-6 && (m.y - y).abs() < 1e-6 && (m.theta - th).abs() < 1e-9);
    }

    #[test]
    fn frame_rotation_round_trip(x in -10.0f64..10.0, y in -10.0f64..10.0, h in -7.0f64..7.0) {
        let (wx, wy) = robot_to_world(x, y, h);
        let (rx, ry) = world_to_robot(wx, wy, h);
        prop_assert!((rx - x).abs() < 1e-9 && (ry - y).abs() < 1e-9);
        prop_assert!((wx.hypot(wy) - x.hypot(y)).abs() < 1e-9);
    }
}
