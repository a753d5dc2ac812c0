//! Executor behaviour: synchronous and asynchronous M-functions, feed hold, stop, override,
//! dwell, decoder synchronisation, single block, backward motion and the coupling, each
//! checked on the executed set-points (limits by finite differences, positions on the path).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::*;
use motus_cnc_planner::{
    CommandError, CouplingState, Event, ExArray, ExecState, Executor, PathItem, PushError, Recouple, Segment,
};
use rand::{Rng, SeedableRng};

fn line(end: [f64; 3], feed: f64) -> PathItem<3> {
    PathItem::Motion(Segment::Line { end, feed, rapid: false })
}

/// An L: (0,0,0) -> (50,0,0) -> (50,40,0) -> (0,40,5), feed 100 mm/s.
const L_POINTS: [[f64; 3]; 4] = [[0.0; 3], [50.0, 0.0, 0.0], [50.0, 40.0, 0.0], [0.0, 40.0, 5.0]];

fn l_program(ex: &mut Executor<3>) {
    for (k, p) in L_POINTS.iter().enumerate().skip(1) {
        ex.push(k as u32, line(*p, 100.0)).unwrap();
    }
    ex.finish();
}

fn close(a: [f64; 3], b: [f64; 3], eps: f64) -> bool {
    (0..3).all(|i| (a[i] - b[i]).abs() <= eps)
}

fn positions(start: [f64; 3], sps: &[motus_cnc_planner::Setpoint<3>]) -> Vec<[f64; 3]> {
    let mut v = vec![start];
    v.extend(sps.iter().map(|s| s.positions));
    v
}

fn assert_limits(pos: &[[f64; 3]]) {
    let (vr, ar) = limit_ratios(pos);
    assert!(vr <= 1.0 + 1e-9, "velocity ratio {vr}");
    assert!(ar <= 1.0, "acceleration ratio {ar}");
}

#[test]
fn synchronous_m_function_waits_for_acknowledge() {
    let mut ex = Executor::new(config(), [0.0; 3]).unwrap();
    ex.push(1, line([50.0, 0.0, 0.0], 100.0)).unwrap();
    ex.push(2, PathItem::MFunction { number: 60, sync: true }).unwrap();
    ex.push(3, line([50.0, 40.0, 0.0], 100.0)).unwrap();
    ex.finish();
    let mut sps = run_until(&mut ex, 100_000, |_, _, _| {}, |s| s.state == ExecState::WaitingAck(60));
    let at = sps.last().unwrap();
    // An exact stop at the programmed end of line 1 (no blend across a synchronous M).
    assert!(close(at.positions, [50.0, 0.0, 0.0], 1e-9), "{:?}", at.positions);
    assert_eq!(at.path_speed, 0.0);
    assert_eq!(ex.poll_event(), Some(Event::MFunction { number: 60, sync: true, line: 2 }));
    assert!(!ex.acknowledge(61)); // the wrong M does not release it
    let waiting = run_until(&mut ex, 500, |_, _, _| {}, |_| false);
    assert!(waiting.iter().all(|s| s.positions == at.positions && s.state == ExecState::WaitingAck(60)));
    sps.extend(waiting);
    assert!(ex.acknowledge(60));
    sps.extend(run_until(&mut ex, 100_000, |_, _, _| {}, idle));
    assert!(close(sps.last().unwrap().positions, [50.0, 40.0, 0.0], 1e-9));
    assert_limits(&positions([0.0; 3], &sps));
}

