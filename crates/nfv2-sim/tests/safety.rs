//! Limits, limit switches, the ENABLE E-stop loop, the power-stage supply, over-current and
//! the command watchdog, on a virtual clock.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::Rig;
use motus_nfv2_protocol::{CommandCode as C, DriveMode, DriveStatus, DrivesMisc};
use motus_nfv2_sim::{ControllerConfig, LimitSwitch};

#[test]
fn position_target_beyond_a_limit_is_clamped_with_the_status_bit() {
    let mut rig = Rig::new();
    rig.set(C::SetDrivesMinPosition, -10_000);
    rig.set(C::SetDrivesMaxPosition, 10_000);
    rig.mode(DriveMode::Position);
    rig.set(C::SetDrivesPosition, 25_000);
    rig.run_ms(2);
    assert!(rig.status().contains(DriveStatus::POSITION_LIMIT));
    rig.run_ms(800);
    assert!((rig.position() - 10_000).abs() <= 2, "stops at the limit");
    assert!(rig.status().contains(DriveStatus::POSITION_LIMIT), "bit stays while the target is outside");
    assert!(!rig.status().contains(DriveStatus::ERROR), "clamping is not an error");
    rig.set(C::SetDrivesPosition, 5_000);
    rig.run_ms(500);
    assert!((rig.position() - 5_000).abs() <= 2);
    assert!(!rig.status().contains(DriveStatus::POSITION_LIMIT));
    // min == max disables the limits (the reference firmware).
    rig.set(C::SetDrivesMaxPosition, -10_000);
    rig.set(C::SetDrivesPosition, 25_000);
    rig.run_ms(800);
    assert!((rig.position() - 25_000).abs() <= 2);
    assert!(!rig.status().contains(DriveStatus::POSITION_LIMIT));
}

#[test]
fn speed_mode_stops_at_a_position_limit() {
    let mut rig = Rig::new();
    rig.set(C::SetDrivesMinPosition, -40_000);
    rig.set(C::SetDrivesMaxPosition, 30_000);
    rig.mode(DriveMode::Speed);
    rig.set(C::SetDrivesSpeed, 10_000);
    let mut furthest = i64::MIN;
    rig.run_ms_with(1_000, |t| furthest = furthest.max(t.counter));
    assert!(furthest <= 30_000 + 200, "overshoot {}", furthest - 30_000);
    assert!((rig.position() - 30_000).abs() <= 200);
    assert!(rig.truth().speed_counts_per_s.abs() < 100.0);
    assert!(rig.status().contains(DriveStatus::POSITION_LIMIT));
    rig.set(C::SetDrivesSpeed, -2_000);
    rig.run_ms(200);
    assert!(rig.truth().speed_counts_per_s < -15_000.0, "driving back is allowed");
    assert!(!rig.status().contains(DriveStatus::POSITION_LIMIT));
}

#[test]
fn pwm_beyond_a_limit_may_only_drive_back() {
    let mut rig = Rig::new();
    rig.set(C::SetDrivesMinPosition, -1_000);
    rig.set(C::SetDrivesMaxPosition, 1_000);
    rig.c.place_axis(2_000.0).unwrap();
    rig.mode(DriveMode::Pwm);
    rig.set(C::SetDrivesPwm, 300);
    rig.run_ms(50);
    assert_eq!(rig.truth().speed_counts_per_s, 0.0);
    assert!(rig.status().contains(DriveStatus::POSITION_LIMIT));
    rig.set(C::SetDrivesPwm, -300);
    rig.run_ms(50);
    assert!(rig.truth().speed_counts_per_s < 0.0);
}

#[test]
fn speed_and_current_setpoints_are_clamped_to_their_limits() {
    let mut rig = Rig::new();
    rig.set(C::SetDrivesMaxSpeed, 3_000);
    rig.mode(DriveMode::Speed);
    rig.set(C::SetDrivesSpeed, 5_000);
    rig.run_ms(400);
    let v = rig.truth().speed_counts_per_s;
    assert!((v - 30_000.0).abs() < 1_500.0, "{v}");
    assert!(rig.status().contains(DriveStatus::SPEED_LIMIT));
    // A limit <= 0 is ignored.
    rig.set(C::SetDrivesMaxSpeed, 0);
    rig.run_ms(100);
    assert!((rig.truth().speed_counts_per_s - 30_000.0).abs() < 1_500.0);

    let mut rig = Rig::new();
    rig.set(C::SetDrivesMaxCurrent, 500);
    rig.mode(DriveMode::Current);
    rig.set(C::SetDrivesCurrent, -1_500);
    rig.run_ms(5);
    assert!((rig.truth().current_a + 0.5).abs() < 0.02, "{}", rig.truth().current_a);
    assert!(rig.status().contains(DriveStatus::CURRENT_LIMIT));
    // Above the 13 A rating the limit is 13 A.
    rig.set(C::SetDrivesMaxCurrent, 20_000);
    rig.set(C::SetDrivesCurrent, 16_000);
    rig.run_ms(2);
    let i = rig.truth().current_a;
    assert!((i - 13.0).abs() < 0.5, "{i}");
}

