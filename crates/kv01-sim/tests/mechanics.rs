//! Joint mechanics and measurements stepped on a virtual clock: gravity and brakes (the
//! spec's "EN before brake release"), the speed loop and gear, positioning, resolver
//! offsets (`specs/kv01.md` table), voltages (D4 constants) and the gripper (D5, current
//! limitation).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::Rig;
use motus_kv01_protocol::{Command, D1Action, ReplyBody};
use motus_kv01_sim::resolver::angle_from_raw;
use motus_kv01_sim::{ArmConfig, GripperConfig, SupplyConfig};

#[test]
fn enable_before_brake_release_holds_the_joint() {
    let mut r = Rig::new();
    assert_eq!(r.angle(2), 15.0, "default pose: joint 2 leans 15 deg");
    r.enable(2);
    r.run(2.0);
    assert!((r.angle(2) - 15.0).abs() < 1e-9, "the speed loop holds it: {}", r.angle(2));
    // The controller carries the gravity load: 200 deg/s² * sin 15° * 2 mA per deg/s².
    let current = r.value(2, "GRC");
    assert!((current.abs() - 104).abs() <= 2, "holding current {current} mA");
}

#[test]
fn brake_release_without_enable_lets_the_joint_fall_onto_its_switch() {
    let mut r = Rig::new();
    let s = r.d1(2, D1Action::ReleaseBrake);
    assert!(s.brake_released && !s.lsstop);
    r.run(0.5);
    let a = r.angle(2);
    assert!(a > 18.0, "falls under gravity: {a}");
    assert!(r.state(2).velocity_deg_s > 5.0);
    // It keeps falling until its upper switch (soft limit 90 + 5) stops it: drive off,
    // brake engaged, LSSTOP; the brake stops it before the end stop (95 + 8).
    r.run(4.0);
    let s = r.state(2);
    assert!(s.lsstop && !s.brake_released && !s.drive_enabled, "{s:?}");
    assert!(s.angle_deg >= 95.0 && s.angle_deg < 103.0, "{}", s.angle_deg);
    assert_eq!(s.velocity_deg_s, 0.0);
    let status = r.d1(2, D1Action::EngageBrake);
    assert!(status.limit_switch && status.lsstop && !status.brake_released);
}

#[test]
fn joint_3_gravity_follows_joint_2() {
    let mut r = Rig::new();
    r.arm.module_mut(2).unwrap().set_joint_angle(-45.0);
    r.arm.module_mut(3).unwrap().set_joint_angle(45.0);
    // The forearm points straight up: no gravity torque, it stays.
    r.d1(3, D1Action::ReleaseBrake);
    r.run(1.0);
    assert_eq!(r.angle(3), 45.0);
    // Tilt the upper arm: now it falls (positive pitch falls positive).
    r.arm.module_mut(2).unwrap().set_joint_angle(-30.0);
    r.run(0.5);
    assert!(r.angle(3) > 46.0, "{}", r.angle(3));
}

#[test]
fn joints_without_gravity_do_not_move_unbraked() {
    let mut r = Rig::new();
    for j in [1, 4, 5] {
        r.d1(j, D1Action::ReleaseBrake);
    }
    r.run(1.0);
    assert_eq!([r.angle(1), r.angle(4), r.angle(5)], [0.0; 3]);
}

#[test]
fn speed_command_turns_the_joint_through_the_gear() {
    let mut r = Rig::new();
    r.enable(1);
    assert_eq!(r.d0(1, "V1000"), "OK");
    r.run(1.0);
    // 1000 rpm through 400:1 = 15 deg/s; the first-order loop lags by tau (50 ms) and
    // the AC ramp (500 rev/s² = 30000 rpm/s) by about 17 ms.
    let s = r.state(1);
    assert!((s.velocity_deg_s - 15.0).abs() < 1e-3, "{}", s.velocity_deg_s);
    assert!((s.angle_deg - 15.0 * (1.0 - 0.05 - 0.017)).abs() < 0.1, "{}", s.angle_deg);
    assert_eq!(r.value(1, "GN"), 1000);
    assert_eq!(r.value(1, "GV"), 1000);
    // POS counts motor increments: angle / 360 * 400 revolutions * 2048.
    let pos = r.value(1, "POS") as f64;
    assert!((pos - r.angle(1) / 360.0 * 400.0 * 2048.0).abs() <= 1.0);
    // The resolver follows the joint.
    let reading = r.d3(1);
    assert!((angle_from_raw(reading.position, -81.85, 16) - r.angle(1)).abs() < 0.01);
    // Speed sign -1 reverses the joint.
    let mut config = ArmConfig::default();
    config.joints[0].speed_sign = -1;
    let mut r = Rig::with(config);
    r.enable(1);
    r.d0(1, "V1000");
    r.run(1.0);
    assert!(r.angle(1) < -14.0);
    // SP limits V.
    assert_eq!(r.d0(1, "V9000"), "OK");
    r.run(1.0);
    assert_eq!(r.value(1, "GV"), 5000);
}

