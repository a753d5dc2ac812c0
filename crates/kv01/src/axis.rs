//! One joint of the arm as an axis of the axis model (positions in radians; the resolver
//! is absolute, so a joint is always homed).

use crate::arm::{ArmError, Kv01Arm};
use motus_axis::{
    Axis, AxisCommand, AxisError, AxisFlags, AxisState, Capabilities, Direction, Fault, FaultKind, Scale,
    UnitKind,
};
use std::sync::Arc;

/// A joint of a shared [`Kv01Arm`].
pub struct Kv01JointAxis {
    arm: Arc<Kv01Arm>,
    joint: u8,
    name: String,
    scale: Scale,
}

impl Kv01JointAxis {
    /// Joint `joint` (1..=6) of `arm`.
    pub fn new(arm: Arc<Kv01Arm>, joint: u8) -> Result<Self, ArmError> {
        crate::arm::address(joint)?;
        let name = format!("kv01:{}#joint{joint}", arm.bus().master().describe());
        // One "device unit" of this axis is a millidegree of joint angle.
        let scale = Scale::new(UnitKind::Rotary, std::f64::consts::PI / 180_000.0)
            .map_err(|e| ArmError::Unsafe { joint, reason: e.to_string() })?;
        Ok(Kv01JointAxis { arm, joint, name, scale })
    }

    fn err(&self, e: ArmError) -> AxisError {
        let axis = self.name.clone();
        match e {
            ArmError::BeyondSoftLimit { target_deg, lower, upper, .. } => AxisError::BeyondLimit {
                axis,
                target: target_deg,
                min: lower,
                max: upper,
                unit: "deg".into(),
            },
            ArmError::Fault { reason, .. } => AxisError::DeviceFault { axis, reason },
            ArmError::Unsafe { reason, .. } => AxisError::Refused { axis, command: "command".into(), reason },
            ArmError::Bus(crate::Kv01Error::Bus(b)) => {
                AxisError::Communication { axis, reason: b.to_string() }
            }
            other => AxisError::Refused { axis, command: "command".into(), reason: other.to_string() },
        }
    }
}

impl Axis for Kv01JointAxis {
    fn name(&self) -> &str {
        &self.name
    }

    fn capabilities(&self) -> Capabilities {
        // The resolver is absolute: no homing.
        Capabilities { home: false, brake: self.joint <= 5, ..Capabilities::POSITIONING }
    }

    fn scale(&self) -> &Scale {
        &self.scale
    }

    fn read_state(&mut self) -> Result<AxisState, AxisError> {
        let s = self.arm.joint(self.joint).map_err(|e| self.err(e))?;
        let mut faults = Vec::new();
        if let Some(reason) = &s.fault {
            let kind = if reason.contains("700 ms") {
                FaultKind::CommunicationTimeout
            } else if reason.contains("limit switch") {
                FaultKind::LimitSwitch
            } else {
                FaultKind::Other
            };
            faults.push(Fault { kind, reason: reason.clone() });
        } else if s.status.lsstop {
            faults.push(Fault {
                kind: FaultKind::LimitSwitch,
                reason: "on the limit switch (LSSTOP): run recover-limit".into(),
            });
        }
        Ok(AxisState {
            position: s.angle_deg.to_radians(),
            position_raw: (s.angle_deg * 1000.0).round() as i64,
            velocity: None,
            current: None,
            following_error: None,
            flags: AxisFlags {
                enabled: s.enabled,
                homed: true,
                moving: s.moving,
                target_reached: !s.moving,
                limit_negative: s.status.limit_switch && s.angle_deg < 0.0,
                limit_positive: s.status.limit_switch && s.angle_deg >= 0.0,
                brake_engaged: (self.joint <= 5).then_some(!s.status.brake_released),
            },
            faults,
        })
    }

    fn execute(&mut self, command: &AxisCommand) -> Result<(), AxisError> {
        let j = self.joint;
        let arm = self.arm.clone();
        let deg_s = |v: Option<f64>| v.map(f64::to_degrees);
        let r = match command {
            AxisCommand::Enable => arm.power_up(j),
            AxisCommand::Disable => arm.disable(j),
            AxisCommand::Home => {
                return Err(AxisError::Unsupported {
                    axis: self.name.clone(),
                    command: "home (absolute resolver)".into(),
                })
            }
            AxisCommand::MoveAbsolute { target, profile } => arm.move_joints(
                &[(j, target.to_degrees())],
                deg_s(profile.velocity),
                deg_s(profile.acceleration),
            ),
            AxisCommand::MoveRelative { distance, profile } => {
                let s = arm.joint(j).map_err(|e| self.err(e))?;
                arm.move_joints(
                    &[(j, crate::normalise_deg(s.angle_deg + distance.to_degrees()))],
                    deg_s(profile.velocity),
                    deg_s(profile.acceleration),
                )
            }
            AxisCommand::Jog { direction, profile } => {
                let config = arm.config();
                let spec = config.joints.get(usize::from(j) - 1).copied();
                let v = deg_s(profile.velocity).unwrap_or(config.velocity_deg_s);
                let sign = match direction {
                    Direction::Positive => 1.0,
                    Direction::Negative => -1.0,
                };
                match spec {
                    Some(_) => arm.jog(j, sign * v),
                    None => Err(ArmError::NoJoint(j)),
                }
            }
            AxisCommand::Stop | AxisCommand::QuickStop => arm.stop(j),
            AxisCommand::FaultReset => arm.reset_faults(j),
        };
        r.map_err(|e| self.err(e))
    }
}
