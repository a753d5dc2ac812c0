//! Acceptance: a 10,000-segment contour executed at 1 ms stays within every axis limit and
//! the path tolerance, and takes at most 10 % more than the time-optimal bound.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::*;
use motus_cnc_planner::{ArcDirection, Executor, PathItem, Plane, Segment};
use std::f64::consts::PI;

/// The programmed contour: (item, dense points of the programmed path after it).
/// Arcs are densified here with a sagitta of 1e-4 mm, independently of the library.
fn contour() -> (Vec<PathItem<3>>, Vec<[f64; 3]>) {
    let mut items = Vec::new();
    let mut prog = vec![[20.0, 0.0, 0.0]];
    let line = |items: &mut Vec<PathItem<3>>, prog: &mut Vec<[f64; 3]>, end: [f64; 3], feed: f64| {
        items.push(PathItem::Motion(Segment::Line { end, feed, rapid: false }));
        prog.push(end);
    };
    // 1. spiral with a Z wave: 6000 short lines (~0.5 mm, ~0.6 degree corners).
    for k in 1..=6000 {
        let t = k as f64 / 6000.0;
        let phi = t * 20.0 * PI;
        let r = 20.0 + 60.0 * t;
        line(&mut items, &mut prog, [r * phi.cos(), r * phi.sin(), 1.5 * (phi * 3.0).sin()], 120.0);
    }
    // 2. a star: 200 lines between radius 80 and 30 (sharp corners), feed 150.
    let last = *prog.last().unwrap();
    let z = last[2];
    for k in 1..=200 {
        let phi = k as f64 * 2.0 * PI / 50.0;
        let r = if k % 2 == 0 { 80.0 } else { 30.0 };
        line(&mut items, &mut prog, [r * phi.cos(), r * phi.sin(), z], 150.0);
    }
    // 3. 100 arcs, alternating direction, radius 10, quarter and half turns along +X.
    let mut at = *prog.last().unwrap();
    for k in 0..100 {
        let r = 10.0;
        let centre = [at[0] + r, at[1]];
        let (end, dir, sweep) = if k % 2 == 0 {
            ([at[0] + 2.0 * r, at[1], at[2]], ArcDirection::Clockwise, -PI)
        } else {
            ([at[0] + 2.0 * r, at[1], at[2]], ArcDirection::CounterClockwise, PI)
        };
        items.push(PathItem::Motion(Segment::Arc {
            end,
            centre,
            plane: Plane::Xy,
            direction: dir,
            extra_turns: 0,
            feed: 100.0,
        }));
        let a0 = (at[1] - centre[1]).atan2(at[0] - centre[0]);
        let steps = (sweep.abs() / (2.0 * (1.0 - 1e-4 / r).acos())).ceil() as usize;
        for s in 1..=steps {
            let phi = a0 + sweep * s as f64 / steps as f64;
            prog.push([centre[0] + r * phi.cos(), centre[1] + r * phi.sin(), at[2]]);
        }
        at = end;
    }
    // 4. zigzag of 3700 short lines (0.3 mm, +-15 degrees) going -Y, then some Z.
    let mut p = at;
    for k in 0..3700 {
        let ang: f64 = if k % 2 == 0 { -PI / 2.0 + 0.26 } else { -PI / 2.0 - 0.26 };
        p = [p[0] + 0.3 * ang.cos(), p[1] + 0.3 * ang.sin(), p[2] + if k % 100 < 50 { 0.02 } else { -0.02 }];
        line(&mut items, &mut prog, p, 80.0);
    }
    (items, prog)
}

