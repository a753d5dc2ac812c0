//! Smoke tests over a real pty against the simulator served on its own thread
//! ([`motus_serial::SimServer::run`]), through the library: bytes cross the kernel's pty,
//! everything happens in real time, so only generous liveness bounds apply. The
//! functional tests (acceptance 3 and 4 of the PS1A issue) run on virtual time in
//! `sim_line.rs`.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::*;
use motus_axis::{Axis, AxisCommand, AxisError, FaultKind, MotionProfile};
use motus_ps1a_sim::LineOptions;
use motus_serial::BusConfig;
use std::time::{Duration, Instant};

fn opts(addresses: &[u8]) -> LineOptions {
    LineOptions { addresses: addresses.to_vec(), ..LineOptions::default() }
}

fn abs(target: i64) -> AxisCommand {
    AxisCommand::MoveAbsolute { target: m(target), profile: MotionProfile::default() }
}

/// A smoke test's reply margin: a simulator on a loaded host answers late (the time-outs of
/// a real line are checked on virtual time, `sim_line.rs`).
fn generous() -> BusConfig {
    BusConfig { margin: Duration::from_millis(100), retries: 2 }
}

#[test]
fn scan_home_move_and_time_out_over_a_pty() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("line");
    let _sim = Sim::start(&path, LineOptions { baud_pacing: true, ..opts(&[1, 4]) });
    let scan = bus(&path, BusConfig { margin: Duration::from_millis(100), retries: 1 });
    let found: Vec<u8> = scan.scan(0..=5).into_iter().map(|(a, _)| a).collect();
    assert_eq!(found, vec![1, 4]);
    drop(scan);
    let bus = bus(&path, generous());
    let mut a = prepare(&bus, 4, 100_000);
    a.execute(&abs(12_345)).unwrap();
    assert_eq!(wait_idle(&bus, &mut a).position_raw, 12_345);
    let t0 = Instant::now();
    let err = axis(&bus, 8, 65_535).read_state().unwrap_err();
    let took = t0.elapsed();
    let limit = bus.master().timeout_for(4, 8) * 3;
    println!("3 time-outs of a missing module took {took:?} ({limit:?} on the wire)");
    assert!(matches!(err, AxisError::Timeout { attempts: 3, .. }), "{err}");
    assert!(took >= limit && took < limit + Duration::from_secs(5), "{took:?} vs {limit:?}");
}

/// The real transport's reconnection: the simulator's pty goes away and comes back, the
/// host's serial port is reopened by itself.
#[test]
fn a_module_restart_during_motion_is_detected_and_motion_refused_until_homed() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("line");
    let o = LineOptions { state_file: Some(dir.path().join("s.json")), ..opts(&[1]) };
    let sim = Sim::start(&path, o.clone());
    let bus = bus(&path, generous());
    let mut a = prepare(&bus, 1, 200_000);
    a.execute(&AxisCommand::MoveAbsolute {
        target: m(150_000),
        profile: MotionProfile { velocity: Some(0.2), acceleration: None, deceleration: None },
    })
    .unwrap();
    std::thread::sleep(Duration::from_millis(200));
    sim.stop();
    let _sim = Sim::start(&path, o);
    // The same driver instance keeps polling: the link is reopened, the reset seen.
    let mut state = None;
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(10) {
        match a.read_state() {
            Ok(s) => {
                state = Some(s);
                break;
            }
            Err(_) => std::thread::sleep(Duration::from_millis(20)),
        }
    }
    let s = state.expect("the driver reconnects to the restarted simulator");
    assert!(!s.flags.homed);
    assert_eq!(s.faults.first().map(|f| f.kind), Some(FaultKind::DeviceReset), "{:?}", s.faults);
    let err = a.execute(&abs(1000)).unwrap_err();
    assert!(matches!(err, AxisError::NotHomed { .. }), "{err}");
    assert!(err.to_string().contains("reset was detected"), "{err}");
    a.execute(&AxisCommand::Enable).unwrap();
    a.execute(&AxisCommand::Home).unwrap();
    assert!(wait_idle(&bus, &mut a).flags.homed);
    a.execute(&abs(1000)).unwrap();
    assert_eq!(wait_idle(&bus, &mut a).position_raw, 1000);
}