#[test]
fn asynchronous_m_function_and_parameters_do_not_stop() {
    let mut ex = Executor::new(config(), [0.0; 3]).unwrap();
    ex.push(1, line([50.0, 0.0, 0.0], 100.0)).unwrap();
    ex.push(2, PathItem::MFunction { number: 8, sync: false }).unwrap();
    ex.push(3, PathItem::ExternalParameter { array: ExArray::W, index: 60, value: 3600.0 }).unwrap();
    ex.push(4, line([50.0, 40.0, 0.0], 100.0)).unwrap();
    ex.finish();
    let mut seen = Vec::new();
    let sps = run_until(
        &mut ex,
        100_000,
        |_, ex, sp| {
            while let Some(e) = ex.poll_event() {
                seen.push((e, sp.path_speed, sp.positions));
            }
        },
        idle,
    );
    assert_eq!(seen.len(), 2, "{seen:?}");
    assert_eq!(seen[0].0, Event::MFunction { number: 8, sync: false, line: 2 });
    assert_eq!(seen[1].0, Event::ExternalParameter { array: ExArray::W, index: 60, value: 3600.0, line: 3 });
    // Reported while moving through the blended corner, near the programmed corner.
    assert!(seen[0].1 > 1.0, "speed at the M-function {}", seen[0].1);
    let d = ((seen[0].2[0] - 50.0).powi(2) + seen[0].2[1].powi(2)).sqrt();
    assert!(d < 0.5, "reported {d} mm from the corner");
    assert!(close(sps.last().unwrap().positions, [50.0, 40.0, 0.0], 1e-9));
    assert_limits(&positions([0.0; 3], &sps));
}

#[test]
fn feed_hold_at_random_points_stops_within_limits_and_resumes_on_the_path() {
    let mut rng = rand::rngs::SmallRng::seed_from_u64(7);
    let prog: Vec<[f64; 3]> = L_POINTS.to_vec();
    for _ in 0..12 {
        let mut ex = Executor::new(config(), [0.0; 3]).unwrap();
        l_program(&mut ex);
        let hold_at = rng.gen_range(1..1400);
        let mut held_at = None;
        let mut held_cycles = 0;
        let sps = run_until(
            &mut ex,
            100_000,
            |k, ex, sp| {
                if k == hold_at {
                    ex.feed_hold();
                }
                if sp.state == ExecState::Held {
                    if held_at.is_none() {
                        held_at = Some((k, sp.positions));
                    }
                    held_cycles += 1;
                    assert_eq!(sp.positions, held_at.unwrap().1, "moved while held");
                    if held_cycles == 200 {
                        ex.cycle_start().unwrap();
                    }
                }
            },
            idle,
        );
        let (k_held, _) = held_at.expect("never held");
        // From 100 mm/s the slowest deceleration on this path (Z-heavy last line: amax 500 /
        // |u_z| = 500 / 0.0775... >= 1500 mm/s² on X/Y lines; blends >= 0.2 * 1500) stops
        // within 0.35 s.
        assert!((k_held - hold_at) as f64 * DT < 0.35, "took {} cycles to stop", k_held - hold_at);
        assert!(close(sps.last().unwrap().positions, L_POINTS[3], 1e-9));
        let pos = positions([0.0; 3], &sps);
        assert_limits(&pos);
        assert!(max_deviation(&pos, &prog, 0.05) <= 0.05 + 1e-9);
    }
}

#[test]
fn stop_at_random_points_decelerates_and_flushes() {
    let mut rng = rand::rngs::SmallRng::seed_from_u64(11);
    for _ in 0..8 {
        let mut ex = Executor::new(config(), [0.0; 3]).unwrap();
        l_program(&mut ex);
        let stop_at = rng.gen_range(1..1400);
        let mut sps = run_until(
            &mut ex,
            100_000,
            |k, ex, _| {
                if k == stop_at {
                    ex.stop();
                }
            },
            |s| s.state == ExecState::Idle,
        );
        let mut events = Vec::new();
        while let Some(e) = ex.poll_event() {
            events.push(e);
        }
        assert!(events.contains(&Event::Stopped), "{events:?}");
        assert_eq!(ex.planner().pieces().len(), 0);
        let here = sps.last().unwrap().positions;
        assert!(!close(here, L_POINTS[3], 1e-3), "stopped at the end?");
        // The decoder restarts from the stop position.
        ex.push(100, line([10.0, 10.0, 0.0], 50.0)).unwrap();
        ex.finish();
        sps.extend(run_until(&mut ex, 100_000, |_, _, _| {}, idle));
        assert!(close(sps.last().unwrap().positions, [10.0, 10.0, 0.0], 1e-9));
        assert_limits(&positions([0.0; 3], &sps));
    }
}

