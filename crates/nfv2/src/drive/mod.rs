//! One 1209A on the scheduler's bus, in device units: positions in encoder counts, speeds
//! in NFv2 speed units (1/100 count per 1 ms = 10 counts/s), accelerations in counts/s²,
//! currents in mA.
//!
//! A [`Drive`] is a handle: commands change what the scheduler sends from the next cycle
//! on, and return once a valid answer to a frame carrying them has arrived (NFv2 has no
//! other acknowledgement). The active set-point is re-sent every cycle (the 1209A's 2 s
//! command watchdog).
//!
//! | command | mode | set-points |
//! |---|---|---|
//! | [`Drive::enable`] | POSITION | position = present position (hold) |
//! | [`Drive::disable`] | ERROR | none (bridge off) |
//! | [`Drive::home`] | HOMING (SYNC_POS0 before 2014) | none; done when status bit 4 "synchronized" is set, then POSITION hold |
//! | [`Drive::move_to`] | POSITION | position (every cycle), profile speed, acceleration |
//! | [`Drive::jog`] | SPEED | speed (every cycle), acceleration |
//! | [`Drive::stop`] / [`Drive::quick_stop`] | unchanged | target = stopping point / speed 0 |
//! | [`Drive::fault_reset`] | POSITION | hold (leaves ERROR) |
//!
//! Every wait polls the shared state on the scheduler's clock ([`Drive::clock`]), so a
//! drive on a virtual clock waits in virtual time.

mod config;
pub(crate) mod registers;
pub(crate) mod runtime;
mod snapshot;
pub(crate) mod status;

use std::sync::Arc;
use std::time::{Duration, Instant};

use motus_axis::Fault;
use motus_clock::SharedClock;
use motus_nfv2_protocol::{DriveStatus, Revision};

use crate::error::Nfv2Error;
use crate::samples::{PositionSample, WhereError};
use crate::scheduler::Inner;
use crate::stream::{StreamCommand, StreamLink};
pub use config::{DeviceLimits, DriveConfig};
use registers::Reg;
use runtime::DriveRuntime;
use snapshot::empty;
pub use snapshot::{DriveSnapshot, IntentKind};
pub use status::INPUT_ENABLE;

/// How often a wait looks at the state the cycle thread updates.
const POLL: Duration = Duration::from_millis(1);

/// A handle on one 1209A of a running [`crate::Scheduler`].
#[derive(Clone)]
pub struct Drive {
    inner: Arc<Inner>,
    index: usize,
    address: u8,
}

impl Drive {
    pub(crate) fn new(inner: Arc<Inner>, index: usize, address: u8) -> Self {
        Drive { inner, index, address }
    }

    /// Bus address.
    #[must_use]
    pub fn address(&self) -> u8 {
        self.address
    }

    /// The drive's protocol revision.
    #[must_use]
    pub fn revision(&self) -> Revision {
        self.inner.bus.revision(self.address)
    }

    /// The clock of the drive's scheduler (its waits and timestamps).
    #[must_use]
    pub fn clock(&self) -> &SharedClock {
        &self.inner.clock
    }

    /// The drive's settings.
    #[must_use]
    pub fn config(&self) -> DriveConfig {
        self.with(|d| d.config.clone()).unwrap_or_else(|_| DriveConfig::new(self.address))
    }

    fn with<T>(&self, f: impl FnOnce(&mut DriveRuntime) -> T) -> Result<T, Nfv2Error> {
        let mut st = self.inner.lock();
        st.drives.get_mut(self.index).map(f).ok_or(Nfv2Error::UnknownSlave(self.address))
    }

    /// The latest state.
    #[must_use]
    pub fn snapshot(&self) -> DriveSnapshot {
        let silence = self.inner.config.silence;
        let now = self.inner.clock.now();
        let mut snap = self.with(|d| d.snapshot(silence, now)).unwrap_or_else(|_| empty(self.address));
        if !self.inner.running() {
            snap.faults.push(Fault {
                kind: motus_axis::FaultKind::CommunicationTimeout,
                reason: "the NFv2 bus scheduler is stopped".into(),
            });
        }
        snap
    }

    fn check_running(&self) -> Result<(), Nfv2Error> {
        if self.inner.running() {
            Ok(())
        } else {
            Err(Nfv2Error::Stopped)
        }
    }

    fn check_fault(&self, d: &DriveRuntime) -> Result<(), Nfv2Error> {
        match d.fault() {
            Some(f) => Err(Nfv2Error::Device { address: self.address, reason: f.reason.clone() }),
            None => Ok(()),
        }
    }

