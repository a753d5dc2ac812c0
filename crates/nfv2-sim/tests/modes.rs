//! Every operating mode on a virtual clock, with the default regulators: POSITION reaches
//! its target, SPEED tracks, CURRENT and PWM drive the motor as the motor equations say,
//! MANUAL follows AI0, POS_INCREMENT integrates the speed, HOMING finds the edge.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::{units_to_counts_s, Rig};
use motus_nfv2_protocol::{CommandCode as C, DriveMode, DriveStatus, Regulator};
use motus_nfv2_sim::{ControllerConfig, MotorConfig};

#[test]
fn power_on_is_error_mode_and_still() {
    let mut rig = Rig::new();
    rig.run_ms(100);
    let s = rig.status();
    assert!(s.contains(DriveStatus::ERROR), "{s}");
    assert!(!s.contains(DriveStatus::SYNCHRONIZED));
    assert_eq!(rig.position(), 0);
    let t = rig.truth();
    assert_eq!(t.mode, DriveMode::Error);
    assert!(!t.bridge_on);
    assert_eq!(t.speed_counts_per_s, 0.0);
}

#[test]
fn position_mode_reaches_the_target_with_the_default_regulators() {
    let mut rig = Rig::new();
    rig.mode(DriveMode::Position);
    rig.set(C::SetDrivesPosition, 50_000);
    // 50 000 counts at 120 000 counts/s and 1e6 counts/s²: 0.54 s.
    let mut peak_speed: f64 = 0.0;
    let mut worst_lag: f64 = 0.0;
    rig.run_ms_with(800, |t| {
        peak_speed = peak_speed.max(t.speed_counts_per_s.abs());
        worst_lag = worst_lag.max((t.position_reference.unwrap() - t.counter as f64).abs());
    });
    let t = rig.truth();
    assert!((t.counter - 50_000).abs() <= 2, "counter {}", t.counter);
    assert!(t.speed_counts_per_s.abs() < 200.0, "speed {}", t.speed_counts_per_s);
    assert_eq!(rig.position(), t.counter);
    assert!(peak_speed <= units_to_counts_s(12_000.0) * 1.05, "peak {peak_speed}");
    assert!(worst_lag < 1_000.0, "following error {worst_lag}");
    assert!(!rig.status().contains(DriveStatus::ERROR));
    // Settled: stays within a count or two.
    rig.run_ms_with(500, |t| assert!((t.counter - 50_000).abs() <= 2, "{}", t.counter));
}

#[test]
fn position_mode_uses_the_speed_setpoint_as_profile_speed() {
    let mut rig = Rig::new();
    rig.mode(DriveMode::Position);
    rig.set(C::SetDrivesSpeed, 2_000); // 20 000 counts/s
    rig.set(C::SetDrivesPosition, -30_000);
    // Cruise from 0.1 s to 1.4 s: the reference moves at exactly 20 000 counts/s, the
    // axis follows it (the start overshoots while the speed loop builds up the current
    // for the friction).
    rig.run_ms(100);
    let p0 = rig.truth().position_counts;
    rig.run_ms_with(1_300, |t| assert_eq!(t.speed_reference, Some(-20_000.0)));
    let mean = (p0 - rig.truth().position_counts) / 1.3;
    assert!((mean - 20_000.0).abs() < 100.0, "{mean}");
    rig.run_ms(600);
    assert!((rig.truth().counter + 30_000).abs() <= 2);
}

#[test]
fn speed_mode_tracks_the_setpoint() {
    let mut rig = Rig::new();
    rig.mode(DriveMode::Speed);
    rig.set(C::SetDrivesSpeed, 5_000); // 50 000 counts/s = 1500 rpm
    rig.run_ms(300);
    let mut speeds = Vec::new();
    rig.run_ms_with(200, |t| speeds.push(t.speed_counts_per_s));
    let mean = speeds.iter().sum::<f64>() / speeds.len() as f64;
    assert!((mean - 50_000.0).abs() < 250.0, "mean {mean}");
    for s in &speeds {
        assert!((s - 50_000.0).abs() < 2_000.0, "{s}");
    }
    // Reverse: the ramp at 1e6 counts/s² takes 0.1 s, then it tracks again.
    rig.set(C::SetDrivesSpeed, -3_000);
    rig.run_ms(400);
    let v = rig.truth().speed_counts_per_s;
    assert!((v + 30_000.0).abs() < 1_500.0, "{v}");
    let s = rig.status();
    assert!(!s.contains(DriveStatus::SPEED_LIMIT) && !s.contains(DriveStatus::ERROR), "{s}");
}

