//! A simulated controller on a virtual clock, with helpers that send one frame the way a
//! host would and unwrap the answer the test expects.
#![allow(dead_code, clippy::panic, clippy::unwrap_used, clippy::expect_used)]

use motus_nfv2_protocol::{Command, CommandCode as C, DriveMode, DriveStatus, Frame, Regulator, Revision};
use motus_nfv2_sim::{Controller, ControllerConfig, TrueState};
use std::time::Duration;

pub const ADDRESS: u8 = 1;

pub struct Rig {
    pub c: Controller,
    pub now: Duration,
}

impl Rig {
    pub fn new() -> Rig {
        Rig::with(ControllerConfig::default())
    }

    pub fn with(config: ControllerConfig) -> Rig {
        Rig { c: Controller::new(ADDRESS, &config).unwrap(), now: Duration::ZERO }
    }

    /// Sends `commands` to the controller at the current time; returns its answer.
    pub fn send(&mut self, commands: Vec<Command>) -> Option<Frame> {
        let frame = Frame { address: ADDRESS, commands };
        let answer = self.c.handle(&frame, self.now);
        if let Some(a) = &answer {
            assert_eq!(a.address, ADDRESS, "answer carries the controller's address");
        }
        answer
    }

    pub fn set(&mut self, code: C, value: i64) {
        assert_eq!(self.send(vec![Command::values(code, [value])]), None, "a set-point is not answered");
    }

    pub fn mode(&mut self, mode: DriveMode) {
        self.set(C::SetDrivesMode, i64::from(mode.to_raw(Revision::LATEST).unwrap()));
    }

    pub fn regulator(&mut self, code: C, r: Regulator) {
        assert_eq!(self.send(vec![Command::regulators(code, [r])]), None);
    }

    /// One query, one value.
    pub fn read(&mut self, code: C) -> i64 {
        self.read_all(code)[0]
    }

    pub fn read_all(&mut self, code: C) -> Vec<i64> {
        let answer = self.send(vec![Command::query(code)]).expect("an answer");
        assert_eq!(answer.commands.len(), 1);
        answer.int_values(code).expect("values").to_vec()
    }

    pub fn status(&mut self) -> DriveStatus {
        DriveStatus(u16::try_from(self.read(C::ReadDrivesStatus)).unwrap())
    }

    pub fn position(&mut self) -> i64 {
        self.read(C::ReadDrivesPosition)
    }

    /// Runs `ms` milliseconds without traffic.
    pub fn run_ms(&mut self, ms: u64) {
        self.now += Duration::from_millis(ms);
        self.c.advance_to(self.now);
    }

    /// Runs `ms` milliseconds, calling `each` after every regulator cycle.
    pub fn run_ms_with(&mut self, ms: u64, mut each: impl FnMut(&TrueState)) {
        for _ in 0..ms {
            self.run_ms(1);
            each(&self.c.true_state());
        }
    }

    pub fn truth(&self) -> TrueState {
        self.c.true_state()
    }
}

/// Speed units (1/100 count per ms) to counts/s.
pub fn units_to_counts_s(units: f64) -> f64 {
    units * motus_nfv2_sim::COUNTS_PER_S_PER_SPEED_UNIT
}
