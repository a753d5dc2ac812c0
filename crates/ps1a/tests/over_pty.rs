//! Integration over a real pty against the simulator, through the library (acceptance 3
//! and 4 of the PS1A issue).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::*;
use motus_axis::{Axis, AxisCommand, AxisError, Direction, FaultKind, MotionProfile};
use motus_ps1a_protocol::{Command, LowStatus, U24};
use motus_ps1a_sim::{LineOptions, MachineConfig};
use motus_serial::{BusConfig, FaultConfig};
use std::time::{Duration, Instant};

fn opts(addresses: &[u8]) -> LineOptions {
    LineOptions { addresses: addresses.to_vec(), ..LineOptions::default() }
}

fn abs(target: i64) -> AxisCommand {
    AxisCommand::MoveAbsolute { target: m(target), profile: MotionProfile::default() }
}

#[test]
fn scan_finds_exactly_the_configured_addresses() {
    let dir = tempfile::tempdir().unwrap();
    let _sim = Sim::start(&dir.path().join("line"), opts(&[1, 4, 7, 15]));
    let bus = bus(&dir.path().join("line"), BusConfig { margin: Duration::from_millis(5), retries: 0 });
    let found: Vec<u8> = bus.scan(0..=20).into_iter().map(|(a, _)| a).collect();
    assert_eq!(found, vec![1, 4, 7, 15]);
}

#[test]
fn home_then_absolute_and_relative_moves_end_at_target() {
    let dir = tempfile::tempdir().unwrap();
    let _sim = Sim::start(&dir.path().join("line"), opts(&[2]));
    let bus = bus(&dir.path().join("line"), BusConfig::default());
    let mut a = axis(&bus, 2, 100_000);
    // Refused before homing (and before parameters).
    a.execute(&AxisCommand::Enable).unwrap();
    assert!(matches!(a.execute(&abs(1000)), Err(AxisError::NotHomed { .. })));
    let mut a = prepare(&bus, 2, 100_000);
    a.execute(&abs(12_345)).unwrap();
    let s = wait_idle(&mut a);
    assert_eq!(s.position_raw, 12_345);
    assert!(s.flags.target_reached);
    a.execute(&AxisCommand::MoveRelative { distance: m(-2_345), profile: MotionProfile::default() }).unwrap();
    assert_eq!(wait_idle(&mut a).position_raw, 10_000);
    // A raw relative move (command 5) too.
    a.raw_relative_move(motus_ps1a_protocol::I24::new(555).unwrap()).unwrap();
    assert_eq!(wait_idle(&mut a).position_raw, 10_555);
    // SI profile: 0.05 m/s.
    a.execute(&AxisCommand::MoveAbsolute {
        target: 0.9,
        profile: MotionProfile { velocity: Some(0.5), acceleration: Some(3.0), deceleration: None },
    })
    .unwrap();
    let s = wait_idle(&mut a);
    assert_eq!(s.position_raw, 90_000);
    assert!((s.position - 0.9).abs() < 1e-9);
}

#[test]
fn beyond_maximum_is_refused_with_no_motion() {
    let dir = tempfile::tempdir().unwrap();
    let _sim = Sim::start(&dir.path().join("line"), opts(&[3]));
    let bus = bus(&dir.path().join("line"), BusConfig::default());
    let mut a = prepare(&bus, 3, 50_000);
    let before = a.read_state().unwrap().position_raw;
    let err = a.execute(&abs(50_001)).unwrap_err();
    assert!(matches!(err, AxisError::BeyondLimit { .. }), "{err}");
    assert!(err.to_string().contains("beyond the limit"), "{err}");
    // The host believes the maximum is larger: the module refuses (LBS bit 6).
    let mut lax = axis(&bus, 3, 80_000);
    let err = lax.execute(&abs(60_000)).unwrap_err();
    assert!(matches!(err, AxisError::Refused { .. }), "{err}");
    assert!(err.to_string().contains("LBS bit 6"), "{err}");
    std::thread::sleep(Duration::from_millis(100));
    let s = a.read_state().unwrap();
    assert_eq!(s.position_raw, before);
    assert!(!s.flags.moving);
}

