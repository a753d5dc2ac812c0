//! The driver against the simulator served in process ([`motus_serial::SimLink`]) on a
//! virtual clock, through the library (acceptance 3 and 4 of the PS1A issue): every
//! exchange takes its wire time at 115200 Bd, time-outs take virtual time only, and the
//! runs are deterministic (seeded faults included). `over_pty.rs` runs the same stack over
//! a real pseudo-terminal.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::*;
use motus_axis::{Axis, AxisCommand, AxisError, Direction, FaultKind, MotionProfile};
use motus_clock::Clock;
use motus_ps1a_protocol::{Command, LowStatus, REPLY_LEN};
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
    let v = Virtual::start(opts(&[1, 4, 7, 15]), BusConfig { margin: Duration::from_millis(5), retries: 0 });
    let t0 = v.clock.now();
    let found: Vec<u8> = v.bus.scan(0..=20).into_iter().map(|(a, _)| a).collect();
    assert_eq!(found, vec![1, 4, 7, 15]);
    // 17 silent addresses time out; 4 modules answer after the wire time of the exchange.
    let status = v.bus.master().line().wire_time(4 + REPLY_LEN);
    assert_eq!(v.clock.elapsed(t0), v.bus.status_timeout() * 17 + status * 4);
}

#[test]
fn home_then_absolute_and_relative_moves_end_at_target() {
    let v = Virtual::start(opts(&[2]), BusConfig::default());
    let mut a = axis(&v.bus, 2, 100_000);
    // Refused before homing (and before parameters).
    a.execute(&AxisCommand::Enable).unwrap();
    assert!(matches!(a.execute(&abs(1000)), Err(AxisError::NotHomed { .. })));
    let mut a = prepare(&v.bus, 2, 100_000);
    a.execute(&abs(12_345)).unwrap();
    let s = wait_idle(&v.bus, &mut a);
    assert_eq!(s.position_raw, 12_345);
    assert!(s.flags.target_reached);
    assert_eq!(v.modules().modules()[0].actual_position().round() as i64, 12_345, "the truth");
    a.execute(&AxisCommand::MoveRelative { distance: m(-2_345), profile: MotionProfile::default() }).unwrap();
    assert_eq!(wait_idle(&v.bus, &mut a).position_raw, 10_000);
    // A raw relative move (command 5) too.
    a.raw_relative_move(motus_ps1a_protocol::I24::new(555).unwrap()).unwrap();
    assert_eq!(wait_idle(&v.bus, &mut a).position_raw, 10_555);
    // SI profile: 0.05 m/s.
    a.execute(&AxisCommand::MoveAbsolute {
        target: 0.9,
        profile: MotionProfile { velocity: Some(0.5), acceleration: Some(3.0), deceleration: None },
    })
    .unwrap();
    let s = wait_idle(&v.bus, &mut a);
    assert_eq!(s.position_raw, 90_000);
    assert!((s.position - 0.9).abs() < 1e-9);
}

#[test]
fn beyond_maximum_is_refused_with_no_motion() {
    let v = Virtual::start(opts(&[3]), BusConfig::default());
    let mut a = prepare(&v.bus, 3, 50_000);
    let before = a.read_state().unwrap().position_raw;
    let err = a.execute(&abs(50_001)).unwrap_err();
    assert!(matches!(err, AxisError::BeyondLimit { .. }), "{err}");
    assert!(err.to_string().contains("beyond the limit"), "{err}");
    // The host believes the maximum is larger: the module refuses (LBS bit 6).
    let mut lax = axis(&v.bus, 3, 80_000);
    let err = lax.execute(&abs(60_000)).unwrap_err();
    assert!(matches!(err, AxisError::Refused { .. }), "{err}");
    assert!(err.to_string().contains("LBS bit 6"), "{err}");
    v.clock.sleep(Duration::from_millis(100));
    let s = a.read_state().unwrap();
    assert_eq!(s.position_raw, before);
    assert!(!s.flags.moving);
}