#[test]
fn feed_override_scales_the_feed_but_not_past_the_axis_limits() {
    let mut ex = Executor::new(config(), [0.0; 3]).unwrap();
    ex.push(1, line([300.0, 0.0, 0.0], 60.0)).unwrap();
    ex.push(2, line([300.0, 300.0, 0.0], 150.0)).unwrap();
    ex.finish();
    ex.set_override(0.5).unwrap();
    assert!(ex.set_override(2.5).is_err());
    let sps = run_until(
        &mut ex,
        100_000,
        |k, ex, _| {
            if k == 2000 {
                ex.set_override(2.0).unwrap();
            }
        },
        idle,
    );
    // 0.5 * 60 = 30 mm/s cruise at 1.9 s; 2.0 * 60 = 120 mm/s on X later; on Y the feed
    // 2.0 * 150 = 300 is capped by the Y axis at 150 mm/s.
    assert!((sps[1900].path_speed - 30.0).abs() < 1e-9, "{}", sps[1900].path_speed);
    let max_x = sps.iter().filter(|s| s.line == 1).map(|s| s.path_speed).fold(0.0, f64::max);
    let max_y = sps.iter().filter(|s| s.line == 2).map(|s| s.path_speed).fold(0.0, f64::max);
    assert!((max_x - 120.0).abs() < 1e-9, "{max_x}");
    assert!((max_y - 150.0).abs() < 1e-9, "{max_y}");
    assert_limits(&positions([0.0; 3], &sps));
}

#[test]
fn dwell_waits_at_rest() {
    let mut ex = Executor::new(config(), [0.0; 3]).unwrap();
    ex.push(1, line([20.0, 0.0, 0.0], 100.0)).unwrap();
    ex.push(2, PathItem::Dwell { seconds: 0.25 }).unwrap();
    ex.push(3, line([20.0, 20.0, 0.0], 100.0)).unwrap();
    ex.finish();
    let sps = run_until(&mut ex, 100_000, |_, _, _| {}, idle);
    let resting: Vec<_> = sps.iter().filter(|s| s.state == ExecState::Dwelling).collect();
    assert!((resting.len() as f64 * DT - 0.25).abs() <= 1.5 * DT, "{} cycles", resting.len());
    assert!(resting.iter().all(|s| close(s.positions, [20.0, 0.0, 0.0], 1e-9)));
}

#[test]
fn decoder_sync_blocks_the_decoder_until_reached() {
    let mut ex = Executor::new(config(), [0.0; 3]).unwrap();
    ex.push(1, line([20.0, 0.0, 0.0], 100.0)).unwrap();
    ex.push(2, PathItem::DecoderSync).unwrap();
    assert!(ex.decoder_blocked());
    assert_eq!(ex.push(3, line([0.0; 3], 10.0)), Err(PushError::AwaitingDecoderSync { line: 2 }));
    let mut reached = None;
    for k in 0..100_000 {
        let sp = ex.tick(DT);
        if let Some(Event::DecoderSyncReached { line: 2 }) = ex.poll_event() {
            reached = Some((k, sp.positions));
            break;
        }
    }
    let (_, at) = reached.unwrap();
    assert!(close(at, [20.0, 0.0, 0.0], 1e-9));
    assert!(!ex.decoder_blocked());
    ex.push(3, line([20.0, 10.0, 0.0], 100.0)).unwrap();
    ex.finish();
    let sps = run_until(&mut ex, 100_000, |_, _, _| {}, idle);
    assert!(close(sps.last().unwrap().positions, [20.0, 10.0, 0.0], 1e-9));
}

#[test]
fn single_block_stops_at_every_block_end() {
    let mut ex = Executor::new(config(), [0.0; 3]).unwrap();
    ex.set_single_block(true);
    l_program(&mut ex);
    let mut stops = Vec::new();
    let sps = run_until(
        &mut ex,
        100_000,
        |_, ex, sp| {
            if let Some(Event::BlockStop { line }) = ex.poll_event() {
                stops.push((line, sp.positions, sp.path_speed));
                ex.cycle_start().unwrap();
            }
        },
        idle,
    );
    assert_eq!(stops.iter().map(|s| s.0).collect::<Vec<_>>(), vec![1, 2]);
    for (k, (_, p, v)) in stops.iter().enumerate() {
        assert_eq!(*v, 0.0);
        // At the block boundary: the blend midpoint, within the path tolerance of the corner.
        let c = L_POINTS[k + 1];
        let d = ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt();
        assert!(d <= 0.05 + 1e-9 && d > 1e-3, "stop {k} is {d} from the corner");
    }
    assert_limits(&positions([0.0; 3], &sps));
}