#[test]
fn ten_thousand_segments_within_limits_tolerance_and_time() {
    let (items, prog) = contour();
    let segments = items.len();
    assert_eq!(segments, 10_000);
    let cfg = config();
    let mut ex = Executor::new(cfg, [20.0, 0.0, 0.0]).unwrap();
    for (i, it) in items.iter().enumerate() {
        ex.push(i as u32 + 1, *it).unwrap();
    }
    ex.finish();
    let pieces: Vec<_> = ex.planner().pieces().iter().copied().collect();
    let bound = time_optimal(&pieces, 0.005);
    // A cruder bound for reference: every piece at its speed cap, no acceleration at all.
    let crude: f64 = pieces.iter().filter(|p| p.length > 0.0).map(|p| p.length / p.cap.min(p.feed)).sum();
    let sps = run_until(&mut ex, 5_000_000, |_, _, _| {}, idle);
    let mut pos = vec![[20.0, 0.0, 0.0]];
    pos.extend(sps.iter().map(|s| s.positions));
    let end = *prog.last().unwrap();
    let fin = *pos.last().unwrap();
    assert!((0..3).all(|i| (fin[i] - end[i]).abs() < 1e-9), "ended at {fin:?}, not {end:?}");
    // Time at rest at the end: the last cycle is the first at rest.
    let time = sps.len() as f64 * DT;
    let (vr, ar) = limit_ratios(&pos);
    let dev = max_deviation_window(&pos, &prog, cfg.path_tolerance, 100, 300);
    // The crude bound: programmed length at min(feed, axis caps) ignoring acceleration.
    eprintln!(
        "contour: {segments} segments, {} pieces, executed in {time:.3} s, time-optimal bound {bound:.3} s (ratio {:.4}), cap-only bound {crude:.3} s, \
         max |v|/vmax {vr:.5}, max (|a|-{ACC_ABS})/(amax(1+{ACC_REL})) {ar:.5}, max deviation {dev:.5} mm",
        pieces.len(),
        time / bound
    );
    assert!(vr <= 1.0 + 1e-6, "velocity ratio {vr}");
    assert!(ar <= 1.0, "acceleration ratio {ar}");
    assert!(dev <= cfg.path_tolerance + 1e-6, "deviation {dev}");
    assert!(time >= bound * 0.999, "faster than the bound?! {time} < {bound}");
    assert!(bound >= crude, "the time-optimal bound {bound} is below the cap-only bound {crude}");
    assert!(time <= bound * 1.10, "time {time} more than 10 % above the bound {bound}");
}

#[test]
fn streaming_with_a_short_buffer_stays_within_limits() {
    // The decoder runs ahead only as far as a 150-piece buffer allows (the star and the
    // arcs of the contour, pushed while executing); 100 pieces of history are kept.
    let (items, prog) = contour();
    let first = 6000;
    let start = prog[first];
    let items = &items[first..6300];
    let prog_part: Vec<[f64; 3]> = prog[first..].to_vec();
    let mut cfg = config();
    cfg.buffer_capacity = 150;
    cfg.history = 100;
    let mut ex = Executor::new(cfg, start).unwrap();
    let mut next = 0;
    let mut refused = 0;
    let mut max_held = 0;
    let mut pos = vec![start];
    for _ in 0..2_000_000 {
        while next < items.len() {
            match ex.push(next as u32, items[next]) {
                Ok(()) => next += 1,
                Err(motus_cnc_planner::PushError::Full { .. }) => {
                    refused += 1;
                    break;
                }
                Err(e) => panic!("{e}"),
            }
        }
        if next == items.len() && ex.planner().has_pending() {
            ex.finish();
        }
        max_held = max_held.max(ex.planner().pieces().len());
        let sp = ex.tick(DT);
        pos.push(sp.positions);
        if next == items.len() && sp.state == motus_cnc_planner::ExecState::Idle {
            break;
        }
    }
    assert!(refused > 0, "the buffer never filled");
    // Capacity 150 ahead (+ one item's pieces) and 100 behind.
    assert!(max_held <= 150 + 100 + 200, "{max_held} pieces held");
    let fin = *pos.last().unwrap();
    let PathItem::Motion(last) = items.last().unwrap() else { panic!() };
    let want = last.end();
    assert!((0..3).all(|i| (fin[i] - want[i]).abs() < 1e-9), "ended at {fin:?}, not {want:?}");
    let (vr, ar) = limit_ratios(&pos);
    assert!(vr <= 1.0 + 1e-6, "velocity ratio {vr}");
    assert!(ar <= 1.0, "acceleration ratio {ar}");
    let dev = max_deviation(&pos, &prog_part, cfg.path_tolerance);
    assert!(dev <= cfg.path_tolerance + 1e-6, "deviation {dev}");
}