#[test]
fn jog_stops_at_the_maximum_position() {
    let v = Virtual::start(opts(&[5]), BusConfig::default());
    let mut a = prepare(&v.bus, 5, 30_000);
    a.execute(&AxisCommand::Jog { direction: Direction::Positive, profile: MotionProfile::default() })
        .unwrap();
    let s = wait_idle(&v.bus, &mut a);
    assert_eq!(s.position_raw, 30_000);
    a.execute(&AxisCommand::Jog { direction: Direction::Negative, profile: MotionProfile::default() })
        .unwrap();
    v.clock.sleep(Duration::from_millis(100));
    a.execute(&AxisCommand::Stop).unwrap();
    let s = wait_idle(&v.bus, &mut a);
    assert!(s.position_raw > 0 && s.position_raw < 30_000, "{}", s.position_raw);
}

#[test]
fn status_bits_clear_after_being_reported() {
    let machine = MachineConfig { limit_positive: 30_000.0, ..MachineConfig::default() };
    let v = Virtual::start(LineOptions { machine, ..opts(&[6]) }, BusConfig::default());
    let mut a = prepare(&v.bus, 6, 100_000);
    a.execute(&abs(90_000)).unwrap();
    let s = wait_stopped(&mut a, v.bus.master().clock());
    let fault = s.faults.first().expect("the limit switch stopped the move");
    assert!(fault.reason.contains("limit switch"), "{fault:?}");
    // The module reported bit 2 once; the next raw status has it cleared...
    let raw = v.bus.transact(6, Command::StatusRequest).unwrap();
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
    let state = dir.path().join("state.json");
    let o = LineOptions { state_file: Some(state.clone()), ..opts(&[1]) };
    let v = Virtual::start(o.clone(), BusConfig::default());
    v.bus.write_parameters(1, fast_params(9, 20_000)).unwrap();
    v.modules().save().unwrap();
    drop(v);
    let v = Virtual::start(o, BusConfig { margin: Duration::from_millis(5), retries: 0 });
    let found: Vec<u8> = v.bus.scan(0..=15).into_iter().map(|(a, _)| a).collect();
    assert_eq!(found, vec![9], "the new address was kept in EEPROM");
    let mut a = axis(&v.bus, 9, 100_000);
    a.execute(&AxisCommand::Enable).unwrap();
    a.execute(&AxisCommand::Home).unwrap();
    wait_idle(&v.bus, &mut a);
    let err = a.execute(&abs(25_000)).unwrap_err();
    assert!(err.to_string().contains("maximum position"), "the stored maximum 20000 applies: {err}");
}

#[test]
fn sixteen_modules_on_one_line_are_independent() {
    let addresses: Vec<u8> = (1..=16).collect();
    let v = Virtual::start(opts(&addresses), BusConfig::default());
    let mut axes: Vec<_> = addresses
        .iter()
        .map(|&a| {
            v.bus.write_parameters(a, fast_params(a, 200_000)).unwrap();
            let mut ax = axis(&v.bus, a, 200_000);
            ax.execute(&AxisCommand::Enable).unwrap();
            ax.execute(&AxisCommand::Home).unwrap();
            ax
        })
        .collect();
    for ax in axes.iter_mut() {
        assert!(wait_idle(&v.bus, ax).flags.homed);
    }
    for (i, ax) in axes.iter_mut().enumerate() {
        ax.execute(&abs(1_000 + 7_919 * i as i64)).unwrap();
    }
    for (i, ax) in axes.iter_mut().enumerate() {
        assert_eq!(wait_idle(&v.bus, ax).position_raw, 1_000 + 7_919 * i as i64, "module {}", i + 1);
    }
    // Jog one, stop it; the others do not move.
    axes[3]
        .execute(&AxisCommand::Jog { direction: Direction::Positive, profile: MotionProfile::default() })
        .unwrap();
    v.clock.sleep(Duration::from_millis(50));
    axes[3].execute(&AxisCommand::Stop).unwrap();
    wait_idle(&v.bus, &mut axes[3]);
    for (i, ax) in axes.iter_mut().enumerate().filter(|(i, _)| *i != 3) {
        assert_eq!(ax.read_state().unwrap().position_raw, 1_000 + 7_919 * i as i64);
    }
    let truth: Vec<i64> = v.modules().modules().iter().map(|m| m.actual_position().round() as i64).collect();
    assert!(truth[3] > 1_000 + 7_919 * 3, "module 4 jogged: {truth:?}");
}