#[test]
fn disable_with_brake_released_lets_a_moving_joint_fall() {
    let mut r = Rig::new();
    r.enable(2);
    r.run(0.5);
    assert_eq!(r.d0(2, "DI"), "OK");
    r.run(0.5);
    assert!(r.angle(2) > 17.0, "{}", r.angle(2));
}

#[test]
fn positioning_with_la_and_m_then_home() {
    let mut r = Rig::new();
    r.enable(4);
    assert_eq!(r.d0(4, "LA20000"), "OK");
    assert_eq!(r.d0(4, "M"), "OK");
    r.run(3.0);
    let pos = r.value(4, "POS");
    assert!((pos - 20000).abs() <= 20, "{pos}");
    assert_eq!(r.d0(4, "GST"), "1001110", "position mode, enabled, reached, edge, switch low");
    assert_ne!(r.value(4, "OST") & 1 << 16, 0);
    // 20000 increments / 2048 / 250 * 360 deg.
    assert!((r.angle(4) - 20000.0 / 2048.0 / 250.0 * 360.0).abs() < 0.02);
    assert_eq!(r.d0(4, "LR-5000"), "OK");
    assert_eq!(r.d0(4, "M"), "OK");
    r.run(3.0);
    assert!((r.value(4, "POS") - 15000).abs() <= 20);
    assert_eq!(r.d0(4, "HO"), "OK");
    assert!(r.value(4, "POS").abs() <= 20);
    assert!(r.value(4, "TPOS").abs() <= 20, "the target moves with the origin");
}

#[test]
fn resolver_offsets_follow_the_spec_table() {
    let mut r = Rig::new();
    let offsets = [-81.85, 190.577, 91.962, -102.549, 252.451, 310.593];
    for (j, angle) in [(1u8, 100.0), (2, -80.0), (3, 0.0), (4, 170.0), (5, -120.0), (6, -33.3)] {
        r.arm.module_mut(j).unwrap().set_joint_angle(angle);
        let reading = r.d3(j);
        let bits = if j == 6 { 12 } else { 16 };
        let back = angle_from_raw(reading.position, offsets[usize::from(j) - 1], bits);
        let count = 360.0 / f64::from(1u32 << bits);
        assert!((back - angle).abs() <= count / 2.0 + 1e-9, "joint {j}: {back} vs {angle}");
    }
    // By hand: joint 3 at 0 deg reads 91.962 / 360 * 65536 = 16741.3 -> 16741.
    assert_eq!(r.d3(3).position, 16741);
    // Joint 4 turns endlessly: 370 deg reads like 10 deg.
    r.arm.module_mut(4).unwrap().set_joint_angle(370.0);
    let a = r.d3(4).position;
    r.arm.module_mut(4).unwrap().set_joint_angle(10.0);
    assert_eq!(r.d3(4).position, a);
    // The gripper's 12-bit value stays below 4096.
    assert!(r.d3(6).position < 4096);
}

