//! The whole arm: six joints kept alive and moved by one control thread, with the safe
//! order of the spec enforced (speed loop enabled before a brake is released; brake
//! engaged before the drive is disabled).

use crate::bus::{Kv01Bus, Kv01Error};
use crate::controller::{self, JointRuntime, Shared};
use crate::joints::JointSpec;
use motus_axis::profile::synchronised;
use motus_clock::SharedClock;
use motus_kv01_protocol::faulhaber;
use motus_kv01_protocol::{Address, Answer, Command, D1Action, JointStatus, ReplyBody, Voltages};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Settings of the arm controller.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmConfig {
    /// Joints 1..=6.
    pub joints: [JointSpec; 6],
    /// Control cycle: every joint gets one message per cycle (keep-alive well inside 700 ms).
    pub cycle: Duration,
    /// Default joint velocity of moves (deg/s).
    pub velocity_deg_s: f64,
    /// Default joint acceleration of moves (deg/s^2).
    pub acceleration_deg_s2: f64,
    /// Position-loop gain (1/s).
    pub kp: f64,
    /// A move is done when the joint is within this many degrees of its target.
    pub tolerance_deg: f64,
    /// A move that does not settle within this time after its profile ends is a fault.
    pub settle_timeout: Duration,
}

impl Default for ArmConfig {
    fn default() -> Self {
        ArmConfig {
            joints: [1, 2, 3, 4, 5, 6].map(JointSpec::kv01),
            cycle: Duration::from_millis(20),
            velocity_deg_s: 20.0,
            acceleration_deg_s2: 40.0,
            kp: 4.0,
            tolerance_deg: 0.05,
            settle_timeout: Duration::from_secs(3),
        }
    }
}

/// A refused or failed arm operation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ArmError {
    /// Communication or module refusal.
    #[error(transparent)]
    Bus(#[from] Kv01Error),
    /// The joint number is not 1..=6.
    #[error("there is no joint {0}: joints are 1..=6")]
    NoJoint(u8),
    /// The safe order of the spec would be broken.
    #[error("joint {joint}: {reason}")]
    Unsafe {
        /// Joint.
        joint: u8,
        /// Why it is refused.
        reason: String,
    },
    /// A target outside the soft limits.
    #[error("joint {joint}: target {target_deg:.3} deg is outside the soft limits {lower} .. {upper} deg")]
    BeyondSoftLimit {
        /// Joint.
        joint: u8,
        /// Requested target.
        target_deg: f64,
        /// Lower soft limit.
        lower: f64,
        /// Upper soft limit.
        upper: f64,
    },
    /// The joint reports a fault.
    #[error("joint {joint}: {reason}")]
    Fault {
        /// Joint.
        joint: u8,
        /// The fault.
        reason: String,
    },
    /// The controller answered something unexpected.
    #[error("joint {joint}: unexpected answer to {what}: {answer}")]
    Unexpected {
        /// Joint.
        joint: u8,
        /// The request.
        what: String,
        /// The answer.
        answer: String,
    },
    /// Waiting took too long.
    #[error("joints {joints:?} did not finish within {timeout:?}")]
    WaitTimeout {
        /// Joints waited for.
        joints: Vec<u8>,
        /// Time waited.
        timeout: Duration,
    },
}

/// A snapshot of one joint.
#[derive(Debug, Clone, PartialEq)]
pub struct JointState {
    /// Joint number 1..=6.
    pub joint: u8,
    /// Angle in degrees with the offset applied, normalised to (-180, 180].
    pub angle_deg: f64,
    /// Raw resolver value.
    pub raw: u16,
    /// Status bits of the last resolver reply.
    pub status: JointStatus,
    /// The drive was enabled by this host ("EN" acknowledged).
    pub enabled: bool,
    /// A move runs.
    pub moving: bool,
    /// A latched fault (safety time-out, limit switch, failed move...).
    pub fault: Option<String>,
    /// Age of the reading.
    pub age: Duration,
    /// Longest gap between two correct replies from this module so far.
    pub longest_gap: Duration,
}