#[test]
fn a_limit_switch_enters_error_and_setting_a_mode_leaves_it() {
    let mut rig = Rig::new();
    rig.mode(DriveMode::Speed);
    rig.set(C::SetDrivesSpeed, 10_000);
    let mut hit = None;
    for ms in 0..2_000 {
        rig.run_ms(1);
        if rig.truth().limit_up {
            hit = Some(ms);
            break;
        }
    }
    assert!(hit.is_some(), "never reached the switch at 60 000");
    rig.run_ms(1);
    let t = rig.truth();
    assert_eq!(t.mode, DriveMode::Error);
    assert!(!t.bridge_on);
    let s = rig.status();
    assert!(s.contains(DriveStatus::ERROR | DriveStatus::LIMIT_SWITCH_UP), "{s}");
    assert_eq!(rig.read(C::ReadDigitalInputs) & 0b1001, 0b1001, "LIM_POS and ENABLE");
    rig.run_ms(500);
    assert_eq!(rig.truth().speed_counts_per_s, 0.0, "coasted to rest on the switch");
    // The way out: set a mode again. Towards the switch stays blocked...
    rig.mode(DriveMode::Speed);
    rig.set(C::SetDrivesSpeed, 1_000);
    rig.run_ms(100);
    assert_eq!(rig.truth().mode, DriveMode::Speed);
    assert!(rig.truth().speed_counts_per_s.abs() < 1.0);
    assert!(!rig.status().contains(DriveStatus::ERROR));
    // ...away from it is allowed, and the switch opens (the axis coasted about 10 000
    // counts beyond it: one second back at 10 000 counts/s).
    rig.set(C::SetDrivesSpeed, -1_000);
    rig.run_ms(100);
    assert!(rig.truth().speed_counts_per_s < -9_000.0);
    rig.run_ms(1_500);
    let t = rig.truth();
    assert!(!t.limit_up && t.speed_counts_per_s < -9_000.0);
    assert_eq!(rig.status().0 & (DriveStatus::ERROR | DriveStatus::LIMIT_SWITCH_UP), 0);
}

#[test]
fn a_forced_switch_stops_a_position_move() {
    let mut rig = Rig::new();
    rig.mode(DriveMode::Position);
    rig.set(C::SetDrivesPosition, -40_000);
    rig.run_ms(200);
    rig.c.set_limit_switch(LimitSwitch::Down, Some(true));
    rig.run_ms(1);
    assert_eq!(rig.truth().mode, DriveMode::Error);
    assert!(rig.status().contains(DriveStatus::ERROR | DriveStatus::LIMIT_SWITCH_DOWN));
    rig.c.set_limit_switch(LimitSwitch::Down, None);
    rig.run_ms(1);
    assert!(!rig.status().contains(DriveStatus::LIMIT_SWITCH_DOWN));
    assert!(rig.status().contains(DriveStatus::ERROR), "ERROR stays until a mode is set");
}

#[test]
fn removing_enable_stops_the_drive_within_one_regulator_cycle() {
    let mut rig = Rig::new();
    rig.mode(DriveMode::Speed);
    rig.set(C::SetDrivesSpeed, 8_000);
    rig.run_ms(300);
    let before = rig.truth();
    assert!(before.bridge_on && before.speed_counts_per_s > 70_000.0);
    // Half-way through a cycle: the next cycle switches the bridge off.
    rig.now += std::time::Duration::from_micros(400);
    rig.c.set_enable(false);
    rig.run_ms(1);
    let t = rig.truth();
    assert_eq!(t.time, before.time + motus_nfv2_sim::REGULATOR_PERIOD);
    assert!(!t.bridge_on, "bridge off within one cycle");
    assert_eq!(t.current_a, 0.0, "no torque within one cycle");
    assert_eq!(t.mode, DriveMode::Error);
    assert!(rig.status().contains(DriveStatus::ERROR));
    assert_eq!(rig.read(C::ReadDigitalInputs) & 0b1000, 0, "ENABLE bit clear");
    // It never drives again: the speed only decreases until the axis is at rest.
    let mut last = t.speed_counts_per_s;
    rig.run_ms_with(1_000, |t| {
        assert!(t.speed_counts_per_s <= last && t.speed_counts_per_s >= 0.0);
        assert!(!t.bridge_on);
        last = t.speed_counts_per_s;
    });
    assert_eq!(last, 0.0);
    // No mode but ERROR while the loop is open, and none restarts when it closes.
    rig.mode(DriveMode::Speed);
    rig.run_ms(10);
    assert_eq!(rig.truth().mode, DriveMode::Error);
    rig.c.set_enable(true);
    rig.run_ms(100);
    assert_eq!(rig.truth().mode, DriveMode::Error);
    assert_eq!(rig.truth().speed_counts_per_s, 0.0);
    rig.mode(DriveMode::Speed);
    rig.set(C::SetDrivesSpeed, 1_000);
    rig.run_ms(200);
    assert!(rig.truth().speed_counts_per_s > 9_000.0);
}