    /// Waits until the values of `regs` were acknowledged.
    fn wait_confirmed(&self, what: &str, regs: &[Reg]) -> Result<(), Nfv2Error> {
        let timeout = self.inner.config.confirm_timeout;
        let t0 = self.inner.clock.now();
        loop {
            self.check_running()?;
            let done = self.with(|d| {
                regs.iter().all(|&r| d.regs.value(r).is_none() || d.regs.value(r) == d.regs.confirmed(r))
            })?;
            if done {
                return Ok(());
            }
            if self.inner.clock.elapsed(t0) > timeout {
                return Err(Nfv2Error::NotConfirmed {
                    address: self.address,
                    what: what.into(),
                    waited: timeout,
                });
            }
            self.inner.clock.sleep(POLL);
        }
    }

    fn wait_sample(&self) -> Result<PositionSample, Nfv2Error> {
        let timeout = self.inner.config.confirm_timeout;
        let t0 = self.inner.clock.now();
        loop {
            self.check_running()?;
            if let Some(s) = self.with(|d| d.history.latest())? {
                return Ok(s);
            }
            if self.inner.clock.elapsed(t0) > timeout {
                return Err(Nfv2Error::NotConfirmed {
                    address: self.address,
                    what: "a position reading".into(),
                    waited: timeout,
                });
            }
            self.inner.clock.sleep(POLL);
        }
    }

    /// Switches the drive on, holding its present position (POSITION mode). Fails with
    /// the drive's reason if it stays in ERROR (e.g. the ENABLE input is absent).
    ///
    /// # Errors
    /// A latched fault, no answer, or the drive refusing to leave ERROR.
    pub fn enable(&self) -> Result<(), Nfv2Error> {
        self.check_running()?;
        self.wait_sample()?;
        self.with(|d| {
            self.check_fault(d)?;
            let at = d.history.latest().map(|s| s.counts).unwrap_or_default();
            d.regs.force(Reg::Mode);
            d.hold_at(at);
            Ok::<_, Nfv2Error>(())
        })??;
        self.wait_confirmed("enable (mode POSITION)", &[Reg::Mode, Reg::Position, Reg::Speed])?;
        self.wait_out_of_error()
    }

    /// Waits until the status leaves ERROR (debounced over two answers): a drive without
    /// ENABLE ignores a mode change. On failure the drive is set to ERROR again.
    fn wait_out_of_error(&self) -> Result<(), Nfv2Error> {
        let timeout = self.inner.config.confirm_timeout;
        let t0 = self.inner.clock.now();
        loop {
            let (ok, cause) = self.with(|d| {
                let status = d.status();
                let ok = status.is_some_and(|s| !s.contains(DriveStatus::ERROR));
                (ok, status.map(|s| status::error_cause(s, d.inputs()).reason))
            })?;
            if ok {
                return Ok(());
            }
            if self.inner.clock.elapsed(t0) > timeout {
                let _ = self.with(DriveRuntime::disable);
                return Err(Nfv2Error::Device {
                    address: self.address,
                    reason: format!(
                        "stays in ERROR after the mode change: {}",
                        cause.unwrap_or_else(|| "no status read".into())
                    ),
                });
            }
            self.inner.clock.sleep(POLL);
        }
    }

    /// Switches the drive off (mode ERROR: bridge off, the axis coasts).
    ///
    /// # Errors
    /// No answer.
    pub fn disable(&self) -> Result<(), Nfv2Error> {
        self.check_running()?;
        self.with(DriveRuntime::disable)?;
        self.wait_confirmed("disable (mode ERROR)", &[Reg::Mode])
    }

    /// Starts homing (HOMING mode: the drive finds the edge of its HOME sensor and sets
    /// its counter there). The drive switches its bridge on for it. Use
    /// [`Drive::wait_homed`] to wait for "synchronized".
    ///
    /// # Errors
    /// A latched fault, a revision without homing, no answer.
    pub fn home(&self) -> Result<(), Nfv2Error> {
        self.check_running()?;
        self.with(|d| {
            self.check_fault(d)?;
            if d.homing_raw().is_none() {
                return Err(Nfv2Error::InvalidArgument(format!("revision {} has no homing mode", d.rev)));
            }
            d.home();
            Ok(())
        })??;
        self.wait_confirmed("home (mode HOMING)", &[Reg::Mode])
    }

    /// Waits until homing is done (status bit 4 after the HOMING mode took effect) and
    /// the drive holds its position in POSITION mode.
    ///
    /// # Errors
    /// A fault, or [`Nfv2Error::WaitTimeout`].
    pub fn wait_homed(&self, timeout: Duration) -> Result<DriveSnapshot, Nfv2Error> {
        self.wait_for("homing", timeout, |s| s.intent != IntentKind::Homing && s.homed && s.settled)
    }

