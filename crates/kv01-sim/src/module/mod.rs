//! One communication module (CM) with its Faulhaber controller and joint (`specs/kv01.md`):
//! its state, the fixed simulation step, the limit-switch stop, the 700 ms safety time-out,
//! power cycling and the test hooks. What it answers to each command is in [`commands`].
//!
//! Time is injected: [`Module::advance_to`] runs whole fixed steps up to the `now` it is
//! given; [`Module::respond`] advances first, then answers, and says how long after the
//! request the reply is due ([`TimedReply::delay`]: module turnaround, plus the exchange
//! with the controller for D0).
//!
//! Choices where the source is silent:
//! - Every rising edge of a switch stops the joint (drive disabled, brake engaged,
//!   LSSTOP), in restricted mode too.
//! - The safety timer starts with the first correct message addressed to this module;
//!   messages to other modules do not count.
//! - A power cycle re-arms everything; a joint found on its switch at power-on starts in
//!   LSSTOP. The "TO" state is latched until then (the spec does not say how to leave it).

use std::time::Duration;

use motus_kv01_protocol::{Address, Reply};
use rand::rngs::SmallRng;
use rand::SeedableRng;

use crate::config::{millis, ArmConfig, CmConfig, JointConfig, Side, SupplyConfig};
use crate::controller::Controller;
use crate::error::SimError;
use crate::gripper::{Gripper, GripperState};
use crate::joint::Joint;
use crate::resolver;

mod commands;

/// A reply and when it is due, counted from the end of the request.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TimedReply {
    /// The reply.
    pub reply: Reply,
    /// Module processing (and controller exchange) time before the reply starts.
    pub delay: Duration,
}

/// Faults injected into one module.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ModuleFaults {
    /// Extra controller processing time: beyond the module's wait, D0 answers "TIMEOUT".
    pub controller_delay: Duration,
    /// The module hears nothing (disconnected): no reply, no safety-timer reset.
    pub deaf: bool,
}

/// A snapshot of a module, for tests and status displays.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModuleState {
    /// The module's address.
    pub address: Address,
    /// True joint angle, degrees (not wrapped).
    pub angle_deg: f64,
    /// Joint speed, deg/s.
    pub velocity_deg_s: f64,
    /// Motor speed, rpm.
    pub motor_rpm: f64,
    /// The controller's power stage is on.
    pub drive_enabled: bool,
    /// The brake is released (joints 1-5).
    pub brake_released: bool,
    /// The switch pressed, if any.
    pub limit_switch: Option<Side>,
    /// LSSTOP: speed commands are blocked.
    pub lsstop: bool,
    /// Restricted mode.
    pub restricted_mode: bool,
    /// The safety time-out has tripped (latched until a power cycle).
    pub timed_out: bool,
    /// The controller's limit-switch program runs.
    pub program_running: bool,
    /// The controller's answer mode (`ANSW`).
    pub answer_mode: u8,
    /// The controller's speed target, rpm.
    pub target_rpm: i32,
    /// The raw resolver reading (what D3 reports).
    pub resolver_raw: u16,
    /// The gripper's open/close drive (module 0xE6 only).
    pub gripper: Option<GripperState>,
}

/// One communication module, its controller and its joint.
#[derive(Debug, Clone)]
pub struct Module {
    address: Address,
    joint_config: JointConfig,
    cm: CmConfig,
    supply: SupplyConfig,
    step: Duration,
    controller: Controller,
    joint: Joint,
    gripper: Option<Gripper>,
    brake_released: bool,
    lsstop: bool,
    restricted: bool,
    switch_was_pressed: bool,
    /// The controller's last speed demand (`None`: power stage off), for the current.
    demand: Option<f64>,
    last_message: Option<Duration>,
    timed_out: bool,
    time: Duration,
    rng: SmallRng,
    faults: ModuleFaults,
}

impl Module {
    /// Powers the module at `address` on at time `now` with the arm's configuration
    /// (checked with [`ArmConfig::validate`]).
    pub fn new(address: Address, config: &ArmConfig, now: Duration) -> Result<Module, SimError> {
        config.validate()?;
        let n = address.joint_number();
        let joint_config = config.joints.get(usize::from(n) - 1).copied().ok_or(SimError::NoSuchJoint(n))?;
        // Positioning critically damped with the speed loop: the position loop's own pole
        // is 1 / (4 tau); the gain is in rpm per increment of error.
        let counts_per_s_per_rpm = joint_config.encoder_counts_per_rev / 60.0;
        let gain = 1000.0 / (4.0 * joint_config.speed_loop_tau_ms) / counts_per_s_per_rpm;
        let serial = config.controller.first_serial.wrapping_add(u32::from(n) - 1);
        let mut m = Module {
            address,
            joint_config,
            cm: config.cm,
            supply: config.supply,
            step: config.step(),
            controller: Controller::new(&config.controller, gain, serial),
            joint: Joint::new(joint_config),
            gripper: address.is_gripper().then(|| Gripper::new(config.gripper)),
            brake_released: false,
            lsstop: false,
            restricted: false,
            switch_was_pressed: false,
            demand: None,
            last_message: None,
            timed_out: false,
            time: now,
            rng: SmallRng::seed_from_u64(config.seed ^ u64::from(address.raw())),
            faults: ModuleFaults::default(),
        };
        m.power_cycle();
        Ok(m)
    }

    /// The module's address.
    #[must_use]
    pub fn address(&self) -> Address {
        self.address
    }

