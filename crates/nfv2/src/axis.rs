//! A 1209A as an axis of the axis model, in SI units: radians of the axis after the gear
//! (2000 counts per motor turn x 100:1 = 200 000 counts per output revolution by default;
//! a negative count inverts the direction).
//!
//! | axis command | 1209A |
//! |---|---|
//! | Enable / Disable | POSITION hold / ERROR (after a stop) |
//! | Home | HOMING until status bit 4 "synchronized" (the drive switches its bridge on) |
//! | MoveAbsolute / MoveRelative | POSITION at the profile speed and acceleration (relative moves are sent as absolute ones from the current target) |
//! | Jog | SPEED at the profile speed; with soft limits, a POSITION move to the soft limit |
//! | Stop / QuickStop | decelerate to rest (quick stop: the quick-stop acceleration) |
//! | FaultReset | leave ERROR, hold (refused while ENABLE is absent) |
//!
//! Soft limits are checked on the host (targets beyond are refused, as other Motus
//! axes do); the drive's own position limits ([`crate::DeviceLimits`]) clamp instead.

use std::sync::Arc;
use std::time::{Duration, Instant};

use motus_axis::{
    Axis, AxisCommand, AxisError, AxisFlags, AxisState, Capabilities, MotionProfile, Scale, UnitKind,
};
use motus_serial::BusConfig;

use crate::bus::Nfv2Bus;
use crate::drive::{Drive, DriveConfig, IntentKind};
use crate::error::Nfv2Error;
use crate::samples::WhereError;
use crate::scheduler::{Scheduler, SchedulerConfig};
use crate::stream::COUNTS_PER_S_PER_SPEED_UNIT;

/// Encoder counts per output revolution of the pan-tilt head's axes: 2000 per motor turn
/// through a 100:1 gear.
pub const DEFAULT_COUNTS_PER_REV: f64 = 200_000.0;

/// Settings of one 1209A axis.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisConfig {
    /// The drive's settings (address, default speed and acceleration in device units).
    pub drive: DriveConfig,
    /// Encoder counts per output revolution (negative: inverted direction).
    pub counts_per_rev: f64,
    /// Soft limits `(min, max)` in radians, checked on the host.
    pub soft_limits: Option<(f64, f64)>,
    /// Refuse absolute moves until the drive reports "synchronized" (homed).
    pub require_home: bool,
}

impl AxisConfig {
    /// Defaults for the drive at `address`: 200 000 counts per revolution, no soft
    /// limits, homing required.
    #[must_use]
    pub fn new(address: u8) -> Self {
        AxisConfig {
            drive: DriveConfig::new(address),
            counts_per_rev: DEFAULT_COUNTS_PER_REV,
            soft_limits: None,
            require_home: true,
        }
    }
}

/// A 1209A as a [`motus_axis::Axis`].
pub struct Nfv2Axis {
    scheduler: Option<Arc<Scheduler>>,
    drive: Drive,
    config: AxisConfig,
    scale: Scale,
    name: String,
}

impl Nfv2Axis {
    /// The axis of `drive` (on a scheduler the caller keeps running).
    ///
    /// # Errors
    /// [`Nfv2Error::InvalidArgument`] for a zero or non-finite `counts_per_rev`.
    pub fn new(drive: Drive, config: AxisConfig, name: impl Into<String>) -> Result<Self, Nfv2Error> {
        let scale = Scale::new(UnitKind::Rotary, std::f64::consts::TAU / config.counts_per_rev)
            .map_err(|e| Nfv2Error::InvalidArgument(e.to_string()))?;
        Ok(Nfv2Axis { scheduler: None, drive, config, scale, name: name.into() })
    }

    /// Opens the port at `path` and runs a scheduler with this one drive; the axis owns it.
    ///
    /// # Errors
    /// Opening the port, starting the scheduler, or a bad configuration.
    pub fn open(
        path: &str,
        baud: u32,
        bus: BusConfig,
        scheduler: SchedulerConfig,
        config: AxisConfig,
    ) -> Result<Self, Nfv2Error> {
        let bus = Nfv2Bus::open(path, baud, bus)?;
        Self::start(bus, scheduler, config)
    }