#[test]
fn jog_stops_at_the_maximum_position() {
    let dir = tempfile::tempdir().unwrap();
    let _sim = Sim::start(&dir.path().join("line"), opts(&[5]));
    let bus = bus(&dir.path().join("line"), BusConfig::default());
    let mut a = prepare(&bus, 5, 30_000);
    a.execute(&AxisCommand::Jog { direction: Direction::Positive, profile: MotionProfile::default() })
        .unwrap();
    let s = wait_idle(&mut a);
    assert_eq!(s.position_raw, 30_000);
    assert!(s.faults.is_empty(), "{:?}", s.faults);
    a.execute(&AxisCommand::Jog { direction: Direction::Negative, profile: MotionProfile::default() })
        .unwrap();
    std::thread::sleep(Duration::from_millis(100));
    a.execute(&AxisCommand::Stop).unwrap();
    let s = wait_idle(&mut a);
    assert!(s.position_raw > 0 && s.position_raw < 30_000, "{}", s.position_raw);
}

#[test]
fn status_bits_clear_after_being_reported() {
    let dir = tempfile::tempdir().unwrap();
    let machine = MachineConfig { limit_positive: 30_000.0, ..MachineConfig::default() };
    let _sim = Sim::start(&dir.path().join("line"), LineOptions { machine, ..opts(&[6]) });
    let bus = bus(&dir.path().join("line"), BusConfig::default());
    let mut a = prepare(&bus, 6, 100_000);
    a.execute(&abs(90_000)).unwrap();
    let err = motus_axis::wait_until(
        &mut a,
        "move",
        Duration::from_secs(30),
        Duration::from_millis(5),
        |s| !s.flags.moving,
        |_| {},
    )
    .unwrap_err();
    assert!(err.to_string().contains("limit switch"), "{err}");
    // The module reported bit 2 once; the next raw status has it cleared...
    let raw = bus.transact(6, Command::StatusRequest).unwrap();
    assert!(!raw.low.has(LowStatus::LIMIT_SWITCH));
    // ...but the driver keeps it latched until fault-reset, and refuses motion.
    let s = a.read_state().unwrap();
    assert_eq!(s.faults.first().map(|f| f.kind), Some(FaultKind::LimitSwitch));
    assert!(matches!(a.execute(&abs(1000)), Err(AxisError::DeviceFault { .. })));
    a.execute(&AxisCommand::FaultReset).unwrap();
    assert!(a.read_state().unwrap().faults.is_empty());
    assert!(!a.read_state().unwrap().flags.enabled, "the module switched its power stage off");
}

#[test]
fn parameters_survive_a_simulator_restart() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("line");
    let state = dir.path().join("state.json");
    let o = LineOptions { state_file: Some(state.clone()), ..opts(&[1]) };
    let sim = Sim::start(&path, o.clone());
    let b = bus(&path, BusConfig::default());
    b.write_parameters(1, fast_params(9, 20_000)).unwrap();
    drop(b);
    sim.stop();
    let _sim = Sim::start(&path, o);
    let b = bus(&path, BusConfig { margin: Duration::from_millis(5), retries: 0 });
    let found: Vec<u8> = b.scan(0..=15).into_iter().map(|(a, _)| a).collect();
    assert_eq!(found, vec![9], "the new address was kept in EEPROM");
    drop(b);
    let b = bus(&path, BusConfig::default());
    let mut a = axis(&b, 9, 100_000);
    a.execute(&AxisCommand::Enable).unwrap();
    a.execute(&AxisCommand::Home).unwrap();
    wait_idle(&mut a);
    let err = a.execute(&abs(25_000)).unwrap_err();
    assert!(err.to_string().contains("maximum position"), "the stored maximum 20000 applies: {err}");
}

#[test]
fn sixteen_modules_on_one_line_are_independent() {
    let dir = tempfile::tempdir().unwrap();
    let addresses: Vec<u8> = (1..=16).collect();
    let _sim = Sim::start(&dir.path().join("line"), opts(&addresses));
    let bus = bus(&dir.path().join("line"), BusConfig::default());
    let mut axes: Vec<_> = addresses
        .iter()
        .map(|&a| {
            bus.write_parameters(a, fast_params(a, 200_000)).unwrap();
            let mut ax = axis(&bus, a, 200_000);
            ax.execute(&AxisCommand::Enable).unwrap();
            ax.execute(&AxisCommand::Home).unwrap();
            ax
        })
        .collect();
    for ax in axes.iter_mut() {
        assert!(wait_idle(ax).flags.homed);
    }
    for (i, ax) in axes.iter_mut().enumerate() {
        ax.execute(&abs(1_000 + 7_919 * i as i64)).unwrap();
    }
    for (i, ax) in axes.iter_mut().enumerate() {
        assert_eq!(wait_idle(ax).position_raw, 1_000 + 7_919 * i as i64, "module {}", i + 1);
    }
    // Jog one, stop it; the others do not move.
    axes[3]
        .execute(&AxisCommand::Jog { direction: Direction::Positive, profile: MotionProfile::default() })
        .unwrap();
    std::thread::sleep(Duration::from_millis(50));
    axes[3].execute(&AxisCommand::Stop).unwrap();
    wait_idle(&mut axes[3]);
    for (i, ax) in axes.iter_mut().enumerate().filter(|(i, _)| *i != 3) {
        assert_eq!(ax.read_state().unwrap().position_raw, 1_000 + 7_919 * i as i64);
    }
}