/// A communication module that latched its 700 ms safety time-out (see
/// [`Kv01Arm::latched_timeouts`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LatchedTimeout {
    /// Joint number 1..=6 (module `0xE0 + joint`).
    pub joint: u8,
    /// The module's address.
    pub address: u8,
    /// When this host first saw the module answer "TO".
    pub since: Instant,
    /// When the module last answered "TO" (it is on the line, and still latched).
    pub last_answer: Instant,
    /// A normal reply came after the last "TO": the module was power-cycled, and this
    /// driver (which keeps the joint disabled) must be started again to use it.
    pub answers_normally_again: bool,
}

/// The KV-01 arm.
///
/// Every wait and every time it keeps (the control cycle, motion profiles, the ages of
/// readings, the latched safety time-outs, recovery's progress watch) runs on its
/// [`Clock`](motus_clock::Clock): the system clock ([`Kv01Arm::start`]), or one given to
/// [`Kv01Arm::start_with_clock`] (a threaded virtual clock in tests, with the bus master
/// and the simulated arm on the same clock).
pub struct Kv01Arm {
    bus: Kv01Bus,
    clock: SharedClock,
    shared: Arc<Shared>,
    stop: Arc<AtomicBool>,
    thread: Mutex<Option<JoinHandle<()>>>,
}

pub(crate) fn address(joint: u8) -> Result<Address, ArmError> {
    Address::joint(joint).ok_or(ArmError::NoJoint(joint))
}

impl Kv01Arm {
    /// Starts the controller on `bus`: it reads every joint at once and then keeps all six
    /// modules alive every `config.cycle`. Runs on the bus master's clock
    /// ([`motus_serial::BusMaster::clock`]: the system clock unless the master was made
    /// with [`motus_serial::BusMaster::with_clock`]).
    pub fn start(bus: Kv01Bus, config: ArmConfig) -> std::io::Result<Kv01Arm> {
        let clock = Arc::clone(bus.master().clock());
        Self::start_with_clock(bus, config, clock)
    }