    /// Runs a scheduler with this one drive on `bus` (on the clock of its bus master); the
    /// axis owns it.
    ///
    /// # Errors
    /// Starting the scheduler, or a bad configuration.
    pub fn start(bus: Nfv2Bus, scheduler: SchedulerConfig, config: AxisConfig) -> Result<Self, Nfv2Error> {
        let name = format!("nfv2:{}#{}", bus.master().describe(), config.drive.address);
        let sched = Arc::new(Scheduler::start(bus, vec![config.drive.clone()], scheduler)?);
        let drive = sched.drive(config.drive.address)?;
        let mut axis = Self::new(drive, config, name)?;
        axis.scheduler = Some(sched);
        Ok(axis)
    }

    /// The drive (device units, raw access).
    #[must_use]
    pub fn drive(&self) -> &Drive {
        &self.drive
    }

    /// The scheduler, if this axis owns it.
    #[must_use]
    pub fn scheduler(&self) -> Option<&Arc<Scheduler>> {
        self.scheduler.as_ref()
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &AxisConfig {
        &self.config
    }

    /// The axis position (radians) at host time `t`, from the sample history.
    ///
    /// # Errors
    /// [`WhereError`] outside the history.
    pub fn position_at(&self, t: Instant) -> Result<f64, WhereError> {
        self.drive.position_at(t).map(|c| self.scale.position_to_si(c))
    }

    fn err(&self, command: &str, e: Nfv2Error) -> AxisError {
        let axis = self.name.clone();
        match e {
            Nfv2Error::Bus(motus_serial::BusError::Timeout { timeout, attempts, corrupt, .. }) => {
                AxisError::Timeout {
                    axis,
                    timeout,
                    attempts,
                    detail: if corrupt > 0 {
                        format!("; {corrupt} corrupt answer(s)")
                    } else {
                        String::new()
                    },
                }
            }
            Nfv2Error::NotConfirmed { what, waited, .. } => AxisError::Timeout {
                axis,
                timeout: waited,
                attempts: 1,
                detail: format!("; {what} not acknowledged"),
            },
            Nfv2Error::Bus(b) => AxisError::Communication { axis, reason: b.to_string() },
            e @ (Nfv2Error::Stopped | Nfv2Error::Open { .. }) => {
                AxisError::Communication { axis, reason: e.to_string() }
            }
            Nfv2Error::NotEnabled(_) => AxisError::NotEnabled { axis },
            Nfv2Error::Device { reason, .. } => AxisError::Refused { axis, command: command.into(), reason },
            Nfv2Error::WaitTimeout { what, timeout, .. } => AxisError::WaitTimeout { axis, what, timeout },
            e @ (Nfv2Error::Encode(_) | Nfv2Error::UnknownSlave(_) | Nfv2Error::InvalidArgument(_)) => {
                AxisError::InvalidArgument { axis, reason: e.to_string() }
            }
        }
    }

    fn invalid(&self, reason: impl Into<String>) -> AxisError {
        AxisError::InvalidArgument { axis: self.name.clone(), reason: reason.into() }
    }

    /// Speed units and acceleration (counts/s²) of `profile`, defaults from the drive.
    fn units(&self, profile: &MotionProfile) -> Result<(i64, i64), AxisError> {
        let d = &self.config.drive;
        let speed = match profile.velocity {
            None => d.speed,
            Some(v) if v.is_finite() && v > 0.0 => {
                let units = (self.scale.rate_from_si(v).abs() / COUNTS_PER_S_PER_SPEED_UNIT).round() as i64;
                units.max(1)
            }
            Some(v) => return Err(self.invalid(format!("velocity {v} must be a positive number"))),
        };
        let acceleration = match profile.acceleration.or(profile.deceleration) {
            None => d.acceleration,
            Some(a) if a.is_finite() && a > 0.0 => (self.scale.rate_from_si(a).abs().round() as i64).max(1),
            Some(a) => return Err(self.invalid(format!("acceleration {a} must be a positive number"))),
        };
        Ok((speed, acceleration))
    }

    fn move_absolute(
        &mut self,
        target: f64,
        profile: &MotionProfile,
        command: &str,
    ) -> Result<(), AxisError> {
        if !target.is_finite() {
            return Err(self.invalid(format!("target {target} is not a number")));
        }
        if let Some((min, max)) = self.config.soft_limits {
            if !(min..=max).contains(&target) {
                return Err(AxisError::BeyondLimit {
                    axis: self.name.clone(),
                    target,
                    min,
                    max,
                    unit: "rad".into(),
                });
            }
        }
        let snap = self.drive.snapshot();
        if self.config.require_home && !snap.homed {
            return Err(AxisError::NotHomed { axis: self.name.clone(), detail: String::new() });
        }
        let (speed, acceleration) = self.units(profile)?;
        let counts = self.scale.position_from_si(target).round();
        if counts.abs() > f64::from(i32::MAX) {
            return Err(self.invalid(format!("target {target} rad is beyond the 32-bit position counter")));
        }
        self.drive.move_to(counts as i64, Some(speed), Some(acceleration)).map_err(|e| self.err(command, e))
    }

    fn snapshot_with_sample(&self) -> Result<crate::DriveSnapshot, AxisError> {
        let clock = self.drive.clock();
        let t0 = clock.now();
        let timeout = self.scheduler.as_ref().map_or(Duration::from_secs(1), |s| s.config().confirm_timeout);
        loop {
            let s = self.drive.snapshot();
            if s.position.is_some() && s.status.is_some() {
                return Ok(s);
            }
            if clock.elapsed(t0) > timeout {
                return Err(AxisError::Timeout {
                    axis: self.name.clone(),
                    timeout,
                    attempts: 1,
                    detail: "; no position and status reading yet".into(),
                });
            }
            clock.sleep(Duration::from_millis(2));
        }
    }
}

impl Axis for Nfv2Axis {
    fn name(&self) -> &str {
        &self.name
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities { reports_velocity: true, reports_current: true, ..Capabilities::POSITIONING }
    }

