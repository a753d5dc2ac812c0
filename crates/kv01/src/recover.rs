//! Driving a joint out of its limit switch, the documented procedure of `specs/kv01.md`:
//! restricted mode (D1 0xA1), "DIPROG" (the drive's own limit-switch program off), "EN",
//! brake release, a slow move out (|speed| <= 399 rpm, the module's limit) until the switch
//! is free and the joint is back inside its soft limits, speed 0, leave restricted mode
//! (D1 0xA0), "ENPROG". Any surprise (moving the wrong way, no progress, a refusal) stops
//! the joint and engages its brake.

use crate::arm::{address, ArmError, JointState, Kv01Arm};
use motus_kv01_protocol::{Command, D1Action};
use std::time::Duration;

/// Speed of the move out (rpm): well inside the restricted-mode limit of 399 rpm.
pub const RECOVERY_RPM: f64 = 200.0;
/// How far (degrees) the joint may move the wrong way before the recovery stops.
pub const WRONG_WAY_TOLERANCE_DEG: f64 = 0.5;
/// How far (degrees) the joint may travel with its switch still pressed before the
/// recovery concludes it is driving the wrong way (deeper into the switch zone).
pub const MAX_TRAVEL_ON_SWITCH_DEG: f64 = 10.0;
/// A joint commanded to move that advances less than this (degrees) in
/// [`STALL_TIME`] has stalled (e.g. against a mechanical end stop).
pub const STALL_DEG: f64 = 0.05;
/// See [`STALL_DEG`].
pub const STALL_TIME: Duration = Duration::from_millis(700);

impl Kv01Arm {
    /// Recovers `joint` from its limit switch by driving it in `direction` (+1 or -1).
    /// `progress` sees the joint state while it moves.
    pub fn recover_limit(
        &self,
        joint: u8,
        direction: i8,
        timeout: Duration,
        mut progress: impl FnMut(&JointState),
    ) -> Result<JointState, ArmError> {
        let spec =
            *self.config().joints.get(usize::from(joint).wrapping_sub(1)).ok_or(ArmError::NoJoint(joint))?;
        let start = self.joint(joint)?;
        if !(start.status.limit_switch || start.status.lsstop) {
            return Err(ArmError::Unsafe {
                joint,
                reason: "the joint is not on its limit switch: nothing to recover".into(),
            });
        }
        let dir = f64::from(direction.signum());
        if dir == 0.0 {
            return Err(ArmError::Unsafe { joint, reason: "direction must be + or -".into() });
        }
        if let Some((lo, hi)) = spec.soft_limits_deg {
            let inward = if start.angle_deg >= hi {
                -1.0
            } else if start.angle_deg <= lo {
                1.0
            } else {
                0.0
            };
            if inward != 0.0 && inward != dir {
                return Err(ArmError::Unsafe {
                    joint,
                    reason: format!(
                        "the joint is at {:.2} deg, beyond its {} soft limit: driving {} would push it further onto the switch; use --direction {}",
                        start.angle_deg,
                        if inward < 0.0 { "upper" } else { "lower" },
                        if dir > 0.0 { "+" } else { "-" },
                        if inward > 0.0 { "+" } else { "-" },
                    ),
                });
            }
        }
        self.set_recovering(joint, true)?;
        let result = self.drive_out(joint, dir, &spec, start.angle_deg, timeout, &mut progress);
        self.set_recovering(joint, false)?;
        match result {
            Ok(state) => Ok(state),
            Err(e) => {
                // Stop safely: speed 0, brake on. Errors here are secondary to the first.
                let _ = self.stop(joint);
                if spec.brake {
                    let _ = self.bus().transact(address(joint)?, Command::BrakeLimit(D1Action::EngageBrake));
                }
                Err(e)
            }
        }
    }

    fn drive_out(
        &self,
        joint: u8,
        dir: f64,
        spec: &crate::JointSpec,
        start_angle: f64,
        timeout: Duration,
        progress: &mut impl FnMut(&JointState),
    ) -> Result<JointState, ArmError> {
        self.d1_action(joint, D1Action::EnterRestrictedMode)?;
        self.faulhaber_ok(joint, "DIPROG")?;
        self.enable(joint)?;
        if spec.brake {
            self.release_brake(joint)?;
        }
        self.reset_faults(joint)?;
        let rpm = dir * RECOVERY_RPM * f64::from(spec.speed_sign.signum());
        self.run_at_rpm(joint, rpm)?;
        let clock = self.clock();
        let t0 = clock.now();
        let expected = dir * f64::from(spec.speed_sign.signum()) * spec.deg_s_per_rpm().signum();
        let mut last_progress = (start_angle, clock.now());
        loop {
            clock.sleep(Duration::from_millis(10));
            let s = self.joint(joint)?;
            progress(&s);
            let moved = (s.angle_deg - start_angle) * expected;
            if (s.angle_deg - last_progress.0).abs() >= STALL_DEG {
                last_progress = (s.angle_deg, clock.now());
            } else if clock.elapsed(last_progress.1) > STALL_TIME {
                return Err(ArmError::Unsafe {
                    joint,
                    reason: format!(
                        "the joint does not move (stalled at {:.2} deg, against an end stop?): stopped, brake engaged; try the other direction",
                        s.angle_deg
                    ),
                });
            }
            if s.status.limit_switch && moved > MAX_TRAVEL_ON_SWITCH_DEG {
                return Err(ArmError::Unsafe {
                    joint,
                    reason: format!(
                        "the joint moved {moved:.1} deg and is still on its limit switch: probably the wrong way; stopped, brake engaged"
                    ),
                });
            }
            if moved < -WRONG_WAY_TOLERANCE_DEG {
                return Err(ArmError::Unsafe {
                    joint,
                    reason: format!(
                        "the joint moved {:.2} deg the wrong way: stopped, brake engaged",
                        -moved
                    ),
                });
            }
            if !s.moving && !(s.status.limit_switch) && spec.within_soft_limits(s.angle_deg) {
                break;
            }
            if !s.status.limit_switch && spec.within_soft_limits(s.angle_deg) && moved > 1.0 {
                self.stop(joint)?;
                break;
            }
            if !s.moving {
                return Err(ArmError::Fault {
                    joint,
                    reason: s
                        .fault
                        .clone()
                        .unwrap_or_else(|| "the joint stopped before leaving its limit switch".into()),
                });
            }
            if clock.elapsed(t0) > timeout {
                return Err(ArmError::WaitTimeout { joints: vec![joint], timeout });
            }
        }
        self.d1_action(joint, D1Action::LeaveRestrictedMode)?;
        self.faulhaber_ok(joint, "ENPROG")?;
        self.joint(joint)
    }

    fn faulhaber_ok(&self, joint: u8, text: &str) -> Result<(), ArmError> {
        match self.faulhaber(joint, text)? {
            motus_kv01_protocol::Answer::Controller(motus_kv01_protocol::faulhaber::Reply::Ok) => Ok(()),
            other => Err(ArmError::Unexpected { joint, what: text.into(), answer: other.to_string() }),
        }
    }

    fn set_recovering(&self, joint: u8, on: bool) -> Result<(), ArmError> {
        let i = usize::from(joint).checked_sub(1).ok_or(ArmError::NoJoint(joint))?;
        let mut st = self.lock();
        let r = st.joints.get_mut(i).ok_or(ArmError::NoJoint(joint))?;
        r.recovering = on;
        Ok(())
    }
}