#[test]
fn backward_motion_retraces_the_path_and_continues_forwards() {
    let mut ex = Executor::new(config(), [0.0; 3]).unwrap();
    l_program(&mut ex);
    let mut sps = run_until(&mut ex, 900, |_, _, _| {}, |_| false); // into the second line
    assert_eq!(sps.last().unwrap().line, 2);
    ex.feed_hold();
    sps.extend(run_until(&mut ex, 10_000, |_, _, _| {}, |s| s.state == ExecState::Held));
    ex.backward().unwrap();
    let back = run_until(&mut ex, 100_000, |_, _, _| {}, |s| s.state == ExecState::Held);
    assert!(back.iter().any(|s| s.state == ExecState::Reversing));
    // Back to the oldest retained point: the program start.
    assert!(close(back.last().unwrap().positions, [0.0; 3], 1e-9), "{:?}", back.last().unwrap().positions);
    sps.extend(back);
    ex.cycle_start().unwrap();
    sps.extend(run_until(&mut ex, 100_000, |_, _, _| {}, idle));
    assert!(close(sps.last().unwrap().positions, L_POINTS[3], 1e-9));
    let pos = positions([0.0; 3], &sps);
    assert_limits(&pos);
    assert!(max_deviation(&pos, &L_POINTS, 0.05) <= 0.05 + 1e-9);
}

#[test]
fn coupling_released_jogged_and_recoupled() {
    for how in [Recouple::ReturnToPath, Recouple::KeepOffset] {
        let mut ex = Executor::new(config(), [0.0; 3]).unwrap();
        l_program(&mut ex);
        let mut sps = run_until(&mut ex, 300, |_, _, _| {}, |_| false);
        assert!(ex.release_coupling().is_err(), "released while moving");
        ex.feed_hold();
        sps.extend(run_until(&mut ex, 10_000, |_, _, _| {}, |s| s.state == ExecState::Held));
        let virt = sps.last().unwrap().path_positions;
        ex.release_coupling().unwrap();
        assert!(matches!(ex.cycle_start(), Err(CommandError::NotCoupled { .. })));
        ex.jog(1, 20.0).unwrap();
        sps.extend(run_until(&mut ex, 500, |_, _, _| {}, |_| false));
        ex.jog(1, 0.0).unwrap();
        sps.extend(run_until(&mut ex, 100, |_, _, _| {}, |_| false));
        let real = sps.last().unwrap().positions;
        assert!(real[1] - virt[1] > 9.0, "jogged {}", real[1] - virt[1]);
        assert_eq!(sps.last().unwrap().path_positions, virt, "virtual axes moved");
        ex.recouple(how).unwrap();
        sps.extend(run_until(&mut ex, 10_000, |_, _, _| {}, |s| s.coupling == CouplingState::Coupled));
        ex.cycle_start().unwrap();
        sps.extend(run_until(&mut ex, 100_000, |_, _, _| {}, idle));
        let end = sps.last().unwrap().positions;
        let offset = real[1] - virt[1];
        match how {
            Recouple::ReturnToPath => assert!(close(end, L_POINTS[3], 1e-9)),
            Recouple::KeepOffset => {
                assert!(close(end, [0.0, 40.0 + offset, 5.0], 1e-9), "{end:?}")
            }
        }
        assert_limits(&positions([0.0; 3], &sps));
    }
}

#[test]
fn single_block_switched_on_while_moving_stops_at_the_next_reachable_block_end() {
    // Short blocks (2 mm) at 100 mm/s: a stop needs 100² / (2 * 2000) = 2.5 mm on X, so the
    // end of the block being run may be out of reach; the stop comes at a later block end,
    // exactly at rest, within the limits.
    let mut ex = Executor::new(config(), [0.0; 3]).unwrap();
    for k in 1..=60u32 {
        let y = if k % 2 == 0 { 0.0 } else { 0.2 };
        ex.push(k, line([2.0 * k as f64, y, 0.0], 100.0)).unwrap();
    }
    ex.finish();
    let mut stop = None;
    let mut sps = run_until(
        &mut ex,
        100_000,
        |k, ex, sp| {
            if k == 400 {
                ex.set_single_block(true);
            }
            if let Some(Event::BlockStop { line }) = ex.poll_event() {
                stop = Some((k, line, sp.path_speed, sp.line));
            }
        },
        |s| s.state == ExecState::BlockStop,
    );
    let (k, line, v, _) = stop.unwrap();
    assert_eq!(v, 0.0);
    assert!(k > 400);
    let line_at_switch = sps[400].line;
    assert!(line > line_at_switch, "stopped at the end of line {line}, switched on in {line_at_switch}");
    ex.set_single_block(false);
    ex.cycle_start().unwrap();
    sps.extend(run_until(&mut ex, 100_000, |_, _, _| {}, idle));
    assert!(close(sps.last().unwrap().positions, [120.0, 0.0, 0.0], 1e-9));
    assert_limits(&positions([0.0; 3], &sps));
}