#[test]
fn voltages_decode_to_the_configured_values() {
    let exact = SupplyConfig { volts_24v: 26.0, volts_5v: 4.8, volts_12v: 11.5, noise_volts: 0.0 };
    let mut r = Rig::with(ArmConfig { supply: exact, ..ArmConfig::default() });
    for j in 1..=6 {
        let v = r.d4(j);
        assert!((v.volts_24v() - 26.0).abs() < 0.01, "{}", v.volts_24v());
        assert!((v.volts_5v() - 4.8).abs() < 0.01, "{}", v.volts_5v());
        assert!((v.volts_12v() - 11.5).abs() < 0.01, "{}", v.volts_12v());
    }
    // With the default noise (±0.03 V) single readings vary, the mean stays within 0.01 V.
    let mut r = Rig::new();
    let readings: Vec<_> = (0..400).map(|_| r.d4(3)).collect();
    assert!(readings.iter().any(|v| v.raw_24v != readings[0].raw_24v), "noisy");
    let mean = |f: fn(&motus_kv01_protocol::Voltages) -> f64| readings.iter().map(f).sum::<f64>() / 400.0;
    assert!((mean(|v| v.volts_24v()) - 24.0).abs() < 0.01);
    assert!((mean(|v| v.volts_5v()) - 5.0).abs() < 0.01);
    assert!((mean(|v| v.volts_12v()) - 12.0).abs() < 0.01);
    // Seeded: the same seed gives the same readings.
    let mut again = Rig::new();
    let replay: Vec<_> = (0..400).map(|_| again.d4(3)).collect();
    assert_eq!(readings, replay);
}

#[test]
fn gripper_current_limit_trips_after_two_seconds_and_rearms_with_speed_0() {
    let mut r = Rig::new();
    let s = r.d1_gripper(D1Action::EnableCurrentLimit);
    assert!(s.current_limit && !s.brake_released);
    // Closing at full speed from half open: closed after 1 s (full stroke 2 s), then
    // stalled (load 31 > 16) for ~2 s.
    let l = r.d5(31, false);
    assert!(l.brake_released && !l.opening);
    r.run(0.5);
    assert_eq!(r.d5(31, false).load, 9, "moving freely: 2 + 31 / 4");
    r.run(2.4);
    let l = r.d5(31, false);
    assert_eq!((l.load, l.brake_released), (31, true), "stalled, not yet tripped");
    r.run(0.2);
    let g = r.state(6).gripper.unwrap();
    assert!(g.tripped && g.opening == 0.0, "{g:?}");
    let l = r.d5(31, true);
    assert_eq!((l.load, l.brake_released), (0, false), "a speed other than 0 does not re-arm");
    r.run(0.5);
    assert_eq!(r.state(6).gripper.unwrap().opening, 0.0);
    r.d5(0, false);
    let l = r.d5(10, true);
    assert!(l.brake_released && l.opening, "re-armed");
    r.run(0.5);
    assert!(r.state(6).gripper.unwrap().opening > 0.05);
    let s = r.d1_gripper(D1Action::DisableCurrentLimit);
    assert_eq!((s.current_limit, s.opening, s.brake_released), (false, true, true));
}

#[test]
fn gripper_on_an_object_without_current_limit_keeps_squeezing() {
    let gripper = GripperConfig { object_opening: Some(0.3), ..GripperConfig::default() };
    let mut r = Rig::with(ArmConfig { gripper, ..ArmConfig::default() });
    r.d1_gripper(D1Action::DisableCurrentLimit);
    r.d5(20, false);
    r.run(5.0);
    let g = r.state(6).gripper.unwrap();
    assert_eq!((g.opening, g.load, g.tripped), (0.3, 31, false));
    // Limitation on: trips after ~2 s more.
    r.d1_gripper(D1Action::EnableCurrentLimit);
    r.run(1.9);
    assert!(!r.state(6).gripper.unwrap().tripped);
    r.run(0.2);
    assert!(r.state(6).gripper.unwrap().tripped);
    // The gripper module's D3 status: BRAKE (software brake) off once tripped.
    assert!(!r.d3(6).status.brake_released);
    // The rotation drive is an ordinary Faulhaber joint.
    assert_eq!(r.d0(6, "EN"), "OK");
    assert!(matches!(r.body(6, Command::Fast { text: "V600".into() }), ReplyBody::FastResolver(_)));
    r.run(1.0);
    assert!(r.angle(6) > 20.0, "600 rpm / 150 * 6 = 24 deg/s: {}", r.angle(6));
}