#[test]
fn without_power_stage_supply_everything_but_motion_works() {
    let mut rig = Rig::new();
    rig.mode(DriveMode::Position);
    rig.set(C::SetDrivesPosition, 5_000);
    rig.run_ms(500);
    rig.c.cut_power_stage();
    rig.set(C::SetDrivesPosition, 30_000);
    rig.run_ms(500);
    let s = rig.status();
    assert!(s.contains(DriveStatus::POWER_STAGE_VOLTAGE_LOW), "{s}");
    assert!(!s.contains(DriveStatus::ERROR), "not an error: only no motion");
    assert!((rig.position() - 5_000).abs() <= 3, "no motion");
    assert!(!rig.truth().bridge_on);
    let vitals = rig.read_all(C::ReadDeviceVitals);
    assert_eq!(vitals.len(), 4);
    assert!(vitals[0] < 100 && (vitals[1] - 24_000).abs() < 100, "{vitals:?}");
    assert_ne!(rig.read(C::ReadDeviceStatus) as u16 & DriveStatus::POWER_STAGE_VOLTAGE_LOW, 0);
    // Inputs and outputs still work.
    rig.set(C::SetDigitalOutputs, 0b10_0101);
    assert_eq!(rig.c.digital_outputs(), 0b10_0101);
    rig.c.place_axis(-1_234.0).unwrap_or_default();
    rig.run_ms(1);
    assert_eq!(rig.position(), -1_234);
    // Supply back: the move resumes from where the axis is.
    rig.c.restore_power_stage();
    rig.run_ms(800);
    assert!((rig.position() - 30_000).abs() <= 2);
    assert!(!rig.status().contains(DriveStatus::POWER_STAGE_VOLTAGE_LOW));
}

#[test]
fn over_current_trips_to_error_until_a_mode_is_set() {
    let config = ControllerConfig { overcurrent_trip_ma: 4_000, ..ControllerConfig::default() };
    let mut rig = Rig::with(config);
    rig.set(C::SetDrivesMaxCurrent, 13_000);
    rig.mode(DriveMode::Pwm);
    rig.set(C::SetDrivesPwm, 1_000);
    rig.run_ms(3);
    let s = rig.status();
    assert!(s.contains(DriveStatus::OVERCURRENT | DriveStatus::ERROR), "{s}");
    assert!(!rig.truth().bridge_on);
    rig.run_ms(100);
    assert!(rig.status().contains(DriveStatus::OVERCURRENT));
    rig.set(C::SetDrivesMaxCurrent, 3_000);
    rig.mode(DriveMode::Pwm);
    rig.run_ms(50);
    let s = rig.status();
    assert!(!s.contains(DriveStatus::OVERCURRENT) && !s.contains(DriveStatus::ERROR), "{s}");
    assert!(rig.truth().speed_counts_per_s > 0.0);
}

#[test]
fn the_command_watchdog_zeroes_a_forgotten_speed() {
    let mut rig = Rig::new();
    rig.mode(DriveMode::Speed);
    rig.set(C::SetDrivesSpeed, 2_000);
    rig.run_ms(1_900);
    assert!(rig.truth().speed_counts_per_s > 19_000.0);
    // Queries do not feed the watchdog.
    assert!(!rig.status().contains(DriveStatus::COMMUNICATION_FAULT));
    rig.run_ms(400);
    assert!(rig.status().contains(DriveStatus::COMMUNICATION_FAULT));
    assert!(rig.truth().speed_counts_per_s.abs() < 100.0);
    rig.set(C::SetDrivesSpeed, 2_000);
    rig.run_ms(300);
    assert!(rig.truth().speed_counts_per_s > 19_000.0);
    assert!(!rig.status().contains(DriveStatus::COMMUNICATION_FAULT));

    let mut rig = Rig::with(ControllerConfig { command_watchdog_ms: None, ..ControllerConfig::default() });
    rig.mode(DriveMode::Speed);
    rig.set(C::SetDrivesSpeed, 2_000);
    rig.run_ms(2_600); // 52 000 counts: short of the switch at 60 000
    assert!(rig.truth().speed_counts_per_s > 19_000.0);
}

#[test]
fn misc_sets_and_resets_synchronized() {
    let mut rig = Rig::new();
    rig.set(C::SetDrivesMisc, i64::from(DrivesMisc::SET_SYNCHRONIZED));
    rig.run_ms(1);
    assert!(rig.status().contains(DriveStatus::SYNCHRONIZED));
    rig.set(C::SetDrivesMisc, i64::from(DrivesMisc::RESET_SYNCHRONIZED));
    rig.run_ms(1);
    assert!(!rig.status().contains(DriveStatus::SYNCHRONIZED));
}