    fn scale(&self) -> &Scale {
        &self.scale
    }

    fn read_state(&mut self) -> Result<AxisState, AxisError> {
        let s = self.snapshot_with_sample()?;
        let counts = s.position.map_or(0, |p| p.counts);
        let inverted = self.config.counts_per_rev < 0.0;
        let (limit_positive, limit_negative) =
            if inverted { (s.limit_down, s.limit_up) } else { (s.limit_up, s.limit_down) };
        Ok(AxisState {
            position: self.scale.position_to_si(counts as f64),
            position_raw: counts,
            velocity: s.velocity.map(|v| self.scale.rate_to_si(v)),
            current: s.current_ma.map(|ma| ma as f64 / 1000.0),
            following_error: None,
            flags: AxisFlags {
                enabled: s.enabled,
                homed: s.homed,
                moving: s.moving,
                target_reached: s.target_reached,
                limit_negative,
                limit_positive,
                brake_engaged: None,
            },
            faults: s.faults,
        })
    }

    fn execute(&mut self, command: &AxisCommand) -> Result<(), AxisError> {
        let name = command.name();
        match command {
            AxisCommand::Enable => self.drive.enable().map_err(|e| self.err(name, e)),
            AxisCommand::Disable => {
                if self.drive.snapshot().moving {
                    self.drive.stop().map_err(|e| self.err(name, e))?;
                    let _ = self.drive.wait_idle(Duration::from_secs(5));
                }
                self.drive.disable().map_err(|e| self.err(name, e))
            }
            AxisCommand::Home => self.drive.home().map_err(|e| self.err(name, e)),
            AxisCommand::MoveAbsolute { target, profile } => self.move_absolute(*target, profile, name),
            AxisCommand::MoveRelative { distance, profile } => {
                if !distance.is_finite() {
                    return Err(self.invalid(format!("distance {distance} is not a number")));
                }
                let s = self.snapshot_with_sample()?;
                // Relative to the running target (so a retried command cannot move twice
                // as far), else to the position.
                let base = match (s.intent, s.target, s.position) {
                    (IntentKind::Position, Some(t), _) if s.moving => t,
                    (_, _, Some(p)) => p.counts,
                    _ => 0,
                };
                let target = self.scale.position_to_si(base as f64) + distance;
                self.move_absolute(target, profile, name)
            }
            AxisCommand::Jog { direction, profile } => match self.config.soft_limits {
                Some((min, max)) => {
                    let limit = if direction.sign() > 0.0 { max } else { min };
                    self.move_absolute(limit, profile, name)
                }
                None => {
                    let (speed, acceleration) = self.units(profile)?;
                    let sign = direction.sign() * self.scale.si_per_unit().signum();
                    self.drive
                        .jog((sign * speed as f64) as i64, Some(acceleration))
                        .map_err(|e| self.err(name, e))
                }
            },
            AxisCommand::Stop => self.drive.stop().map_err(|e| self.err(name, e)),
            AxisCommand::QuickStop => self.drive.quick_stop().map_err(|e| self.err(name, e)),
            AxisCommand::FaultReset => self.drive.fault_reset().map_err(|e| self.err(name, e)),
        }
    }
}
