//! A CiA 402 drive as an axis of the axis model.

use crate::drive::{Drive, MoveKind};
use crate::error::DriveError;
use crate::io::{DriveIo, IoError};
use crate::settings::Profile;
use motus_axis::{
    Axis, AxisCommand, AxisError, AxisFlags, AxisState, Capabilities, Fault, FaultKind, MotionProfile, Scale,
};
use motus_cia402_protocol::{sw, PowerState};
use std::time::Duration;

/// A CiA 402 drive presented through [`Axis`]. Positions are SI through `scale` (raw unit
/// = one drive increment).
pub struct Cia402Axis<Io: DriveIo> {
    drive: Drive<Io>,
    name: String,
    scale: Scale,
    homed: bool,
    default_profile: Profile,
    homing_timeout: Duration,
}

impl<Io: DriveIo> Cia402Axis<Io> {
    /// An axis named `name` over `drive`; moves without an explicit profile use
    /// `default_profile`.
    pub fn new(drive: Drive<Io>, name: impl Into<String>, scale: Scale, default_profile: Profile) -> Self {
        Self {
            drive,
            name: name.into(),
            scale,
            homed: false,
            default_profile,
            homing_timeout: Duration::from_secs(60),
        }
    }

    /// The driver underneath.
    pub fn drive(&mut self) -> &mut Drive<Io> {
        &mut self.drive
    }

    /// True once `home` succeeded on this axis.
    pub fn is_homed(&self) -> bool {
        self.homed
    }

    fn err(&self, command: &str, e: DriveError) -> AxisError {
        let axis = self.name.clone();
        match e {
            DriveError::Io(IoError::Timeout { .. }) => {
                AxisError::Timeout { axis, timeout: Duration::ZERO, attempts: 1, detail: format!("; {e}") }
            }
            DriveError::Io(IoError::Bus { .. } | IoError::NodeLost { .. } | IoError::Malformed { .. }) => {
                AxisError::Communication { axis, reason: e.to_string() }
            }
            DriveError::Io(IoError::Refused { .. })
            | DriveError::ModeRefused { .. }
            | DriveError::ModeUnsupported { .. }
            | DriveError::SetPointNotAcknowledged { .. }
            | DriveError::StateTimeout { .. } => {
                AxisError::Refused { axis, command: command.into(), reason: e.to_string() }
            }
            DriveError::Fault { .. }
            | DriveError::FaultPersists { .. }
            | DriveError::FollowingError { .. }
            | DriveError::HomingFailed { .. } => AxisError::DeviceFault { axis, reason: e.to_string() },
            DriveError::NotEnabled { .. } => AxisError::NotEnabled { axis },
            DriveError::MotionTimeout { waited, .. } => {
                AxisError::WaitTimeout { axis, what: command.into(), timeout: waited }
            }
            DriveError::BeyondLimit { target, min, max, .. } => AxisError::BeyondLimit {
                axis,
                target: target as f64,
                min: f64::from(min),
                max: f64::from(max),
                unit: "device units".into(),
            },
            DriveError::InvalidArgument { reason, .. } => AxisError::InvalidArgument { axis, reason },
        }
    }

    fn profile(&self, p: &MotionProfile) -> Result<Profile, AxisError> {
        let conv = |si: Option<f64>, default: u32, what: &str| -> Result<u32, AxisError> {
            match si {
                None => Ok(default),
                Some(v) if v.is_finite() && v > 0.0 => {
                    let raw = self.scale.rate_from_si(v).abs().round();
                    if raw < 1.0 || raw > f64::from(u32::MAX) {
                        Err(AxisError::InvalidArgument {
                            axis: self.name.clone(),
                            reason: format!("{what} {v} is {raw} inc, outside 1 .. {}", u32::MAX),
                        })
                    } else {
                        Ok(raw as u32)
                    }
                }
                Some(v) => Err(AxisError::InvalidArgument {
                    axis: self.name.clone(),
                    reason: format!("{what} must be a positive number, got {v}"),
                }),
            }
        };
        let velocity = conv(p.velocity, self.default_profile.velocity, "velocity")?;
        let acceleration = conv(p.acceleration, self.default_profile.acceleration, "acceleration")?;
        let deceleration =
            conv(p.deceleration.or(p.acceleration), self.default_profile.deceleration, "deceleration")?;
        Ok(Profile { velocity, acceleration, deceleration })
    }