    /// Waits until the drive is not moving (target reached, jog stopped...).
    ///
    /// # Errors
    /// A fault, or [`Nfv2Error::WaitTimeout`].
    pub fn wait_idle(&self, timeout: Duration) -> Result<DriveSnapshot, Nfv2Error> {
        self.wait_for("motion", timeout, |s| !s.moving)
    }

    fn wait_for(
        &self,
        what: &str,
        timeout: Duration,
        done: impl Fn(&DriveSnapshot) -> bool,
    ) -> Result<DriveSnapshot, Nfv2Error> {
        let t0 = self.inner.clock.now();
        loop {
            self.check_running()?;
            let s = self.snapshot();
            if let Some(f) = s.faults.first() {
                return Err(Nfv2Error::Device { address: self.address, reason: f.reason.clone() });
            }
            if done(&s) {
                return Ok(s);
            }
            if self.inner.clock.elapsed(t0) > timeout {
                return Err(Nfv2Error::WaitTimeout { address: self.address, what: what.into(), timeout });
            }
            self.inner.clock.sleep(POLL * 2);
        }
    }

    fn check_motion(&self, d: &DriveRuntime, direction: f64) -> Result<(), Nfv2Error> {
        self.check_fault(d)?;
        let Some(status) = d.status() else {
            return Err(Nfv2Error::NotConfirmed {
                address: self.address,
                what: "a status reading".into(),
                waited: Duration::ZERO,
            });
        };
        if status.contains(DriveStatus::ERROR) {
            return Err(Nfv2Error::NotEnabled(self.address));
        }
        if status.contains(DriveStatus::POWER_STAGE_VOLTAGE_LOW) {
            return Err(Nfv2Error::Device {
                address: self.address,
                reason: "power stage supply low (status bit 9): no motion possible".into(),
            });
        }
        let blocked = (direction > 0.0 && status.contains(DriveStatus::LIMIT_SWITCH_UP))
            || (direction < 0.0 && status.contains(DriveStatus::LIMIT_SWITCH_DOWN));
        if blocked {
            return Err(Nfv2Error::Device {
                address: self.address,
                reason: "the limit switch in that direction is closed: only moves away from it are possible"
                    .into(),
            });
        }
        Ok(())
    }

    /// Moves to `target` counts in POSITION mode at `speed` units and `acceleration`
    /// counts/s² (the configured defaults when `None`). The drive clamps a target outside
    /// its position limits and a speed above its speed limit (status bits 10 / 11).
    ///
    /// # Errors
    /// Not enabled, a fault, a closed limit switch in that direction, no answer.
    pub fn move_to(
        &self,
        target: i64,
        speed: Option<i64>,
        acceleration: Option<i64>,
    ) -> Result<(), Nfv2Error> {
        self.check_running()?;
        self.with(|d| {
            let from = d.history.latest().map_or(0, |s| s.counts);
            self.check_motion(d, (target - from) as f64)?;
            let speed = speed.unwrap_or(d.config.speed);
            let acceleration = acceleration.unwrap_or(d.config.acceleration);
            if speed == 0 || acceleration <= 0 {
                return Err(Nfv2Error::InvalidArgument("speed and acceleration must be positive".into()));
            }
            let acceleration = d.rev.width(Reg::MaxAcceleration.code()).map(|_| acceleration);
            d.position(target, speed, acceleration);
            Ok(())
        })??;
        self.wait_confirmed("move (POSITION)", &[Reg::Mode, Reg::Position, Reg::Speed, Reg::MaxAcceleration])
    }

    /// Runs at `speed` units (signed) in SPEED mode until [`Drive::stop`].
    ///
    /// # Errors
    /// Not enabled, a fault, a closed limit switch in that direction, no answer.
    pub fn jog(&self, speed: i64, acceleration: Option<i64>) -> Result<(), Nfv2Error> {
        self.check_running()?;
        self.with(|d| {
            self.check_motion(d, speed as f64)?;
            let acceleration = acceleration.unwrap_or(d.config.acceleration);
            if acceleration <= 0 {
                return Err(Nfv2Error::InvalidArgument("acceleration must be positive".into()));
            }
            let acceleration = d.rev.width(Reg::MaxAcceleration.code()).map(|_| acceleration);
            d.jog(speed, acceleration);
            Ok(())
        })??;
        self.wait_confirmed("jog (SPEED)", &[Reg::Mode, Reg::Speed, Reg::MaxAcceleration])
    }