#[test]
fn override_zero_halts_on_the_path_and_restores() {
    let mut ex = Executor::new(config(), [0.0; 3]).unwrap();
    l_program(&mut ex);
    let sps = run_until(
        &mut ex,
        100_000,
        |k, ex, _| {
            if k == 300 {
                ex.set_override(0.0).unwrap();
            }
            if k == 900 {
                ex.set_override(1.0).unwrap();
            }
        },
        idle,
    );
    assert_eq!(sps[850].path_speed, 0.0);
    assert_eq!(sps[850].state, ExecState::Running);
    assert!(close(sps.last().unwrap().positions, L_POINTS[3], 1e-9));
    let pos = positions([0.0; 3], &sps);
    assert_limits(&pos);
    assert!(max_deviation(&pos, &L_POINTS, 0.05) <= 0.05 + 1e-9);
}

#[test]
fn braking_looks_through_asynchronous_markers() {
    // Straight on through an asynchronous M-function into a short last line: the first
    // line must already brake for the end of the second (regression: a zero-length marker
    // once passed an unlimited speed to the piece before it).
    let mut ex = Executor::new(config(), [0.0; 3]).unwrap();
    ex.push(1, line([40.0, 0.0, 0.0], 150.0)).unwrap();
    ex.push(2, PathItem::MFunction { number: 7, sync: false }).unwrap();
    ex.push(3, line([40.5, 0.0, 0.0], 150.0)).unwrap();
    ex.finish();
    let sps = run_until(&mut ex, 100_000, |_, _, _| {}, idle);
    assert!(close(sps.last().unwrap().positions, [40.5, 0.0, 0.0], 1e-9));
    assert_limits(&positions([0.0; 3], &sps));
}

#[test]
fn single_block_stops_at_a_reversal_and_before_the_markers_ending_a_block() {
    // A reversal is an exact stop (a marker after the block's motion): the block stop still
    // comes at the end of that block, not one block later. Likewise before an M-function.
    for (start, pts) in [
        ([50.0, 0.0, 0.0], [[0.0, 0.0, 0.0], [50.0, 20.0, 0.0], [0.0, 0.0, 0.0]]),
        ([0.0, 0.0, 0.0], [[50.0, 0.0, 0.0], [0.0, 0.0, 0.0], [50.0, 20.0, 0.0]]),
        ([0.0, 0.0, 0.0], [[50.0, 0.0, 0.0], [50.0, 20.0, 0.0], [0.0, 0.0, 0.0]]),
    ] {
        for with_m in [false, true] {
            let mut ex = Executor::new(config(), start).unwrap();
            ex.set_single_block(true);
            for (k, p) in pts.iter().enumerate() {
                ex.push(k as u32 + 1, line(*p, 50.0)).unwrap();
                if with_m && k == 0 {
                    ex.push(1, PathItem::MFunction { number: 100, sync: false }).unwrap();
                }
            }
            ex.finish();
            let mut stops = Vec::new();
            let sps = run_until(
                &mut ex,
                100_000,
                |_, ex, sp| {
                    while let Some(e) = ex.poll_event() {
                        if let Event::BlockStop { line } = e {
                            stops.push((line, sp.positions));
                            ex.cycle_start().unwrap();
                        }
                    }
                },
                idle,
            );
            assert_eq!(
                stops.iter().map(|s| s.0).collect::<Vec<_>>(),
                vec![1, 2],
                "{start:?} {pts:?} M {with_m}"
            );
            assert!(close(sps.last().unwrap().positions, pts[2], 1e-9));
        }
    }
}
