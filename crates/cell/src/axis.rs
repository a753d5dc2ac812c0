//! [`CellAxis`]: the axis the station holds for one `[[axis]]`. It forwards to the current
//! driver axis in a shared slot (swapped when the device reconnects), carries the name and
//! scale of the cell file, converts between the driver's and the cell's SI when they differ,
//! and enforces the machine limits (position range, velocity and acceleration caps).

use std::sync::{Arc, Mutex, MutexGuard, PoisonError, TryLockError};

use motus_axis::{Axis, AxisCommand, AxisError, AxisState, Capabilities, MotionProfile, Scale};
use motus_station::config::AxisConfig;

/// The live driver axis of one configured axis (`None` while its device is down).
pub(crate) type Slot = Arc<Mutex<Option<Box<dyn Axis + Send>>>>;

/// An empty slot.
pub(crate) fn new_slot() -> Slot {
    Arc::new(Mutex::new(None))
}

/// Locks a slot (a panic elsewhere does not poison the cell).
pub(crate) fn lock(slot: &Slot) -> MutexGuard<'_, Option<Box<dyn Axis + Send>>> {
    slot.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Puts a driver axis into a slot.
pub(crate) fn put(slot: &Slot, axis: Box<dyn Axis + Send>) {
    *lock(slot) = Some(axis);
}

/// Cheap health check of the axis in a slot: `read_state` succeeds. A slot busy with a long
/// command (a blocking homing) counts as healthy: its user sees any failure itself.
pub(crate) fn slot_healthy(slot: &Slot) -> bool {
    match slot.try_lock() {
        Ok(mut g) => g.as_mut().is_some_and(|a| a.read_state().is_ok()),
        Err(TryLockError::WouldBlock) => true,
        Err(TryLockError::Poisoned(p)) => p.into_inner().as_mut().is_some_and(|a| a.read_state().is_ok()),
    }
}

/// True when two scales describe the same device unit (relative difference below 1e-6).
fn same_scale(a: &Scale, b: &Scale) -> bool {
    let (x, y) = (a.si_per_unit(), b.si_per_unit());
    (x - y).abs() <= 1e-6 * x.abs().max(y.abs()) && a.position_to_si(0.0) == b.position_to_si(0.0)
}

/// One configured axis (see the module documentation).
pub struct CellAxis {
    config: AxisConfig,
    device: String,
    slot: Slot,
}

impl std::fmt::Debug for CellAxis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CellAxis").field("name", &self.config.name).field("device", &self.device).finish()
    }
}

impl CellAxis {
    pub(crate) fn new(config: AxisConfig, slot: Slot) -> Self {
        let device = config.device.clone();
        Self { config, device, slot }
    }

    /// The device that moves this axis.
    pub fn device(&self) -> &str {
        &self.device
    }

    /// The axis configuration from the cell file.
    pub fn config(&self) -> &AxisConfig {
        &self.config
    }

    fn down(&self) -> AxisError {
        AxisError::Communication {
            axis: self.config.name.clone(),
            reason: format!("device {} is disconnected", self.device),
        }
    }

    /// Renames the driver's axis in an error to the configured name.
    fn rename(&self, e: AxisError) -> AxisError {
        let name = self.config.name.clone();
        match e {
            AxisError::NotHomed { detail, .. } => AxisError::NotHomed { axis: name, detail },
            AxisError::BeyondLimit { target, min, max, unit, .. } => {
                AxisError::BeyondLimit { axis: name, target, min, max, unit }
            }
            AxisError::NotEnabled { .. } => AxisError::NotEnabled { axis: name },
            AxisError::DeviceFault { reason, .. } => AxisError::DeviceFault { axis: name, reason },
            AxisError::Refused { command, reason, .. } => AxisError::Refused { axis: name, command, reason },
            AxisError::Timeout { timeout, attempts, detail, .. } => {
                AxisError::Timeout { axis: name, timeout, attempts, detail }
            }
            AxisError::Communication { reason, .. } => AxisError::Communication { axis: name, reason },
            AxisError::Unsupported { command, .. } => AxisError::Unsupported { axis: name, command },
            AxisError::InvalidArgument { reason, .. } => AxisError::InvalidArgument { axis: name, reason },
            AxisError::WaitTimeout { what, timeout, .. } => {
                AxisError::WaitTimeout { axis: name, what, timeout }
            }
        }
    }