    /// The simulated time the module has advanced to.
    #[must_use]
    pub fn now(&self) -> Duration {
        self.time
    }

    /// A snapshot of everything a test may check.
    #[must_use]
    pub fn state(&self) -> ModuleState {
        ModuleState {
            address: self.address,
            angle_deg: self.joint.angle(),
            velocity_deg_s: self.joint.velocity(),
            motor_rpm: self.joint.motor_rpm(),
            drive_enabled: self.controller.enabled(),
            brake_released: self.brake_released,
            limit_switch: self.joint.switch(),
            lsstop: self.lsstop,
            restricted_mode: self.restricted,
            timed_out: self.timed_out,
            program_running: self.controller.program_running(),
            answer_mode: self.controller.answer_mode(),
            target_rpm: self.controller.target_rpm(),
            resolver_raw: self.resolver_raw(),
            gripper: self.gripper.as_ref().map(Gripper::state),
        }
    }

    /// True joint angle, degrees.
    #[must_use]
    pub fn joint_angle(&self) -> f64 {
        self.joint.angle()
    }

    /// Pitch of the link this joint moves (gravity of the next joint).
    pub(crate) fn pitch(&self) -> f64 {
        self.joint.pitch()
    }

    /// Sets the pitch of the link carrying this joint (the arm chains joints 2 and 3).
    pub(crate) fn set_base_pitch(&mut self, deg: f64) {
        self.joint.set_base_pitch(deg);
    }

    /// The injected faults, to change.
    pub fn faults_mut(&mut self) -> &mut ModuleFaults {
        &mut self.faults
    }

    /// Power off and on: controller back to its saved settings and disabled, brake
    /// engaged, restricted mode and the safety time-out cleared (the only way out of "TO"),
    /// LSSTOP set if the joint is on a switch. The joint stays where it is.
    pub fn power_cycle(&mut self) {
        self.joint.stop();
        self.demand = None;
        self.controller.power_cycle(self.joint.counts());
        self.brake_released = false;
        self.restricted = false;
        self.switch_was_pressed = self.joint.switch().is_some();
        self.lsstop = self.switch_was_pressed;
        self.last_message = None;
        self.timed_out = false;
        if let Some(g) = &mut self.gripper {
            g.power_cycle();
        }
    }

    /// Test hook: puts the joint just beyond its `side` switch (0.5° past it, at rest), as
    /// if pushed there; the module reacts at the next step.
    pub fn push_onto_switch(&mut self, side: Side) -> Result<(), SimError> {
        let joint = self.address.joint_number();
        let [lo, hi] = self.joint_config.switch_positions_deg().ok_or(SimError::NoLimitSwitch { joint })?;
        self.joint.place(match side {
            Side::Lower => lo - 0.5,
            Side::Upper => hi + 0.5,
        });
        Ok(())
    }

    /// Test hook: puts the joint at `deg`, at rest (end stops apply; a switch reached this
    /// way stops the joint at the next step).
    pub fn set_joint_angle(&mut self, deg: f64) {
        self.joint.place(deg);
    }

    /// Test hook (gripper module): an object between the jaws at `opening` (0..=1), or none.
    pub fn set_gripper_object(&mut self, opening: Option<f64>) -> Result<(), SimError> {
        let joint = self.address.joint_number();
        self.gripper.as_mut().ok_or(SimError::NoGripper { joint })?.set_object(opening);
        Ok(())
    }

    /// Runs whole steps up to `now`.
    pub fn advance_to(&mut self, now: Duration) {
        while self.time + self.step <= now {
            self.step();
        }
    }

    /// Runs exactly one step.
    pub(crate) fn step(&mut self) {
        self.time += self.step;
        self.check_safety_timeout(self.time);
        let dt = self.step.as_secs_f64();
        let limits = self.controller.current_limits();
        let drive = self.joint.drive(None, limits);
        self.demand = self.controller.demand(dt, &drive);
        self.joint.step(dt, self.demand, !self.brake_released);
        if let Some(g) = &mut self.gripper {
            g.step(dt);
        }
        let pressed = self.joint.switch();
        if pressed.is_some() && !self.switch_was_pressed {
            tracing::info!(address = %self.address, ?pressed, angle = self.joint.angle(), "limit switch: LSSTOP");
            self.controller.disable();
            self.brake_released = false;
            self.lsstop = true;
        }
        self.switch_was_pressed = pressed.is_some();
    }

    /// Moves the last message `gap` later (the simulator's own stall is not the host's
    /// silence); a latched time-out stays latched.
    pub(crate) fn excuse_silence(&mut self, gap: Duration) {
        if !self.timed_out {
            self.last_message = self.last_message.map(|t| t + gap);
        }
    }

    fn check_safety_timeout(&mut self, now: Duration) {
        let Some(last) = self.last_message else { return };
        if !self.timed_out && now.saturating_sub(last) >= millis(self.cm.safety_timeout_ms) {
            tracing::warn!(address = %self.address, "safety time-out: drive disabled, brake engaged");
            self.timed_out = true;
            self.controller.disable();
            self.brake_released = false;
            if let Some(g) = &mut self.gripper {
                g.stop();
            }
        }
    }

    fn resolver_raw(&self) -> u16 {
        let c = &self.joint_config;
        resolver::raw_from_angle(self.joint.angle(), c.resolver_offset_deg, c.resolver_bits)
    }
}
