//! Module behaviour from `specs/ps1a.md`, stepped on a virtual clock: status bits and
//! their clearing, homing, maximum position, jog limit, limit switches, following error.
#![allow(clippy::panic, clippy::unwrap_used, clippy::indexing_slicing)]

use motus_ps1a_protocol::*;
use motus_ps1a_sim::{MachineConfig, Module};
use std::time::Duration;

struct Rig {
    m: Module,
    now: Duration,
}

impl Rig {
    fn new(programmed: bool, machine: MachineConfig) -> Rig {
        let p = Parameters { address: 1, ..Parameters::default() };
        Rig {
            m: Module::power_on(p, programmed, machine, machine.initial_position, Duration::ZERO),
            now: Duration::ZERO,
        }
    }
    fn cmd(&mut self, c: Command) -> StatusReply {
        self.m.handle(&c, self.now)
    }
    fn run(&mut self, secs: f64) {
        self.now += Duration::from_secs_f64(secs);
        self.m.advance_to(self.now);
    }
    fn settle(&mut self) {
        for _ in 0..100_000 {
            if !self.m.in_motion() {
                return;
            }
            self.run(0.01);
        }
        panic!("motion did not end");
    }
    fn power(&mut self) {
        self.cmd(Command::ControlByte { control: ControlByte(ControlByte::POWER_STAGE) });
    }
}

#[test]
fn reset_flag_until_homed_and_homing_bits() {
    let mut r = Rig::new(true, MachineConfig::default());
    let s = r.cmd(Command::StatusRequest);
    assert!(s.low.has(LowStatus::AFTER_RESET));
    assert_eq!(s.position.get(), 0, "counter reads 0 after power-on");
    r.power();
    let s = r.cmd(Command::Home);
    assert!(s.low.has(LowStatus::IN_MOTION));
    r.settle();
    let s = r.cmd(Command::StatusRequest);
    assert!(!s.low.has(LowStatus::AFTER_RESET));
    assert!(s.high.has(HighStatus::REFERENCE_SWITCH | HighStatus::ENCODER_ZERO));
    // Counter is zero at the first zero pulse above the switch (machine 500): the module
    // stops a little beyond it.
    assert!(r.m.actual_position() >= 0.0 && r.m.actual_position() < 50.0, "{}", r.m.actual_position());
    // Reset: flag back, homing bits cleared.
    let s = r.cmd(Command::Reset);
    assert!(s.low.has(LowStatus::AFTER_RESET));
    assert_eq!(s.high.0, 0);
}

#[test]
fn beyond_max_position_is_refused_without_motion() {
    let mut r = Rig::new(true, MachineConfig::default());
    r.power();
    r.cmd(Command::Home);
    r.settle();
    let before = r.m.actual_position();
    let s = r.cmd(Command::MoveAbsolute { target: U24::new(70_000).unwrap() }); // max 65535
    assert!(s.low.has(LowStatus::BEYOND_MAX_POSITION));
    assert!(!s.low.has(LowStatus::IN_MOTION));
    r.run(1.0);
    assert_eq!(r.m.actual_position(), before);
    // The bit stays (not cleared by reporting) until a valid move is accepted.
    assert!(r.cmd(Command::StatusRequest).low.has(LowStatus::BEYOND_MAX_POSITION));
    let s = r.cmd(Command::MoveRelative { increment: I24::new(-1000).unwrap() });
    assert!(s.low.has(LowStatus::BEYOND_MAX_POSITION), "relative below zero refused");
    let s = r.cmd(Command::MoveAbsolute { target: U24::new(1000).unwrap() });
    assert!(!s.low.has(LowStatus::BEYOND_MAX_POSITION));
    r.settle();
    assert_eq!(r.cmd(Command::StatusRequest).position.get(), 1000);
}

#[test]
fn jog_stops_at_max_position_silently_and_stop_stops_a_jog() {
    let mut r = Rig::new(true, MachineConfig::default());
    r.power();
    r.cmd(Command::Home);
    r.settle();
    r.cmd(Command::SetSpeed { speed: 2000, acceleration: Acceleration::new(10).unwrap() });
    r.cmd(Command::JogPlus);
    r.settle();
    let s = r.cmd(Command::StatusRequest);
    assert_eq!(s.position.get(), 65535);
    assert_eq!(s.low.0 & !LowStatus::AFTER_RESET, 0, "no error bits: {:?}", s.low.names());
    r.cmd(Command::JogMinus);
    r.run(0.2);
    assert!(r.m.in_motion());
    r.cmd(Command::Stop);
    r.settle();
    let p = r.m.actual_position();
    assert!(p > 0.0 && p < 65535.0);
}

#[test]
fn clear_after_report_bits() {
    let mut r = Rig::new(true, MachineConfig::default());
    let s = r.m.checksum_error(r.now);
    assert!(s.low.has(LowStatus::CHECKSUM_ERROR));
    assert!(!r.cmd(Command::StatusRequest).low.has(LowStatus::CHECKSUM_ERROR));
    r.m.inject_encoder_error();
    assert!(r.cmd(Command::StatusRequest).low.has(LowStatus::ENCODER_ERROR));
    assert!(!r.cmd(Command::StatusRequest).low.has(LowStatus::ENCODER_ERROR));
    assert!(!r.m.power_stage(), "encoder error switches the power stage off");
}

#[test]
fn no_parameters_bit_in_factory_state() {
    let mut r = Rig::new(false, MachineConfig::default());
    r.power();
    let s = r.cmd(Command::JogPlus);
    assert!(s.low.has(LowStatus::NO_PARAMETERS));
    assert!(!r.m.in_motion());
    let s = r.cmd(Command::SetParameters { parameters: Parameters { address: 1, ..Parameters::default() } });
    assert!(!s.low.has(LowStatus::NO_PARAMETERS));
}

#[test]
fn limit_switch_switches_power_stage_off() {
    let machine = MachineConfig { limit_positive: 20_000.0, ..MachineConfig::default() };
    let mut r = Rig::new(true, machine);
    r.power();
    r.cmd(Command::SetParameters {
        parameters: Parameters {
            address: 1,
            max_position: U24::new(100_000).unwrap(),
            ..Parameters::default()
        },
    });
    r.cmd(Command::Home);
    r.settle();
    r.cmd(Command::SetSpeed { speed: 500, acceleration: Acceleration::new(5).unwrap() });
    r.cmd(Command::MoveAbsolute { target: U24::new(90_000).unwrap() });
    r.settle();
    let s = r.cmd(Command::StatusRequest);
    assert!(s.low.has(LowStatus::LIMIT_SWITCH), "{:?}", s.low.names());
    assert!(!r.m.power_stage());
    assert!(r.m.machine_position() < 20_500.0);
    assert!(!r.cmd(Command::StatusRequest).low.has(LowStatus::LIMIT_SWITCH), "cleared after report");
}

#[test]
fn following_error_without_power_stage() {
    let mut r = Rig::new(true, MachineConfig::default());
    r.power();
    r.cmd(Command::Home);
    r.settle();
    r.cmd(Command::ControlByte { control: ControlByte(0) });
    r.cmd(Command::SetSpeed { speed: 3000, acceleration: Acceleration::new(10).unwrap() });
    r.cmd(Command::MoveAbsolute { target: U24::new(60_000).unwrap() });
    r.settle();
    let s = r.cmd(Command::StatusRequest);
    assert!(s.low.has(LowStatus::FOLLOWING_ERROR), "{:?}", s.low.names());
    assert!(s.position.get() < 50, "the axis did not follow");
}