    /// Caps the profile at the machine limits.
    fn cap(&self, p: &MotionProfile) -> MotionProfile {
        let v = self.config.max_velocity;
        let a = self.config.max_acceleration;
        MotionProfile {
            velocity: p.velocity.map(|x| x.min(v)),
            acceleration: p.acceleration.map(|x| x.min(a)),
            deceleration: p.deceleration.map(|x| x.min(a)),
        }
    }

    fn check_target(&self, target: f64) -> Result<(), AxisError> {
        let l = self.config.limits;
        if !target.is_finite() || target < l.min || target > l.max {
            return Err(AxisError::BeyondLimit {
                axis: self.config.name.clone(),
                target,
                min: l.min,
                max: l.max,
                unit: self.config.unit.symbol().into(),
            });
        }
        Ok(())
    }
}

/// Converts between the driver's SI and the cell's SI through the common device unit.
struct Conv<'a> {
    driver: &'a Scale,
    cell: &'a Scale,
    same: bool,
}

impl Conv<'_> {
    fn position_to_cell(&self, si: f64) -> f64 {
        if self.same {
            si
        } else {
            self.cell.position_to_si(self.driver.position_from_si(si))
        }
    }
    fn position_to_driver(&self, si: f64) -> f64 {
        if self.same {
            si
        } else {
            self.driver.position_to_si(self.cell.position_from_si(si))
        }
    }
    fn rate_to_cell(&self, si: f64) -> f64 {
        if self.same {
            si
        } else {
            self.cell.rate_to_si(self.driver.rate_from_si(si))
        }
    }
    fn rate_to_driver(&self, si: f64) -> f64 {
        if self.same {
            si
        } else {
            self.driver.rate_to_si(self.cell.rate_from_si(si))
        }
    }
    fn profile(&self, p: &MotionProfile) -> MotionProfile {
        MotionProfile {
            velocity: p.velocity.map(|v| self.rate_to_driver(v)),
            acceleration: p.acceleration.map(|v| self.rate_to_driver(v)),
            deceleration: p.deceleration.map(|v| self.rate_to_driver(v)),
        }
    }
}

impl Axis for CellAxis {
    fn name(&self) -> &str {
        &self.config.name
    }

    fn capabilities(&self) -> Capabilities {
        lock(&self.slot).as_ref().map_or(Capabilities::POSITIONING, |a| a.capabilities())
    }

    fn scale(&self) -> &Scale {
        &self.config.scale
    }

    fn read_state(&mut self) -> Result<AxisState, AxisError> {
        let mut g = lock(&self.slot);
        let inner = g.as_mut().ok_or_else(|| self.down())?;
        let mut s = inner.read_state().map_err(|e| self.rename(e))?;
        let driver = *inner.scale();
        let c =
            Conv { driver: &driver, cell: &self.config.scale, same: same_scale(&driver, &self.config.scale) };
        s.position = c.position_to_cell(s.position);
        s.velocity = s.velocity.map(|v| c.rate_to_cell(v));
        s.following_error = s.following_error.map(|v| c.rate_to_cell(v));
        Ok(s)
    }

    fn execute(&mut self, command: &AxisCommand) -> Result<(), AxisError> {
        let mut g = lock(&self.slot);
        let inner = g.as_mut().ok_or_else(|| self.down())?;
        let driver = *inner.scale();
        let c =
            Conv { driver: &driver, cell: &self.config.scale, same: same_scale(&driver, &self.config.scale) };
        let cmd = match command {
            AxisCommand::MoveAbsolute { target, profile } => {
                self.check_target(*target)?;
                AxisCommand::MoveAbsolute {
                    target: c.position_to_driver(*target),
                    profile: c.profile(&self.cap(profile)),
                }
            }
            AxisCommand::MoveRelative { distance, profile } => AxisCommand::MoveRelative {
                distance: c.rate_to_driver(*distance),
                profile: c.profile(&self.cap(profile)),
            },
            AxisCommand::Jog { direction, profile } => {
                AxisCommand::Jog { direction: *direction, profile: c.profile(&self.cap(profile)) }
            }
            other => other.clone(),
        };
        inner.execute(&cmd).map_err(|e| self.rename(e))
    }
}