#[test]
fn current_mode_gives_the_torque_asked() {
    let mut rig = Rig::new();
    rig.mode(DriveMode::Current);
    rig.set(C::SetDrivesCurrent, 1_000);
    rig.run_ms(20);
    let t = rig.truth();
    // The current loop's integral lags the rising back-EMF a little (about 3 %).
    assert!((t.current_a - 1.0).abs() < 0.04, "{}", t.current_a);
    // Acceleration = (kt i - Tc - b w) / J: check the speed after 20 ms by hand.
    let m = MotorConfig::default();
    let accel = (m.torque_constant_nm_per_a * 1.0 - m.coulomb_friction_nm) / m.inertia_kg_m2;
    let expected = accel * 0.02 / std::f64::consts::TAU * m.encoder_counts_per_rev;
    assert!(
        (t.speed_counts_per_s - expected).abs() < 0.1 * expected,
        "{} vs {expected}",
        t.speed_counts_per_s
    );
    let ma = rig.read(C::ReadDrivesCurrent);
    assert!((ma as f64 - t.current_a * 1000.0).abs() <= 11.0, "{ma} vs {}", t.current_a);
}

#[test]
fn pwm_mode_sets_the_voltage() {
    let mut rig = Rig::new();
    rig.mode(DriveMode::Pwm);
    rig.set(C::SetDrivesPwm, 500); // 50 % of 24 V
    rig.run_ms(400);
    let t = rig.truth();
    assert!((t.voltage_v - 12.0).abs() < 1e-9);
    let m = MotorConfig::default();
    let (k, r) = (m.torque_constant_nm_per_a, m.resistance_ohm);
    let w = (k * 12.0 / r - m.coulomb_friction_nm) / (k * k / r + m.viscous_friction_nm_s_per_rad);
    let expected = w / std::f64::consts::TAU * m.encoder_counts_per_rev;
    assert!((t.speed_counts_per_s - expected).abs() < 0.01 * expected);
    // Zero duty: the bridge is off (the reference's "still" pattern), the motor coasts.
    rig.set(C::SetDrivesPwm, 0);
    rig.run_ms(2);
    assert!(!rig.truth().bridge_on);
}

#[test]
fn pwm_start_is_current_limited() {
    let mut rig = Rig::new();
    rig.set(C::SetDrivesMaxCurrent, 2_000);
    rig.mode(DriveMode::Pwm);
    rig.set(C::SetDrivesPwm, 1_000);
    let mut peak: f64 = 0.0;
    let mut limited = false;
    for _ in 0..50 {
        rig.run_ms(1);
        peak = peak.max(rig.truth().current_a.abs());
        limited |= rig.status().contains(DriveStatus::CURRENT_LIMIT);
    }
    assert!(peak <= 2.0 + 1e-6, "{peak}");
    assert!(limited);
}

#[test]
fn manual_mode_follows_ai0() {
    let mut rig = Rig::new();
    rig.mode(DriveMode::Manual);
    rig.run_ms(100);
    assert_eq!(rig.truth().speed_counts_per_s, 0.0, "AI0 at 12 V: stop");
    rig.c.set_analog_input(0, 18.0).unwrap(); // +6 V of 12: about half power forward
    rig.run_ms(400);
    let forward = rig.truth().speed_counts_per_s;
    assert!(forward > 40_000.0, "{forward}");
    rig.c.set_analog_input(0, 3.0).unwrap(); // -9 V: faster, backwards
    rig.run_ms(400);
    let backward = rig.truth().speed_counts_per_s;
    assert!(backward < -1.3 * forward, "{backward}");
    let ai = rig.read_all(C::ReadAnalogInputs);
    assert!((ai[0] - 3_000).abs() <= 15, "{ai:?}");
}

