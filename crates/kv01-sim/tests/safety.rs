//! The module's protective behaviour stepped on a virtual clock (`specs/kv01.md`): the
//! limit-switch stop (LSSTOP), driving out in restricted mode (±399 rpm, LIMVAL) with the
//! controller's program off (DIPROG/ENPROG), the 700 ms safety time-out ("TO", latched
//! until a power cycle), "TIMEOUT" from a slow controller, and "UC".
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::Rig;
use motus_kv01_protocol::{code, Answer, Command, D1Action, ReplyBody, ShortCode};
use motus_kv01_sim::{ArmConfig, CmConfig, D2Refusal, Side};
use std::time::Duration;

#[test]
fn limit_switch_stops_the_joint_and_blocks_speed_commands() {
    let mut r = Rig::new();
    r.enable(5);
    r.arm.module_mut(5).unwrap().set_joint_angle(130.0);
    assert_eq!(r.d0(5, "V3000"), "OK");
    // 3000 rpm / 250 * 6 = 72 deg/s: the switch at 135 + 5 is reached in ~0.2 s; the
    // brake (1500 deg/s²) stops the joint within ~1.7 deg, before the end stop at 148.
    r.run(1.0);
    let s = r.state(5);
    assert!(s.lsstop && !s.drive_enabled && !s.brake_released, "{s:?}");
    assert_eq!(s.limit_switch, Some(Side::Upper));
    assert!(s.angle_deg > 140.0 && s.angle_deg < 143.0, "{}", s.angle_deg);
    assert_eq!(s.velocity_deg_s, 0.0);
    // Speed commands are blocked, others pass.
    assert_eq!(r.d0(5, "V-100"), "LSSTOP");
    assert_eq!(r.d0(5, "v 0"), "LSSTOP");
    assert_eq!(r.d0(5, "EN"), "OK");
    assert!(r.value(5, "POS") > 0);
    assert_eq!(r.state(5).target_rpm, 0);
    // D2 refusal: a D0 "LSSTOP" reply by default...
    let body = r.body(5, Command::Fast { text: "V-100".into() });
    assert_eq!(body, ReplyBody::Faulhaber { answer: Answer::LsStop });
    // ... and D2 without a speed command still reads the resolver, with the bits.
    let body = r.body(5, Command::Fast { text: "GN".into() });
    let ReplyBody::FastResolver(reading) = body else { panic!("{body:?}") };
    assert!(reading.status.lsstop && reading.status.limit_switch);
    assert_eq!(body.code(), Some(code::D2), "the reply echoes D2");
}

#[test]
fn d2_refusal_can_be_the_resolver_reply() {
    let cm = CmConfig { d2_refusal: D2Refusal::Resolver, ..CmConfig::default() };
    let mut r = Rig::with(ArmConfig { cm, ..ArmConfig::default() });
    r.arm.push_joint_onto_switch(1, Side::Lower).unwrap();
    r.run(0.1);
    let body = r.body(1, Command::Fast { text: "V100".into() });
    let ReplyBody::FastResolver(reading) = body else { panic!("{body:?}") };
    assert!(reading.status.lsstop);
    assert_eq!(r.state(1).target_rpm, 0, "not forwarded");
}

#[test]
fn drive_out_in_restricted_mode_with_the_program_off() {
    let mut r = Rig::new();
    r.arm.push_joint_onto_switch(1, Side::Upper).unwrap();
    r.run(0.1);
    let s = r.d1(1, D1Action::EngageBrake);
    assert!(s.limit_switch && s.lsstop && !s.restricted_mode && !s.brake_released);
    // 0xA0 is refused while the switch is pressed; 0xA1 enters restricted mode.
    assert!(r.d1(1, D1Action::LeaveRestrictedMode).lsstop);
    let s = r.d1(1, D1Action::EnterRestrictedMode);
    assert!(s.restricted_mode && s.lsstop);
    assert!(r.d1(1, D1Action::LeaveRestrictedMode).restricted_mode, "still pressed");
    r.enable(1);
    assert_eq!(r.d0(1, "V-400"), "LIMVAL");
    assert_eq!(r.d0(1, "V500"), "LIMVAL");
    assert!(matches!(
        r.body(1, Command::Fast { text: "V1000".into() }),
        ReplyBody::Faulhaber { answer: Answer::LimVal }
    ));
    // The controller's own program zeroes the speed while the switch is pressed.
    assert_eq!(r.d0(1, "V-399"), "OK");
    let before = r.angle(1);
    r.run(0.5);
    assert!((r.angle(1) - before).abs() < 0.05, "program holds it: {}", r.angle(1));
    assert_eq!(r.value(1, "GV"), 0);
    assert_eq!(r.value(1, "OST") & 2, 2, "program running");
    // DIPROG, then -399 rpm = -5.985 deg/s drives out of the switch (125 deg).
    assert_eq!(r.d0(1, "DIPROG"), "OK");
    assert!(!r.state(1).program_running);
    assert!(matches!(r.body(1, Command::Fast { text: "V-399".into() }), ReplyBody::FastResolver(_)));
    r.run(0.05);
    assert!(r.d3(1).status.limit_switch, "not out yet");
    r.run(0.95);
    let s = r.state(1);
    assert_eq!(s.limit_switch, None, "out at {}", s.angle_deg);
    assert!(s.angle_deg < 125.0 && s.angle_deg > 118.0);
    assert_eq!(r.d0(1, "V0"), "OK");
    assert_eq!(r.d0(1, "ENPROG"), "OK");
    let s = r.d1(1, D1Action::LeaveRestrictedMode);
    assert!(!s.restricted_mode && !s.lsstop && !s.limit_switch && s.brake_released);
    assert_eq!(r.d0(1, "V1000"), "OK", "normal speeds again");
}

