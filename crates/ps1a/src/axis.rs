//! One PS1A module as an axis of the axis model.
//!
//! The PS1A reports position and status bits but not whether its power stage is on, and
//! some bits are cleared once reported: the driver therefore keeps what it learnt (last
//! control byte, latched faults, last target) and merges it with every reply.

use crate::bus::{Ps1aBus, Ps1aError};
use motus_axis::{
    Axis, AxisCommand, AxisError, AxisFlags, AxisState, Capabilities, Direction, Fault, FaultKind,
    MotionProfile, Scale,
};
use motus_ps1a_protocol::units::{
    acceleration_number_for, acceleration_units_per_s2, speed_value_for, velocity_units_per_s,
};
use motus_ps1a_protocol::{Acceleration, Command, ControlByte, DdaCycle, LowStatus, StatusReply, I24, U24};

/// Configuration of one PS1A axis (what the host must know, since the module's
/// parameters cannot be read back).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisConfig {
    /// Module address.
    pub addr: u8,
    /// SI size of one encoder unit (default 1e-5 m = 0.01 mm).
    pub scale: Scale,
    /// DS parameter in the module (for speed conversion).
    pub ds: u8,
    /// TVZ parameter in the module.
    pub tvz: DdaCycle,
    /// Maximum position parameter in the module (checked before sending).
    pub max_position: U24,
    /// Default speed value for moves and jogs.
    pub speed: u16,
    /// Default acceleration number.
    pub acceleration: Acceleration,
    /// Set D1 (interpolation blocking on following error) when enabling.
    pub interpolation_blocking: bool,
}

impl Default for AxisConfig {
    fn default() -> Self {
        AxisConfig {
            addr: 0,
            scale: Scale::HUNDREDTH_MM,
            ds: 39,
            tvz: DdaCycle::Ms1_54,
            max_position: U24::DEFAULT_MAX_POSITION,
            speed: 100,
            acceleration: Acceleration::MAX,
            interpolation_blocking: false,
        }
    }
}

/// A PS1A module as an axis.
pub struct Ps1aAxis {
    bus: Ps1aBus,
    config: AxisConfig,
    name: String,
    power_stage: Option<bool>,
    latched: Vec<Fault>,
    seen_homed: bool,
    last_target: Option<i64>,
    last_reply: Option<StatusReply>,
}