#[test]
fn pos_increment_integrates_the_speed() {
    let mut rig = Rig::new();
    rig.mode(DriveMode::PosIncrement);
    rig.set(C::SetDrivesSpeed, 1_000); // 10 000 counts/s
    rig.run_ms(1_000);
    let t = rig.truth();
    // 1 s at 10 000 counts/s minus the 10 ms ramp (50 counts lost).
    assert!((t.position_reference.unwrap() - 9_950.0).abs() < 15.0, "{:?}", t.position_reference);
    assert!((t.counter as f64 - t.position_reference.unwrap()).abs() < 30.0);
    rig.set(C::SetDrivesSpeed, 0);
    rig.run_ms(300);
    let hold = rig.truth().counter;
    rig.run_ms(300);
    assert_eq!(rig.truth().counter, hold);
}

#[test]
fn homing_finds_the_edge_and_sets_synchronized() {
    for (start, edge) in [(0.0, -3_000.0), (-8_000.0, -3_000.0), (5_000.0, 7_321.0)] {
        let config = ControllerConfig {
            initial_position_counts: start,
            home_edge_counts: Some(edge),
            home_position: 100,
            ..ControllerConfig::default()
        };
        let mut rig = Rig::with(config);
        rig.mode(DriveMode::Homing);
        let mut synchronized_at = None;
        for ms in 0..4_000 {
            rig.run_ms(1);
            if rig.status().contains(DriveStatus::SYNCHRONIZED) {
                synchronized_at = Some(ms);
                break;
            }
        }
        assert!(synchronized_at.is_some(), "start {start}: never synchronized");
        rig.run_ms(1_000);
        let t = rig.truth();
        // The counter reads 100 at the edge, within what 1 ms at the homing speed
        // (5 000 counts/s) and the encoder resolution allow.
        let at_edge = t.counter as f64 - (t.position_counts - edge);
        assert!((at_edge - 100.0).abs() <= 7.0, "start {start}: counter at the edge {at_edge}");
        assert!(t.speed_counts_per_s.abs() < 1.0, "holds after homing: {}", t.speed_counts_per_s);
        assert!((t.counter as f64 - t.position_reference.unwrap()).abs() <= 15.0);
        assert!(t.home == (t.position_counts <= edge));
        assert!(rig.status().contains(DriveStatus::SYNCHRONIZED));
    }
}

#[test]
fn regulators_are_set_and_used() {
    let mut rig = Rig::new();
    let soft = Regulator { p: 1500, i: 0, d: 0, t: 0 };
    rig.regulator(C::SetPositionRegulator, soft);
    assert_eq!(rig.c.regulators()[2], soft);
    rig.mode(DriveMode::Position);
    rig.set(C::SetDrivesPosition, 20_000);
    rig.run_ms(1_000);
    assert!((rig.truth().counter - 20_000).abs() <= 3);
    // A position regulator without gain does not correct: feed-forward only.
    let none = Regulator::default();
    rig.regulator(C::SetPositionRegulator, none);
    rig.regulator(C::SetSpeedRegulator, Regulator { p: 300, i: 10, d: 0, t: 0 });
    assert_eq!(rig.c.regulators()[1].p, 300);
}

#[test]
fn the_truth_trace_keeps_every_cycle_however_far_one_advances() {
    let mut rig = Rig::new();
    rig.mode(DriveMode::Position);
    rig.set(C::SetDrivesPosition, 20_000);
    rig.c.trace_truth(Some(100));
    let mut stepped = Vec::new();
    let mut twin = rig.c.clone();
    // One jump of 250 ms keeps the last 100 cycles, each equal to a cycle-by-cycle run.
    rig.run_ms(250);
    for ms in 1..=250u64 {
        twin.advance_to(std::time::Duration::from_millis(ms));
        stepped.push(twin.true_state());
    }
    let trace = rig.c.take_truth_trace();
    assert_eq!(trace.len(), 100);
    assert_eq!(trace, stepped[150..]);
    assert!(rig.c.take_truth_trace().is_empty(), "taken");
    rig.c.trace_truth(None);
    rig.run_ms(10);
    assert!(rig.c.take_truth_trace().is_empty(), "stopped");
}