#[test]
fn restricted_mode_without_a_switch_limits_speed_too() {
    let mut r = Rig::new();
    r.d1(4, D1Action::EnterRestrictedMode);
    r.enable(4);
    assert_eq!(r.d0(4, "V399"), "OK");
    assert_eq!(r.d0(4, "V-399"), "OK");
    assert_eq!(r.d0(4, "V400"), "LIMVAL");
    let s = r.d1(4, D1Action::LeaveRestrictedMode);
    assert!(!s.restricted_mode);
    assert_eq!(r.d0(4, "V400"), "OK");
    assert!(matches!(
        r.arm.push_joint_onto_switch(4, Side::Upper),
        Err(motus_kv01_sim::SimError::NoLimitSwitch { joint: 4 })
    ));
}

#[test]
fn safety_timeout_trips_after_700_ms_of_silence_and_not_before() {
    let mut r = Rig::new();
    // Not armed before the first correct message.
    r.run_silent(5000);
    assert!(!r.state(2).timed_out);
    r.enable(2);
    // Messages 699 ms apart keep it alive.
    for _ in 0..10 {
        r.run_silent(699);
        r.d3(2);
    }
    assert!(!r.state(2).timed_out);
    assert!((r.angle(2) - 15.0).abs() < 1e-9);
    // 700 ms of silence: drive off, brake on, latched.
    r.run_silent(700);
    let s = r.state(2);
    assert!(s.timed_out && !s.drive_enabled && !s.brake_released, "{s:?}");
    for command in [Command::ReadResolver, Command::ReadVoltages, Command::Faulhaber { text: "EN".into() }] {
        assert_eq!(r.short(2, command), ShortCode::Timeout);
    }
    r.run_silent(100);
    assert_eq!(r.short(2, Command::BrakeLimit(D1Action::ReleaseBrake)), ShortCode::Timeout);
    assert!(!r.state(2).brake_released, "nothing executed");
    // The joint was held by the brake: it did not fall.
    r.run_silent(2000);
    assert!((r.angle(2) - 15.0).abs() < 1e-9);
    // The other modules are not affected (joint 3 was never addressed: not armed).
    r.d3(3);
    // Only a power cycle clears it.
    r.arm.power_cycle();
    assert!(!r.state(2).timed_out);
    assert_eq!(r.d0(2, "GST"), "0000010", "disabled, velocity mode");
}

#[test]
fn safety_timeout_trips_exactly_at_700_ms_when_the_next_message_comes() {
    let mut r = Rig::new();
    r.d3(1);
    r.now += Duration::from_micros(699_999);
    r.d3(1);
    r.now += Duration::from_millis(700);
    assert_eq!(r.short(1, Command::ReadResolver), ShortCode::Timeout);
}

#[test]
fn safety_timeout_stops_the_gripper() {
    let mut r = Rig::new();
    r.d5(10, true);
    r.run_silent(800);
    let g = r.state(6).gripper.unwrap();
    assert_eq!((g.speed, g.driven), (0, false));
}

/// `d` is `ms` milliseconds within a microsecond.
fn close(d: Duration, ms: f64) {
    assert!((d.as_secs_f64() * 1000.0 - ms).abs() < 1e-3, "{d:?} vs {ms} ms");
}

#[test]
fn slow_controller_gives_timeout() {
    let mut r = Rig::new();
    let request = |text: &str| {
        motus_kv01_protocol::Request::new(
            motus_kv01_protocol::Address::joint(3).unwrap(),
            Command::Faulhaber { text: text.into() },
        )
    };
    // Normal: turnaround + "EN\r" (3 chars at 9600 Bd = 3.125 ms) + 1 ms latency +
    // "OK\r\n" (4.167 ms).
    let t = r.arm.respond(&request("EN"), r.now).unwrap();
    let turnaround = motus_kv01_sim::ArmConfig::default().cm.turnaround_ms;
    close(t.delay, turnaround + 3.125 + 1.0 + 4.1667);
    r.arm.module_mut(3).unwrap().faults_mut().controller_delay = Duration::from_millis(80);
    let t = r.arm.respond(&request("DI"), r.now).unwrap();
    assert_eq!(t.reply.body, ReplyBody::Faulhaber { answer: Answer::Timeout });
    // The module waited its 50 ms after forwarding.
    close(t.delay, turnaround + 3.125 + 50.0);
    assert!(!r.state(3).drive_enabled, "the command still reached the controller");
    // D2 does not wait: the resolver reply comes at once.
    let t = r.arm.respond(
        &motus_kv01_protocol::Request::new(
            motus_kv01_protocol::Address::joint(3).unwrap(),
            Command::Fast { text: "V100".into() },
        ),
        r.now,
    );
    close(t.unwrap().delay, turnaround);
    // Line-wide: every module slow.
    r.arm.set_controller_delay(Duration::from_millis(49));
    assert_eq!(r.d0(1, "POS"), "TIMEOUT", "49 ms + answer wire time > 50 ms");
    r.arm.set_controller_delay(Duration::ZERO);
    assert_eq!(r.d0(1, "POS"), "0");
}