#[test]
fn a_missing_module_times_out_exactly_and_the_line_keeps_serving() {
    let config = BusConfig { margin: Duration::from_millis(20), retries: 2 };
    let v = Virtual::start(opts(&[1]), config);
    let mut missing = axis(&v.bus, 8, 65_535);
    let (t0, wall) = (v.clock.now(), Instant::now());
    let err = missing.read_state().unwrap_err();
    assert!(matches!(err, AxisError::Timeout { attempts: 3, .. }), "{err}");
    assert_eq!(v.clock.elapsed(t0), v.bus.status_timeout() * 3);
    assert!(wall.elapsed() < Duration::from_secs(5), "virtual time-outs do not wait: {:?}", wall.elapsed());
    assert!(axis(&v.bus, 1, 65_535).read_state().is_ok());
    assert_eq!(v.bus.master().device_stats(8).failures, 1);
}

/// Moves module 1 through a list of targets on a faulty line, checking every reading; the
/// bus statistics and the virtual time it took.
fn faulty_moves(seed: u64) -> (motus_serial::BusStats, Duration) {
    let faults = FaultConfig { drop_rate: 0.01, corrupt_rate: 0.01, seed };
    let v = Virtual::start(
        LineOptions { faults, ..opts(&[1, 2]) },
        BusConfig { margin: Duration::from_millis(10), retries: 5 },
    );
    let t0 = v.clock.now();
    let mut a = prepare(&v.bus, 1, 200_000);
    let mut b = prepare(&v.bus, 2, 200_000);
    let targets = [50_000i64, 12_000, 180_000, 3, 99_999, 100_000, 64_000];
    let b_pos = b.read_state().unwrap().position_raw;
    let mut start = a.read_state().unwrap().position_raw;
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
    let modules = v.modules();
    assert_eq!(modules.modules()[0].actual_position().round() as i64, 64_000);
    assert_eq!(modules.modules()[1].actual_position().round() as i64, b_pos);
    (v.bus.master().stats(), v.clock.elapsed(t0))
}

#[test]
fn one_percent_corruption_never_gives_a_wrong_position_or_motion_and_repeats_exactly() {
    let (stats, took) = faulty_moves(7);
    println!("{took:?} of virtual time; bus stats {stats:?}");
    assert!(
        stats.totals.corrupt_frames > 0 && stats.totals.timeouts > 0,
        "faults were injected and detected: {stats:?}"
    );
    assert_eq!(faulty_moves(7), (stats, took), "the same seed gives the same run");
}

#[test]
fn a_module_restart_during_motion_is_detected_and_motion_refused_until_homed() {
    let dir = tempfile::tempdir().unwrap();
    let o = LineOptions { state_file: Some(dir.path().join("s.json")), ..opts(&[1]) };
    let v = Virtual::start(o.clone(), BusConfig::default());
    let mut a = prepare(&v.bus, 1, 200_000);
    a.execute(&AxisCommand::MoveAbsolute {
        target: m(150_000),
        profile: MotionProfile { velocity: Some(0.2), acceleration: None, deceleration: None },
    })
    .unwrap();
    v.clock.sleep(Duration::from_millis(200));
    // The simulator restarts from its state file on the same line; the driver keeps polling.
    v.modules().save().unwrap();
    let (restarted, _modules) = sim_link(o, &v.clock);
    *v.cable.lock().unwrap() = restarted;
    let s = a.read_state().unwrap();
    assert!(!s.flags.homed);
    assert_eq!(s.faults.first().map(|f| f.kind), Some(FaultKind::DeviceReset), "{:?}", s.faults);
    let err = a.execute(&abs(1000)).unwrap_err();
    assert!(matches!(err, AxisError::NotHomed { .. }), "{err}");
    assert!(err.to_string().contains("reset was detected"), "{err}");
    a.execute(&AxisCommand::Enable).unwrap();
    a.execute(&AxisCommand::Home).unwrap();
    assert!(wait_idle(&v.bus, &mut a).flags.homed);
    a.execute(&abs(1000)).unwrap();
    assert_eq!(wait_idle(&v.bus, &mut a).position_raw, 1000);
}