impl Ps1aAxis {
    /// The axis of module `config.addr` on `bus`.
    pub fn new(bus: Ps1aBus, config: AxisConfig) -> Self {
        let name = format!("ps1a:{}#{}", bus.master().describe(), config.addr);
        Ps1aAxis {
            bus,
            config,
            name,
            power_stage: None,
            latched: Vec::new(),
            seen_homed: false,
            last_target: None,
            last_reply: None,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &AxisConfig {
        &self.config
    }

    /// The bus this axis uses.
    pub fn bus(&self) -> &Ps1aBus {
        &self.bus
    }

    /// The last status reply received.
    pub fn last_reply(&self) -> Option<StatusReply> {
        self.last_reply
    }

    fn bus_error(&self, e: Ps1aError) -> AxisError {
        match e {
            Ps1aError::Bus(motus_serial::BusError::Timeout { timeout, attempts, corrupt, .. }) => {
                AxisError::Timeout {
                    axis: self.name.clone(),
                    timeout,
                    attempts,
                    detail: if corrupt > 0 {
                        format!("; {corrupt} corrupted reply frame(s)")
                    } else {
                        String::new()
                    },
                }
            }
            other => AxisError::Communication { axis: self.name.clone(), reason: other.to_string() },
        }
    }

    fn send(&mut self, command: Command) -> Result<StatusReply, AxisError> {
        let reply = self.bus.transact(self.config.addr, command).map_err(|e| self.bus_error(e))?;
        self.absorb(&reply);
        Ok(reply)
    }

    /// Merges a reply into what the driver knows: latches the clear-after-report fault
    /// bits and detects a module reset.
    fn absorb(&mut self, r: &StatusReply) {
        let low = r.low;
        let mut latch = |kind: FaultKind, reason: &str| {
            if !self.latched.iter().any(|f| f.kind == kind) {
                self.latched.push(Fault { kind, reason: reason.to_string() });
            }
        };
        if low.has(LowStatus::LIMIT_SWITCH) {
            latch(
                FaultKind::LimitSwitch,
                "emergency limit switch crossed (LBS bit 2): the module switched the power stage off",
            );
        }
        if low.has(LowStatus::ENCODER_ERROR) {
            latch(
                FaultKind::Encoder,
                "encoder error (LBS bit 3): lost phase, broken duty ratio or phase shift; power stage off",
            );
        }
        if low.has(LowStatus::FOLLOWING_ERROR) {
            latch(FaultKind::FollowingError, "following-error overflow during motion (LBS bit 7)");
        }
        if low.has(LowStatus::AFTER_RESET) && self.seen_homed {
            latch(
                FaultKind::DeviceReset,
                "module reset detected (LBS bit 0: power loss, restart or reset command): position reference lost, home again",
            );
            self.seen_homed = false;
            self.power_stage = Some(false);
            self.last_target = None;
        }
        if !low.has(LowStatus::AFTER_RESET) {
            self.seen_homed = true;
        }
        if low.has(LowStatus::LIMIT_SWITCH) || low.has(LowStatus::ENCODER_ERROR) {
            self.power_stage = Some(false);
        }
        self.last_reply = Some(*r);
    }

    fn raw_position(&self, r: &StatusReply) -> i64 {
        if self.config.max_position.get() < (1 << 23) {
            i64::from(r.position.as_signed())
        } else {
            i64::from(r.position.get())
        }
    }

    fn state_from(&self, r: &StatusReply) -> AxisState {
        let raw = self.raw_position(r);
        let moving = r.low.has(LowStatus::IN_MOTION);
        let homed = !r.low.has(LowStatus::AFTER_RESET)
            && !self.latched.iter().any(|f| f.kind == FaultKind::DeviceReset);
        let mut faults = self.latched.clone();
        if r.low.has(LowStatus::NO_PARAMETERS) {
            faults.push(Fault {
                kind: FaultKind::Other,
                reason:
                    "parameters were never sent (LBS bit 4): write them with `motus ps1a <port> params set`"
                        .into(),
            });
        }
        AxisState {
            position: self.config.scale.position_to_si(raw as f64),
            position_raw: raw,
            velocity: None,
            current: None,
            following_error: None,
            flags: AxisFlags {
                enabled: self.power_stage.unwrap_or(false),
                homed,
                moving,
                target_reached: !moving && self.last_target.is_none_or(|t| t == raw),
                limit_negative: false,
                limit_positive: false,
                brake_engaged: None,
            },
            faults,
        }
    }

    fn require_motion_ok(&mut self, command: &str) -> Result<StatusReply, AxisError> {
        let r = self.send(Command::StatusRequest)?;
        if let Some(f) = self.latched.iter().find(|f| f.kind != FaultKind::DeviceReset) {
            return Err(AxisError::DeviceFault {
                axis: self.name.clone(),
                reason: format!("{}; run fault-reset", f.reason),
            });
        }
        let reset = self.latched.iter().any(|f| f.kind == FaultKind::DeviceReset);
        if r.low.has(LowStatus::AFTER_RESET) || reset {
            let detail = if reset { "; a module reset was detected".to_string() } else { String::new() };
            return Err(AxisError::NotHomed { axis: self.name.clone(), detail });
        }
        if self.power_stage == Some(false) {
            return Err(AxisError::NotEnabled { axis: self.name.clone() });
        }
        let _ = command;
        Ok(r)
    }

    fn profile_numbers(&self, profile: &MotionProfile) -> Result<(u16, Acceleration), AxisError> {
        let c = &self.config;
        let speed = match profile.velocity {
            None => c.speed,
            Some(v) if v.is_finite() && v > 0.0 => {
                let units = c.scale.rate_from_si(v).abs();
                speed_value_for(units, c.ds, c.tvz).filter(|s| *s > 0).ok_or_else(|| {
                    AxisError::InvalidArgument {
                        axis: self.name.clone(),
                        reason: format!(
                            "velocity {v} is below one speed unit ({} units/s)",
                            velocity_units_per_s(1, c.ds, c.tvz)
                        ),
                    }
                })?
            }
            Some(v) => {
                return Err(AxisError::InvalidArgument {
                    axis: self.name.clone(),
                    reason: format!("velocity must be > 0, got {v}"),
                })
            }
        };
        let acceleration = match profile.acceleration {
            None => c.acceleration,
            Some(a) if a.is_finite() && a > 0.0 => {
                acceleration_number_for(c.scale.rate_from_si(a).abs(), c.ds, c.tvz)
                    .unwrap_or(Acceleration::MIN)
            }
            Some(a) => {
                return Err(AxisError::InvalidArgument {
                    axis: self.name.clone(),
                    reason: format!("acceleration must be > 0, got {a}"),
                })
            }
        };
        Ok((speed, acceleration))
    }

    fn move_to_raw(&mut self, target: i64, profile: &MotionProfile) -> Result<(), AxisError> {
        let max = i64::from(self.config.max_position.get());
        if !(0..=max).contains(&target) {
            let s = &self.config.scale;
            return Err(AxisError::BeyondLimit {
                axis: self.name.clone(),
                target: target as f64,
                min: 0.0,
                max: max as f64,
                unit: format!("device units (1 unit = {} {})", s.si_per_unit(), s.kind().symbol()),
            });
        }
        let (speed, acceleration) = self.profile_numbers(profile)?;
        self.require_motion_ok("move")?;
        self.send(Command::SetSpeed { speed, acceleration })?;
        let t = U24::new(u32::try_from(target).unwrap_or(0)).unwrap_or_default();
        let r = self.send(Command::MoveAbsolute { target: t })?;
        if r.low.has(LowStatus::BEYOND_MAX_POSITION) {
            return Err(AxisError::Refused {
                axis: self.name.clone(),
                command: "move".into(),
                reason: format!("target {target} is beyond the module's maximum position (LBS bit 6); the host's configured maximum ({max}) differs from the module's"),
            });
        }
        if r.low.has(LowStatus::NO_PARAMETERS) {
            return Err(AxisError::Refused {
                axis: self.name.clone(),
                command: "move".into(),
                reason: "the module has no parameters (LBS bit 4): write them first".into(),
            });
        }
        self.last_target = Some(target);
        Ok(())
    }

    /// Sends a raw relative move (command 5). Not retried on a lost reply, since a repeat
    /// would move twice; [`AxisCommand::MoveRelative`] uses absolute moves instead.
    pub fn raw_relative_move(&mut self, increment: I24) -> Result<StatusReply, AxisError> {
        self.require_motion_ok("move-rel")?;
        self.send(Command::MoveRelative { increment })
    }

    /// The speed of the configured default speed value, in units/s.
    pub fn default_velocity_units(&self) -> f64 {
        velocity_units_per_s(self.config.speed, self.config.ds, self.config.tvz)
    }

    /// The acceleration of the configured default number, in units/s^2.
    pub fn default_acceleration_units(&self) -> f64 {
        acceleration_units_per_s2(self.config.acceleration, self.config.ds, self.config.tvz)
    }

    fn control(&self, power: bool) -> ControlByte {
        let mut b = 0;
        if power {
            b |= ControlByte::POWER_STAGE;
        }
        if self.config.interpolation_blocking {
            b |= ControlByte::INTERPOLATION_BLOCKING;
        }
        ControlByte(b)
    }
}

impl Axis for Ps1aAxis {
    fn name(&self) -> &str {
        &self.name
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities::POSITIONING
    }

    fn scale(&self) -> &Scale {
        &self.config.scale
    }

    fn read_state(&mut self) -> Result<AxisState, AxisError> {
        let r = self.send(Command::StatusRequest)?;
        Ok(self.state_from(&r))
    }

    fn execute(&mut self, command: &AxisCommand) -> Result<(), AxisError> {
        match command {
            AxisCommand::Enable => {
                self.send(Command::ControlByte { control: self.control(true) })?;
                self.power_stage = Some(true);
            }
            AxisCommand::Disable => {
                self.send(Command::ControlByte { control: self.control(false) })?;
                self.power_stage = Some(false);
            }
            AxisCommand::Home => {
                if self.power_stage == Some(false) {
                    return Err(AxisError::NotEnabled { axis: self.name.clone() });
                }
                if let Some(f) = self.latched.iter().find(|f| f.kind != FaultKind::DeviceReset) {
                    return Err(AxisError::DeviceFault {
                        axis: self.name.clone(),
                        reason: format!("{}; run fault-reset", f.reason),
                    });
                }
                self.latched.retain(|f| f.kind != FaultKind::DeviceReset);
                self.seen_homed = false;
                self.last_target = None;
                let r = self.send(Command::Home)?;
                if r.low.has(LowStatus::NO_PARAMETERS) {
                    return Err(AxisError::Refused {
                        axis: self.name.clone(),
                        command: "home".into(),
                        reason: "the module has no parameters (LBS bit 4): write them first".into(),
                    });
                }
            }
            AxisCommand::MoveAbsolute { target, profile } => {
                if !target.is_finite() {
                    return Err(AxisError::InvalidArgument {
                        axis: self.name.clone(),
                        reason: format!("target {target} is not a number"),
                    });
                }
                let raw = self.config.scale.position_from_si(*target).round() as i64;
                self.move_to_raw(raw, profile)?;
            }
            AxisCommand::MoveRelative { distance, profile } => {
                if !distance.is_finite() {
                    return Err(AxisError::InvalidArgument {
                        axis: self.name.clone(),
                        reason: format!("distance {distance} is not a number"),
                    });
                }
                let r = self.require_motion_ok("move-rel")?;
                let moving = r.low.has(LowStatus::IN_MOTION);
                let base = match (moving, self.last_target) {
                    (true, Some(t)) => t,
                    _ => self.raw_position(&r),
                };
                let d = self.config.scale.rate_from_si(*distance).round() as i64;
                // Sent as an absolute move: a retry after a lost reply cannot move twice.
                self.move_to_raw(base + d, profile)?;
            }
            AxisCommand::Jog { direction, profile } => {
                let (speed, acceleration) = self.profile_numbers(profile)?;
                self.require_motion_ok("jog")?;
                self.send(Command::SetSpeed { speed, acceleration })?;
                self.last_target = None;
                self.send(match direction {
                    Direction::Positive => Command::JogPlus,
                    Direction::Negative => Command::JogMinus,
                })?;
            }
            AxisCommand::Stop => {
                self.send(Command::Stop)?;
                self.last_target = None;
            }
            AxisCommand::QuickStop => {
                // The PS1A has no quick stop: stop with the steepest acceleration number.
                let speed = self.config.speed.max(1);
                self.send(Command::SetSpeed { speed, acceleration: Acceleration::MAX })?;
                self.send(Command::Stop)?;
                self.last_target = None;
            }
            AxisCommand::FaultReset => {
                self.latched.retain(|f| f.kind == FaultKind::DeviceReset);
                self.read_state()?;
            }
        }
        Ok(())
    }
}