#[test]
fn missing_module_times_out_in_time_and_the_line_keeps_serving() {
    let dir = tempfile::tempdir().unwrap();
    let _sim = Sim::start(&dir.path().join("line"), opts(&[1]));
    let config = BusConfig { margin: Duration::from_millis(20), retries: 2 };
    let bus = bus(&dir.path().join("line"), config);
    let mut missing = axis(&bus, 8, 65_535);
    let t0 = Instant::now();
    let err = missing.read_state().unwrap_err();
    let took = t0.elapsed();
    let limit = bus.master().timeout_for(4, 8) * 3;
    assert!(matches!(err, AxisError::Timeout { attempts: 3, .. }), "{err}");
    assert!(took >= limit && took < limit + Duration::from_millis(50), "{took:?} vs {limit:?}");
    assert!(axis(&bus, 1, 65_535).read_state().is_ok());
    assert_eq!(bus.master().device_stats(8).failures, 1);
}

#[test]
fn one_percent_corruption_never_gives_a_wrong_position_or_motion() {
    let dir = tempfile::tempdir().unwrap();
    let faults = FaultConfig { drop_rate: 0.01, corrupt_rate: 0.01, seed: 7 };
    let sim = Sim::start(&dir.path().join("line"), LineOptions { faults, ..opts(&[1, 2]) });
    let bus = bus(&dir.path().join("line"), BusConfig { margin: Duration::from_millis(10), retries: 5 });
    let mut a = prepare(&bus, 1, 200_000);
    let mut b = prepare(&bus, 2, 200_000);
    let targets = [50_000i64, 12_000, 180_000, 3, 99_999, 100_000, 64_000];
    let b_pos = b.read_state().unwrap().position_raw;
    let mut start = a.read_state().unwrap().position_raw;
    let mut readings = 0;
    for &target in &targets {
        let (lo, hi) = (start.min(target), start.max(target));
        a.execute(&abs(target)).unwrap_or_else(|e| panic!("move to {target}: {e}"));
        loop {
            // Every position read during the move lies on the path; module 2 never moves.
            let s = match a.read_state() {
                Ok(s) => s,
                Err(AxisError::Timeout { .. }) => continue,
                Err(e) => panic!("{e}"),
            };
            readings += 1;
            assert!(
                (lo..=hi).contains(&s.position_raw),
                "implausible position {} during move {start} -> {target}",
                s.position_raw
            );
            if !s.flags.moving {
                assert_eq!(s.position_raw, target);
                break;
            }
        }
        if let Ok(s) = b.read_state() {
            assert_eq!(s.position_raw, b_pos, "module 2 must not move");
        }
        start = target;
    }
    let stats = bus.master().stats();
    let line = sim.stop();
    assert_eq!(line.modules()[0].actual_position().round() as i64, 64_000);
    assert_eq!(line.modules()[1].actual_position().round() as i64, b_pos);
    assert!(
        stats.totals.corrupt_frames + stats.totals.timeouts > 0,
        "faults were injected and detected: {stats:?}"
    );
    eprintln!("{readings} readings; bus stats {stats:?}");
}

#[test]
fn a_module_restart_during_motion_is_detected_and_motion_refused_until_homed() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("line");
    let o = LineOptions { state_file: Some(dir.path().join("s.json")), ..opts(&[1]) };
    let sim = Sim::start(&path, o.clone());
    let bus = bus(&path, BusConfig::default());
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
    for _ in 0..50 {
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
    assert!(wait_idle(&mut a).flags.homed);
    a.execute(&abs(1000)).unwrap();
    assert_eq!(wait_idle(&mut a).position_raw, 1000);
    let _ = U24::MAX;
}
