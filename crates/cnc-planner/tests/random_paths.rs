//! Property test: random small paths (random corners, feeds, tolerances, rapids, an arc)
//! are executed within every axis limit, within the path tolerance, and end at the last
//! programmed point.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::*;
use motus_cnc_planner::{ArcDirection, Executor, PathItem, Plane, Segment};
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]
    #[test]
    fn random_paths_respect_limits_and_tolerance(
        pts in proptest::collection::vec((-30.0f64..30.0, -30.0f64..30.0, -5.0f64..5.0, 20.0f64..300.0, any::<bool>()), 1..8),
        tol in 0.0f64..0.3,
        radius in 1.0f64..10.0,
        ccw in any::<bool>(),
        ovr in 0.3f64..2.0,
    ) {
        let mut cfg = config();
        cfg.path_tolerance = tol;
        let mut ex = Executor::new(cfg, [0.0; 3]).unwrap();
        ex.set_override(ovr).unwrap();
        let mut prog = vec![[0.0; 3]];
        for (k, (x, y, z, feed, rapid)) in pts.iter().enumerate() {
            let end = [*x, *y, *z];
            ex.push(k as u32, PathItem::Motion(Segment::Line { end, feed: *feed, rapid: *rapid && k % 3 == 0 })).unwrap();
            prog.push(end);
        }
        // A full circle starting and ending at the last point, centre `radius` along +X.
        let last = *prog.last().unwrap();
        let centre = [last[0] + radius, last[1]];
        let direction = if ccw { ArcDirection::CounterClockwise } else { ArcDirection::Clockwise };
        ex.push(99, PathItem::Motion(Segment::Arc { end: last, centre, plane: Plane::Xy, direction, extra_turns: 0, feed: 50.0 })).unwrap();
        for k in 1..=2000 {
            let phi = std::f64::consts::PI + if ccw { 1.0 } else { -1.0 } * k as f64 * std::f64::consts::TAU / 2000.0;
            prog.push([centre[0] + radius * phi.cos(), centre[1] + radius * phi.sin(), last[2]]);
        }
        ex.finish();
        let sps = run_until(&mut ex, 2_000_000, |_, _, _| {}, idle);
        let mut pos = vec![[0.0; 3]];
        pos.extend(sps.iter().map(|s| s.positions));
        let end = *prog.last().unwrap();
        let fin = *pos.last().unwrap();
        prop_assert!((0..3).all(|i| (fin[i] - end[i]).abs() < 1e-9), "ended at {:?} not {:?}", fin, end);
        let (vr, ar) = limit_ratios(&pos);
        prop_assert!(vr <= 1.0 + 1e-9, "velocity ratio {}", vr);
        prop_assert!(ar <= 1.0, "acceleration ratio {}", ar);
        // Arcs are chords within the chord tolerance: the bound is the larger of the two.
        let bound = tol.max(cfg.chord_tolerance);
        let dev = max_deviation(&pos, &prog, bound);
        prop_assert!(dev <= bound + 1e-9, "deviation {} > {}", dev, bound);
    }
}
