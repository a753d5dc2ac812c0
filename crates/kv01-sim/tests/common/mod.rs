//! A simulated arm on a virtual clock, with helpers that send one command and unwrap the
//! reply shape the test expects.
#![allow(dead_code, clippy::panic, clippy::unwrap_used, clippy::expect_used)]

use motus_kv01_protocol::{
    Address, Command, D1Action, GripperLoad, GripperStatus, JointStatus, Reply, ReplyBody, Request,
    ResolverReading, ShortCode, Voltages,
};
use motus_kv01_sim::{Arm, ArmConfig, ModuleState};
use std::time::Duration;

pub struct Rig {
    pub arm: Arm,
    pub now: Duration,
}

impl Rig {
    pub fn new() -> Rig {
        Rig::with(ArmConfig::default())
    }

    pub fn with(config: ArmConfig) -> Rig {
        Rig { arm: Arm::new(&config).unwrap(), now: Duration::ZERO }
    }

    pub fn send(&mut self, joint: u8, command: Command) -> Option<Reply> {
        let request = Request::new(Address::joint(joint).unwrap(), command);
        let reply = self.arm.handle(&request, self.now);
        if let Some(r) = &reply {
            assert_eq!(r.address, request.address, "reply from the addressed module");
        }
        reply
    }

    pub fn body(&mut self, joint: u8, command: Command) -> ReplyBody {
        self.send(joint, command).expect("a reply").body
    }

    /// D0: the answer text.
    pub fn d0(&mut self, joint: u8, text: &str) -> String {
        match self.body(joint, Command::Faulhaber { text: text.into() }) {
            ReplyBody::Faulhaber { answer } => answer.to_string(),
            other => panic!("D0 {text:?} to joint {joint}: {other:?}"),
        }
    }

    /// D0 expecting a number.
    pub fn value(&mut self, joint: u8, text: &str) -> i64 {
        let a = self.d0(joint, text);
        a.parse().unwrap_or_else(|_| panic!("{text} -> {a:?}"))
    }

    pub fn d1(&mut self, joint: u8, action: D1Action) -> JointStatus {
        match self.body(joint, Command::BrakeLimit(action)) {
            ReplyBody::Status(s) => s,
            other => panic!("D1 {action:?} to joint {joint}: {other:?}"),
        }
    }

    pub fn d1_gripper(&mut self, action: D1Action) -> GripperStatus {
        match self.body(6, Command::BrakeLimit(action)) {
            ReplyBody::GripperStatus(s) => s,
            other => panic!("D1 {action:?} to the gripper: {other:?}"),
        }
    }

    pub fn d3(&mut self, joint: u8) -> ResolverReading {
        match self.body(joint, Command::ReadResolver) {
            ReplyBody::Resolver(r) => r,
            other => panic!("D3 to joint {joint}: {other:?}"),
        }
    }

    pub fn d4(&mut self, joint: u8) -> Voltages {
        match self.body(joint, Command::ReadVoltages) {
            ReplyBody::Voltages(v) => v,
            other => panic!("D4 to joint {joint}: {other:?}"),
        }
    }

    pub fn d5(&mut self, speed: u8, opening: bool) -> GripperLoad {
        match self.body(6, Command::Gripper { speed, opening }) {
            ReplyBody::Gripper(l) => l,
            other => panic!("D5: {other:?}"),
        }
    }

    pub fn short(&mut self, joint: u8, command: Command) -> ShortCode {
        match self.body(joint, command) {
            ReplyBody::Short { text } => text,
            other => panic!("expected a short message: {other:?}"),
        }
    }

    /// Runs `secs` with a keep-alive D3 to every module each 100 ms (as a host does).
    pub fn run(&mut self, secs: f64) {
        let end = self.now + Duration::from_millis((secs * 1000.0).round() as u64);
        while self.now < end {
            self.now = (self.now + Duration::from_millis(100)).min(end);
            for j in 1..=6 {
                self.d3(j);
            }
        }
    }

    /// Runs `ms` milliseconds without any traffic.
    pub fn run_silent(&mut self, ms: u64) {
        self.now += Duration::from_millis(ms);
        self.arm.advance_to(self.now);
    }

    pub fn state(&self, joint: u8) -> ModuleState {
        self.arm.state(joint).unwrap()
    }

    pub fn angle(&self, joint: u8) -> f64 {
        self.state(joint).angle_deg
    }

    /// EN, then brake release: the safe order.
    pub fn enable(&mut self, joint: u8) {
        assert_eq!(self.d0(joint, "EN"), "OK");
        assert!(self.d1(joint, D1Action::ReleaseBrake).brake_released);
    }
}
