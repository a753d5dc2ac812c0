//! The whole arm: six modules (0xE1..=0xE6) on one line, stepped in lock-step so joint 3's
//! gravity follows joint 2's pitch. Sans-IO: [`Arm::respond`] / [`Arm::handle`] take a
//! decoded request and the time, [`Arm::advance_to`] runs the fixed steps in between.

use std::time::Duration;

use motus_kv01_protocol::{Address, Reply, Request};

use crate::config::{ArmConfig, Side, JOINTS};
use crate::error::SimError;
use crate::module::{Module, ModuleState, TimedReply};

/// The simulated KV-01 arm.
#[derive(Debug, Clone)]
pub struct Arm {
    modules: Vec<Module>,
    time: Duration,
    step: Duration,
}

impl Arm {
    /// Powers the arm on at time 0.
    pub fn new(config: &ArmConfig) -> Result<Arm, SimError> {
        Self::power_on(config, Duration::ZERO)
    }

    /// Powers the arm on at time `now`.
    pub fn power_on(config: &ArmConfig, now: Duration) -> Result<Arm, SimError> {
        config.validate()?;
        let modules = Address::all().map(|a| Module::new(a, config, now)).collect::<Result<Vec<_>, _>>()?;
        let mut arm = Arm { modules, time: now, step: config.step() };
        arm.chain_pitch();
        Ok(arm)
    }

    /// The simulated time the arm has advanced to.
    #[must_use]
    pub fn now(&self) -> Duration {
        self.time
    }

    /// The six modules, joint 1 first.
    #[must_use]
    pub fn modules(&self) -> &[Module] {
        &self.modules
    }

    /// Module of joint `joint` (1..=6).
    pub fn module(&self, joint: u8) -> Result<&Module, SimError> {
        usize::from(joint)
            .checked_sub(1)
            .and_then(|i| self.modules.get(i))
            .ok_or(SimError::NoSuchJoint(joint))
    }

    /// Module of joint `joint` (1..=6), to change (faults, test hooks).
    pub fn module_mut(&mut self, joint: u8) -> Result<&mut Module, SimError> {
        usize::from(joint)
            .checked_sub(1)
            .and_then(|i| self.modules.get_mut(i))
            .ok_or(SimError::NoSuchJoint(joint))
    }

    /// Snapshot of joint `joint` (1..=6).
    pub fn state(&self, joint: u8) -> Result<ModuleState, SimError> {
        self.module(joint).map(Module::state)
    }

    /// The true joint angles, degrees, joint 1 first.
    #[must_use]
    pub fn joint_angles(&self) -> [f64; JOINTS] {
        let mut out = [0.0; JOINTS];
        for (o, m) in out.iter_mut().zip(&self.modules) {
            *o = m.joint_angle();
        }
        out
    }

    fn chain_pitch(&mut self) {
        let mut previous = 0.0;
        for m in &mut self.modules {
            m.set_base_pitch(previous);
            previous = m.pitch();
        }
    }

    /// Runs whole steps of every module up to `now`.
    pub fn advance_to(&mut self, now: Duration) {
        while self.time + self.step <= now {
            self.time += self.step;
            self.chain_pitch();
            for m in &mut self.modules {
                m.step();
            }
        }
    }

    /// The simulator did not run for `gap` (see `motus_serial::Responder::simulator_stalled`):
    /// every module's communication watch starts that much later, so only the host's own
    /// silence trips the 700 ms time-out.
    pub fn excuse_silence(&mut self, gap: Duration) {
        self.modules.iter_mut().for_each(|m| m.excuse_silence(gap));
    }

    /// Answers `request` at `now` (advancing first), with the time the reply is due.
    /// `None`: the module is deaf (fault injection).
    pub fn respond(&mut self, request: &Request, now: Duration) -> Option<TimedReply> {
        self.advance_to(now);
        let joint = request.address.joint_number();
        self.module_mut(joint).ok()?.respond(request, now)
    }

    /// Answers `request` at `now` (advancing first).
    pub fn handle(&mut self, request: &Request, now: Duration) -> Option<Reply> {
        self.respond(request, now).map(|r| r.reply)
    }

    /// Power off and on (the interface box's supply): every module re-armed, "TO" cleared.
    pub fn power_cycle(&mut self) {
        self.modules.iter_mut().for_each(Module::power_cycle);
    }

    /// Test hook: pushes joint `joint` just beyond its `side` limit switch; the module
    /// stops it (LSSTOP) at the next step.
    pub fn push_joint_onto_switch(&mut self, joint: u8, side: Side) -> Result<(), SimError> {
        self.module_mut(joint)?.push_onto_switch(side)
    }

    /// Fault injection: every controller answers `delay` later than normal (beyond the
    /// module's wait, D0 is answered "TIMEOUT").
    pub fn set_controller_delay(&mut self, delay: Duration) {
        for m in &mut self.modules {
            m.faults_mut().controller_delay = delay;
        }
    }
}