    fn raw_target(&self, si: f64, absolute: bool) -> Result<i32, AxisError> {
        let raw =
            if absolute { self.scale.position_from_si(si) } else { self.scale.rate_from_si(si) }.round();
        if !raw.is_finite() || raw < f64::from(i32::MIN) || raw > f64::from(i32::MAX) {
            return Err(AxisError::InvalidArgument {
                axis: self.name.clone(),
                reason: format!("target {si} does not fit the drive's 32-bit position"),
            });
        }
        Ok(raw as i32)
    }
}

fn fault_kind(code: Option<u16>) -> FaultKind {
    match code {
        Some(0x8611) => FaultKind::FollowingError,
        Some(c) if c & 0xFF00 == 0x8100 => FaultKind::CommunicationTimeout,
        Some(c) if c & 0xFF00 == 0x7300 => FaultKind::Encoder,
        _ => FaultKind::Other,
    }
}

impl<Io: DriveIo> Axis for Cia402Axis<Io> {
    fn name(&self) -> &str {
        &self.name
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities { reports_velocity: true, reports_following_error: false, ..Capabilities::POSITIONING }
    }

    fn scale(&self) -> &Scale {
        &self.scale
    }

    fn read_state(&mut self) -> Result<AxisState, AxisError> {
        let (state, word) = self.drive.state().map_err(|e| self.err("status", e))?;
        let raw = self.drive.position().map_err(|e| self.err("status", e))?;
        let velocity = self.drive.velocity().ok().map(|v| self.scale.rate_to_si(f64::from(v)));
        let mut faults = Vec::new();
        if matches!(state, PowerState::Fault | PowerState::FaultReactionActive) {
            let code = self.drive.error_code();
            faults.push(Fault {
                kind: fault_kind(code),
                reason: match code {
                    Some(c) => format!(
                        "CiA 402 fault, error code 0x{c:04X} ({})",
                        motus_canopen_protocol::EmcyClass::of(c).description()
                    ),
                    None => "CiA 402 fault (error code unreadable)".into(),
                },
            });
        }
        if word & sw::FOLLOWING_ERROR != 0 && state == PowerState::OperationEnabled {
            faults.push(Fault {
                kind: FaultKind::FollowingError,
                reason: "statusword bit 13: following error".into(),
            });
        }
        let target_reached = word & sw::TARGET_REACHED != 0;
        Ok(AxisState {
            position: self.scale.position_to_si(f64::from(raw)),
            position_raw: raw.into(),
            velocity,
            current: None,
            following_error: None,
            flags: AxisFlags {
                enabled: state == PowerState::OperationEnabled,
                homed: self.homed,
                moving: state == PowerState::OperationEnabled && !target_reached,
                target_reached,
                limit_negative: false,
                limit_positive: word & sw::INTERNAL_LIMIT != 0,
                brake_engaged: None,
            },
            faults,
        })
    }

    fn execute(&mut self, command: &AxisCommand) -> Result<(), AxisError> {
        let name = command.name();
        let result = match command {
            AxisCommand::Enable => self.drive.enable(),
            AxisCommand::Disable => self.drive.disable(),
            AxisCommand::Home => {
                let method = self.drive.settings().homing_method;
                let r = self.drive.home(method, self.homing_timeout);
                self.homed = r.is_ok();
                r
            }
            AxisCommand::MoveAbsolute { target, profile } => {
                if !self.homed {
                    return Err(AxisError::NotHomed { axis: self.name.clone(), detail: String::new() });
                }
                let p = self.profile(profile)?;
                let raw = self.raw_target(*target, true)?;
                self.drive.set_profile(&p).and_then(|_| self.drive.start_move(raw, MoveKind::Absolute, true))
            }
            AxisCommand::MoveRelative { distance, profile } => {
                let p = self.profile(profile)?;
                let raw = self.raw_target(*distance, false)?;
                self.drive.set_profile(&p).and_then(|_| self.drive.start_move(raw, MoveKind::Relative, true))
            }
            AxisCommand::Jog { direction, profile } => {
                let p = self.profile(profile)?;
                let v = i32::try_from(p.velocity).unwrap_or(i32::MAX);
                let signed = if direction.sign() < 0.0 { -v } else { v };
                self.drive.set_profile(&p).and_then(|_| self.drive.run_velocity(signed))
            }
            AxisCommand::Stop => self.drive.halt(),
            AxisCommand::QuickStop => self.drive.quick_stop(),
            AxisCommand::FaultReset => self.drive.fault_reset(),
        };
        result.map_err(|e| self.err(name, e))
    }
}