    /// Decelerates to rest with the drive's acceleration.
    ///
    /// # Errors
    /// No answer.
    pub fn stop(&self) -> Result<(), Nfv2Error> {
        self.check_running()?;
        self.with(|d| d.stop(None))?;
        self.wait_confirmed("stop", &[Reg::Mode, Reg::Position, Reg::Speed])
    }

    /// Decelerates to rest with the quick-stop acceleration.
    ///
    /// # Errors
    /// No answer.
    pub fn quick_stop(&self) -> Result<(), Nfv2Error> {
        self.check_running()?;
        self.with(|d| {
            let a = d.rev.width(Reg::MaxAcceleration.code()).map(|_| d.config.quick_stop_acceleration);
            d.stop(a);
        })?;
        self.wait_confirmed("quick stop", &[Reg::Mode, Reg::Position, Reg::Speed, Reg::MaxAcceleration])
    }

    /// Clears the host's fault latch and leaves ERROR, holding the present position. A
    /// drive on a limit switch may then only move away from it.
    ///
    /// # Errors
    /// [`Nfv2Error::Device`] if the ENABLE input is absent; no answer.
    pub fn fault_reset(&self) -> Result<(), Nfv2Error> {
        self.check_running()?;
        // The ENABLE input as it is now, not as last read.
        let before = self.with(|d| {
            d.request_inputs();
            d.inputs_read
        })?;
        let timeout = self.inner.config.confirm_timeout;
        let t0 = self.inner.clock.now();
        while self.with(|d| d.inputs_read)? == before {
            if self.inner.clock.elapsed(t0) > timeout {
                return Err(Nfv2Error::NotConfirmed {
                    address: self.address,
                    what: "a digital-input reading".into(),
                    waited: timeout,
                });
            }
            self.inner.clock.sleep(POLL);
        }
        self.with(|d| {
            d.fault_reset().map_err(|reason| Nfv2Error::Device { address: self.address, reason })
        })??;
        self.wait_confirmed("fault reset (mode POSITION)", &[Reg::Mode, Reg::Position])?;
        self.wait_out_of_error()
    }

    /// Sets limits the drive enforces itself.
    ///
    /// # Errors
    /// A limit the drive's revision cannot carry; no answer.
    pub fn set_limits(&self, limits: DeviceLimits) -> Result<(), Nfv2Error> {
        self.check_running()?;
        let values = [
            (Reg::MinPosition, limits.position.map(|p| p.0)),
            (Reg::MaxPosition, limits.position.map(|p| p.1)),
            (Reg::MaxSpeed, limits.max_speed),
            (Reg::MaxCurrent, limits.max_current_ma),
            (Reg::MaxAcceleration, limits.max_acceleration),
        ];
        self.with(|d| {
            for (r, v) in values {
                let Some(v) = v else { continue };
                let command = motus_nfv2_protocol::Command::values(r.code(), [v]);
                command.encoded_len(d.rev)?;
                d.regs.set(r, v);
            }
            Ok::<_, Nfv2Error>(())
        })??;
        let regs: Vec<Reg> = values.iter().filter(|(_, v)| v.is_some()).map(|(r, _)| *r).collect();
        self.wait_confirmed("limits", &regs)
    }

    /// Makes the drive follow `link`'s source (POS_INCREMENT, SPEED before 2014).
    pub(crate) fn follow(&self, link: StreamLink) -> Result<(), Nfv2Error> {
        self.check_running()?;
        self.with(|d| {
            self.check_motion(d, 0.0)?;
            d.stream(link);
            Ok::<_, Nfv2Error>(())
        })??;
        self.wait_confirmed("streaming (POS_INCREMENT)", &[Reg::Mode])
    }

    /// The position (counts) at host time `t`, interpolated from the sample history.
    ///
    /// # Errors
    /// [`WhereError`] outside the history.
    pub fn position_at(&self, t: Instant) -> Result<f64, WhereError> {
        self.with(|d| d.history.position_at(t)).unwrap_or(Err(WhereError::NoSamples))
    }

    /// The accepted position samples, oldest first.
    #[must_use]
    pub fn samples(&self) -> Vec<PositionSample> {
        self.with(|d| d.history.iter().copied().collect()).unwrap_or_default()
    }

    /// The speed commands sent while streaming, oldest first.
    #[must_use]
    pub fn stream_log(&self) -> Vec<StreamCommand> {
        self.with(|d| d.stream_log.iter().copied().collect()).unwrap_or_default()
    }
}