#[test]
fn silent_controller_gives_timeout() {
    let mut r = Rig::new();
    // Answer mode 0: no confirmation, so the module times out; queries still answer.
    assert_eq!(r.d0(2, "ANSW0"), "TIMEOUT");
    assert_eq!(r.d0(2, "EN"), "TIMEOUT");
    assert!(r.state(2).drive_enabled);
    assert_eq!(r.d0(2, "GN"), "0");
    assert_eq!(r.d0(2, "ANSW2"), "OK");
    // Another node's prefix: silent.
    assert_eq!(r.d0(2, "5EN"), "TIMEOUT");
    assert_eq!(r.d0(2, "0EN"), "OK");
    // BAUD: answered at the old rate, then the module cannot reach it until a power cycle.
    assert_eq!(r.d0(2, "BAUD19200"), "OK");
    assert_eq!(r.d0(2, "POS"), "TIMEOUT");
    r.arm.power_cycle();
    assert_eq!(r.d0(2, "POS"), "0");
}

#[test]
fn unknown_commands_and_bad_arguments() {
    let mut r = Rig::new();
    assert_eq!(r.d0(1, "FOO"), "Unknown command");
    assert_eq!(r.d0(1, "V"), "Invalid parameter");
    assert_eq!(r.d0(1, "EN5"), "Invalid parameter");
    assert_eq!(r.d0(1, "V99999999999"), "Invalid parameter");
    assert_eq!(r.d0(1, "ANSW3"), "Invalid parameter");
    assert_eq!(r.d0(1, "GADV9"), "Invalid parameter");
    assert_eq!(r.d0(1, "VER"), "MCDC3006S V3.05 (motus kv01-sim)");
    assert_eq!(r.d0(2, "GSER"), "1004202");
    assert_eq!(r.d0(1, "SAVE"), "EEPROM writing done");
    let uc = ShortCode::UnknownCommand;
    assert_eq!(r.short(1, Command::Faulhaber { text: String::new() }), uc);
    assert_eq!(r.short(1, Command::Fast { text: String::new() }), uc);
    assert_eq!(r.short(1, Command::BrakeLimit(D1Action::EnableCurrentLimit)), uc);
    assert_eq!(r.short(1, Command::BrakeLimit(D1Action::Unknown { byte: 0x55 })), uc);
    assert_eq!(r.short(1, Command::Gripper { speed: 3, opening: true }), uc);
    assert_eq!(r.short(6, Command::BrakeLimit(D1Action::ReleaseBrake)), uc);
    assert_eq!(r.short(3, Command::Other { code: 0xD7, data: vec![] }), uc);
    assert_eq!(r.short(3, Command::Other { code: code::D3, data: vec![1] }), uc);
}

#[test]
fn a_deaf_module_neither_answers_nor_resets_its_timer() {
    let mut r = Rig::new();
    r.d3(4);
    r.arm.module_mut(4).unwrap().faults_mut().deaf = true;
    r.run_silent(500);
    assert!(r.send(4, Command::ReadResolver).is_none());
    r.run_silent(300);
    r.arm.module_mut(4).unwrap().faults_mut().deaf = false;
    assert_eq!(r.short(4, Command::ReadResolver), ShortCode::Timeout);
}

#[test]
fn power_on_on_a_switch_starts_in_lsstop() {
    let mut r = Rig::new();
    r.arm.push_joint_onto_switch(3, Side::Lower).unwrap();
    r.arm.power_cycle();
    let s = r.d1(3, D1Action::EngageBrake);
    assert!(s.lsstop && s.limit_switch);
    assert_eq!(r.d0(3, "V10"), "LSSTOP");
}

#[test]
fn the_simulators_own_stall_is_not_the_hosts_silence() {
    // The serve loop did not run for 600 ms (a loaded host): the host's messages waited in
    // the line. The watch starts again after the stall, so 400 ms more of real silence is
    // fine, and 700 ms of it still trips.
    let mut r = Rig::new();
    r.d3(2);
    r.arm.excuse_silence(Duration::from_millis(600));
    r.run_silent(1000);
    assert!(!r.state(2).timed_out, "1000 ms, of which 600 ms the simulator's own stall");
    r.run_silent(300);
    assert!(r.state(2).timed_out, "700 ms of silence after the stall");
    // A latched module is not un-latched by a later stall.
    r.arm.excuse_silence(Duration::from_secs(10));
    assert!(r.state(2).timed_out);
}