    /// [`Kv01Arm::start`] on `clock` (e.g. [`motus_clock::SystemClock::shared`], or a
    /// [`motus_clock::VirtualClock::threaded`] shared with the bus master and an in-process
    /// simulator): the control thread (started with [`motus_clock::spawn`]) cycles on it
    /// and every wait of the arm sleeps on it. Give the bus master the same clock.
    pub fn start_with_clock(bus: Kv01Bus, config: ArmConfig, clock: SharedClock) -> std::io::Result<Kv01Arm> {
        let shared = Arc::new(Shared::new(config));
        let stop = Arc::new(AtomicBool::new(false));
        let (b, s, f, c) = (bus.clone(), shared.clone(), stop.clone(), clock.clone());
        let builder = std::thread::Builder::new().name("kv01-arm".into());
        let thread = motus_clock::spawn(&clock, builder, move || {
            // The keep-alive and position loop: each module trips after 700 ms without it.
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Cyclic);
            controller::run(&b, &s, &f, &*c)
        })?;
        let arm = Kv01Arm { bus, clock, shared, stop, thread: Mutex::new(Some(thread)) };
        arm.wait_first_readings(Duration::from_secs(2));
        Ok(arm)
    }

    /// The clock the arm runs on.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }

    fn wait_first_readings(&self, timeout: Duration) {
        let t0 = self.clock.now();
        while self.clock.elapsed(t0) < timeout {
            if self
                .lock()
                .joints
                .iter()
                .all(|j| j.reading.is_some() || j.fault.is_some() || j.timeout_latched.is_some())
            {
                return;
            }
            self.clock.sleep(Duration::from_millis(5));
        }
    }

    /// The bus.
    pub fn bus(&self) -> &Kv01Bus {
        &self.bus
    }

    /// The configuration.
    pub fn config(&self) -> ArmConfig {
        self.lock().config.clone()
    }

    pub(crate) fn lock(&self) -> MutexGuard<'_, controller::State> {
        self.shared.lock()
    }

    fn runtime<T>(&self, joint: u8, f: impl FnOnce(&mut JointRuntime) -> T) -> Result<T, ArmError> {
        let i = usize::from(joint).checked_sub(1).filter(|i| *i < 6).ok_or(ArmError::NoJoint(joint))?;
        let mut st = self.lock();
        st.joints.get_mut(i).map(f).ok_or(ArmError::NoJoint(joint))
    }

    /// The latest state of joint `joint` (read by the controller within one cycle).
    pub fn joint(&self, joint: u8) -> Result<JointState, ArmError> {
        let now = self.clock.now();
        self.runtime(joint, |r| r.snapshot(joint, now))
    }

    /// The communication modules that latched their 700 ms safety time-out (they answer
    /// "TO" to everything until power-cycled), by joint.
    pub fn latched_timeouts(&self) -> Vec<LatchedTimeout> {
        let st = self.lock();
        st.joints
            .iter()
            .zip(1u8..)
            .filter_map(|(r, joint)| {
                let (since, last_answer) = (r.latched_at?, r.last_latched_answer?);
                Some(LatchedTimeout {
                    joint,
                    address: address(joint).map_or(0, |a| a.raw()),
                    since,
                    last_answer,
                    answers_normally_again: r.reading.is_some_and(|x| x.at > last_answer),
                })
            })
            .collect()
    }

    /// All six joints, from the same controller cycle or fresher.
    pub fn joints(&self) -> Vec<JointState> {
        let now = self.clock.now();
        let st = self.lock();
        st.joints.iter().zip(1u8..).map(|(r, j)| r.snapshot(j, now)).collect()
    }

    /// Sends a Faulhaber command through D0 and returns the answer (e.g. "OK", a number,
    /// "LSSTOP", "LIMVAL", "TIMEOUT").
    pub fn faulhaber(&self, joint: u8, text: &str) -> Result<Answer, ArmError> {
        let req = faulhaber::Request::parse(text).map_err(|e| ArmError::Unexpected {
            joint,
            what: text.to_string(),
            answer: format!("not a Faulhaber command: {e}"),
        })?;
        match self
            .bus
            .transact(address(joint)?, Command::d0(&req))
            .map_err(|e| self.note_bus_error(joint, e))?
        {
            ReplyBody::Faulhaber { answer } => Ok(answer),
            other => Err(ArmError::Unexpected { joint, what: text.into(), answer: format!("{other:?}") }),
        }
    }

    fn note_bus_error(&self, joint: u8, e: Kv01Error) -> ArmError {
        if let Kv01Error::SafetyTimeout { .. } = e {
            let now = self.clock.now();
            let _ = self.runtime(joint, |r| r.latch_timeout(&e, now));
        }
        ArmError::Bus(e)
    }

    fn expect_ok(&self, joint: u8, text: &str) -> Result<(), ArmError> {
        match self.faulhaber(joint, text)? {
            Answer::Controller(faulhaber::Reply::Ok) => Ok(()),
            Answer::LsStop => Err(ArmError::Fault {
                joint,
                reason: format!(
                    "{text} blocked with LSSTOP: the joint is on its limit switch; run recover-limit"
                ),
            }),
            Answer::LimVal => Err(ArmError::Unsafe {
                joint,
                reason: format!("{text} refused with LIMVAL: restricted mode allows only -399..399 rpm"),
            }),
            other => Err(ArmError::Unexpected { joint, what: text.into(), answer: other.to_string() }),
        }
    }

    fn d1(&self, joint: u8, action: D1Action) -> Result<ReplyBody, ArmError> {
        let body = self
            .bus
            .transact(address(joint)?, Command::BrakeLimit(action))
            .map_err(|e| self.note_bus_error(joint, e))?;
        if let ReplyBody::Status(status) = &body {
            // The reply carries the new status bits: use them now, not one cycle later.
            let status = *status;
            let now = self.clock.now();
            self.runtime(joint, |r| {
                if let Some(reading) = &mut r.reading {
                    reading.status = status;
                }
                r.status_set_at = Some(now);
            })?;
        }
        Ok(body)
    }

    /// Enables the drive's speed loop ("EN"). The brake stays as it is.
    pub fn enable(&self, joint: u8) -> Result<(), ArmError> {
        self.check_no_timeout(joint)?;
        self.expect_ok(joint, "EN")?;
        self.runtime(joint, |r| r.enabled = true)
    }

    /// Releases the brake; refused unless this host enabled the drive first (otherwise
    /// gravity moves the arm).
    pub fn release_brake(&self, joint: u8) -> Result<(), ArmError> {
        self.d1_action(joint, D1Action::ReleaseBrake).map(|_| ())
    }

    /// Engages the brake (stopping any motion of the joint first).
    pub fn engage_brake(&self, joint: u8) -> Result<(), ArmError> {
        self.stop(joint)?;
        self.d1(joint, D1Action::EngageBrake)?;
        Ok(())
    }

    /// Stops the joint, engages its brake, then disables the drive ("DI").
    pub fn disable(&self, joint: u8) -> Result<(), ArmError> {
        if self.config().joints.get(usize::from(joint) - 1).is_some_and(|s| s.brake) {
            self.engage_brake(joint)?;
        } else {
            self.stop(joint)?;
        }
        self.expect_ok(joint, "DI")?;
        self.runtime(joint, |r| r.enabled = false)
    }

    /// Enables the joint and releases its brake, in the safe order.
    pub fn power_up(&self, joint: u8) -> Result<(), ArmError> {
        self.enable(joint)?;
        if self.config().joints.get(usize::from(joint) - 1).is_some_and(|s| s.brake) {
            self.release_brake(joint)?;
        }
        Ok(())
    }

    /// Stops the joint's motion now (speed 0).
    pub fn stop(&self, joint: u8) -> Result<(), ArmError> {
        self.runtime(joint, |r| {
            r.motion = None;
            r.override_rpm = None;
        })?;
        match self.faulhaber(joint, "V0") {
            Ok(_) => Ok(()),
            Err(ArmError::Bus(Kv01Error::SafetyTimeout { .. })) => Ok(()),
            Err(e) => Err(e),
        }
    }

    fn check_no_timeout(&self, joint: u8) -> Result<(), ArmError> {
        match self.runtime(joint, |r| r.timeout_latched.clone())? {
            Some(reason) => Err(ArmError::Fault { joint, reason }),
            None => Ok(()),
        }
    }

    /// Moves several joints to target angles (degrees) together: one normalised profile
    /// scaled per joint, so all arrive at the same time. `velocity` / `acceleration`
    /// (deg/s, deg/s^2) default to the configuration's.
    pub fn move_joints(
        &self,
        targets: &[(u8, f64)],
        velocity: Option<f64>,
        acceleration: Option<f64>,
    ) -> Result<(), ArmError> {
        let config = self.config();
        let v = velocity.unwrap_or(config.velocity_deg_s);
        let a = acceleration.unwrap_or(config.acceleration_deg_s2);
        let mut starts = Vec::new();
        for &(joint, target) in targets {
            let spec =
                *config.joints.get(usize::from(joint).wrapping_sub(1)).ok_or(ArmError::NoJoint(joint))?;
            if !target.is_finite() {
                return Err(ArmError::Unsafe { joint, reason: format!("target {target} is not a number") });
            }
            if let Some((lo, hi)) = spec.soft_limits_deg {
                if !(lo..=hi).contains(&target) {
                    return Err(ArmError::BeyondSoftLimit {
                        joint,
                        target_deg: target,
                        lower: lo,
                        upper: hi,
                    });
                }
            }
            let s = self.joint(joint)?;
            if let Some(f) = &s.fault {
                return Err(ArmError::Fault { joint, reason: f.clone() });
            }
            if !s.enabled {
                return Err(ArmError::Unsafe { joint, reason: "the drive is not enabled (EN)".into() });
            }
            if spec.brake && !s.status.brake_released {
                return Err(ArmError::Unsafe {
                    joint,
                    reason: "the brake is engaged: release it first".into(),
                });
            }
            if s.status.lsstop || s.status.limit_switch {
                return Err(ArmError::Fault {
                    joint,
                    reason: "the joint is on its limit switch (LSSTOP): run recover-limit".into(),
                });
            }
            let d = if spec.soft_limits_deg.is_none() {
                crate::joints::normalise_deg(target - s.angle_deg)
            } else {
                target - s.angle_deg
            };
            starts.push((joint, s.angle_deg, d, spec.max_deg_s().min(v), a));
        }
        let limits: Vec<(f64, f64, f64)> = starts.iter().map(|&(_, _, d, v, a)| (d, v, a)).collect();
        let Some(plan) = synchronised(&limits) else {
            return Ok(()); // nothing moves
        };
        let start = self.clock.now();
        let mut st = self.lock();
        for (joint, x0, d, _, _) in starts {
            if let Some(r) = st.joints.get_mut(usize::from(joint) - 1) {
                r.override_rpm = None;
                r.last_correction_at = None;
                r.motion = Some(controller::Motion { start, plan: plan.clone(), x0, d, settled_at: None });
            }
        }
        Ok(())
    }

    /// Jogs a joint at `deg_s` (signed): a move to its soft limit in that direction (so it
    /// decelerates and stops before the limit), or a constant speed for endless joints.
    pub fn jog(&self, joint: u8, deg_s: f64) -> Result<(), ArmError> {
        let config = self.config();
        let spec = *config.joints.get(usize::from(joint).wrapping_sub(1)).ok_or(ArmError::NoJoint(joint))?;
        match spec.soft_limits_deg {
            Some((lo, hi)) => {
                let target = if deg_s >= 0.0 { hi } else { lo };
                self.move_joints(&[(joint, target)], Some(deg_s.abs()), None)
            }
            None => self.run_at_rpm(joint, spec.rpm_for(deg_s)),
        }
    }

    /// Moves one joint at `rpm` (motor speed) until [`Kv01Arm::stop`]; the controller stops
    /// it before its soft limit (allowing for the stopping distance).
    pub fn run_at_rpm(&self, joint: u8, rpm: f64) -> Result<(), ArmError> {
        if !rpm.is_finite() {
            return Err(ArmError::Unsafe { joint, reason: format!("speed {rpm} is not a number") });
        }
        self.runtime(joint, |r| {
            r.motion = None;
            r.override_rpm = Some(rpm);
        })
    }

    /// Waits until none of `joints` moves; a fault on one of them ends the wait with it.
    pub fn wait_idle(&self, joints: &[u8], timeout: Duration) -> Result<Vec<JointState>, ArmError> {
        let t0 = self.clock.now();
        loop {
            let states: Vec<JointState> = joints.iter().map(|&j| self.joint(j)).collect::<Result<_, _>>()?;
            if let Some(s) = states.iter().find(|s| s.fault.is_some()) {
                return Err(ArmError::Fault { joint: s.joint, reason: s.fault.clone().unwrap_or_default() });
            }
            if states.iter().all(|s| !s.moving) {
                return Ok(states);
            }
            if self.clock.elapsed(t0) > timeout {
                return Err(ArmError::WaitTimeout { joints: joints.to_vec(), timeout });
            }
            self.clock.sleep(Duration::from_millis(5));
        }
    }

    /// Clears latched faults other than the safety time-out (which needs a power cycle).
    pub fn reset_faults(&self, joint: u8) -> Result<(), ArmError> {
        self.runtime(joint, |r| r.fault = None)
    }

    /// Reads the module's supply voltages (D4).
    pub fn voltages(&self, joint: u8) -> Result<Voltages, ArmError> {
        match self
            .bus
            .transact(address(joint)?, Command::ReadVoltages)
            .map_err(|e| self.note_bus_error(joint, e))?
        {
            ReplyBody::Voltages(v) => Ok(v),
            other => Err(ArmError::Unexpected { joint, what: "D4".into(), answer: format!("{other:?}") }),
        }
    }

    /// Sends the raw D1 action and returns the reply (status bits).
    pub fn d1_action(&self, joint: u8, action: D1Action) -> Result<ReplyBody, ArmError> {
        self.check_no_timeout(joint)?;
        if action == D1Action::ReleaseBrake && !self.runtime(joint, |r| r.enabled)? {
            return Err(ArmError::Unsafe {
                joint,
                reason:
                    "refusing to release the brake before the drive is enabled (EN): the joint could fall"
                        .into(),
            });
        }
        self.d1(joint, action)
    }

    /// Opens (`opening = true`) or closes the gripper at `speed` 0..=31 (D5).
    pub fn gripper(&self, speed: u8, opening: bool) -> Result<ReplyBody, ArmError> {
        let speed = speed.min(Command::MAX_GRIPPER_SPEED);
        self.bus
            .transact(Address::GRIPPER, Command::Gripper { speed, opening })
            .map_err(|e| self.note_bus_error(6, e))
    }

    /// Stops the controller thread (motions are stopped first).
    pub fn shutdown(&self) {
        for j in 1..=6 {
            let moving = self.runtime(j, |r| r.motion.is_some() || r.override_rpm.is_some()).unwrap_or(false);
            if moving {
                let _ = self.stop(j);
            }
        }
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.lock().unwrap_or_else(|p| p.into_inner()).take() {
            // The control thread ends at its next cycle, on the clock.
            let _ = motus_clock::while_blocked(&*self.clock, || t.join());
        }
    }
}

impl Drop for Kv01Arm {
    fn drop(&mut self) {
        self.shutdown();
    }
}
