//! The pan-tilt head: two 1209A drives (pan, tilt) on one RS-485 bus, served by one
//! [`Scheduler`], in degrees of the axes after the gear.
//!
//! - [`PanTilt::home`]: both axes home together (HOMING until "synchronized"), then the
//!   drives get the head's limits (position, speed, acceleration) and hold.
//! - [`PanTilt::goto`]: a synchronised move — one normalised trapezoid
//!   ([`motus_axis::profile::synchronised`]) scaled per axis, streamed every cycle, so
//!   both axes arrive together within their own limits; at the end the drives hold the
//!   exact target in POSITION mode.
//! - [`PanTilt::track`] / [`PanTilt::track_live`]: a second-order limiter per axis
//!   ([`filter`]) follows a stream of timestamped targets with a set-point whose speed and
//!   acceleration stay within the limits; targets beyond the soft limits are clamped.
//! - [`PanTilt::where_at`]: pan and tilt at a host instant from the sample histories (a
//!   camera frame's exposure time).
//!
//! Streaming is explained in [`crate::stream`]: POS_INCREMENT mode, a speed per cycle with
//! the drive's own speed limit and acceleration set to the head's, so the drives bound
//! their references even if a request is corrupted on the line.

pub mod filter;
pub mod sources;
pub mod targets;

use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use motus_axis::profile::synchronised;
use motus_serial::BusConfig;

use crate::bus::Nfv2Bus;
use crate::drive::{DeviceLimits, Drive, DriveConfig};
use crate::error::Nfv2Error;
use crate::samples::WhereError;
use crate::scheduler::{Scheduler, SchedulerConfig};
use crate::stream::{SharedSource, StreamLink, COUNTS_PER_S_PER_SPEED_UNIT};
use filter::Limits;
use sources::{GotoSource, SetpointRecord, TrackSetup, TrackSource};
use targets::TargetPoint;

/// One axis of the head.
#[derive(Debug, Clone, PartialEq)]
pub struct HeadAxis {
    /// Bus address of its 1209A.
    pub address: u8,
    /// Encoder counts per axis revolution (2000 x 100:1 = 200 000).
    pub counts_per_rev: f64,
    /// Soft limits after homing, degrees (also set in the drive).
    pub limits_deg: (f64, f64),
    /// Speed limit, deg/s (goto and tracking; also the drive's speed limit).
    pub velocity_deg_s: f64,
    /// Acceleration limit, deg/s² (also the drive's acceleration).
    pub acceleration_deg_s2: f64,
}

impl HeadAxis {
    /// Counts per degree.
    #[must_use]
    pub fn counts_per_deg(&self) -> f64 {
        self.counts_per_rev / 360.0
    }

    fn limits(&self) -> Limits {
        Limits { velocity: self.velocity_deg_s, acceleration: self.acceleration_deg_s2 }
    }

    /// The speed limit in NFv2 speed units (rounded down, so never above the limit).
    fn max_units(&self) -> i64 {
        (self.velocity_deg_s * self.counts_per_deg().abs() / COUNTS_PER_S_PER_SPEED_UNIT).floor() as i64
    }

    /// The acceleration limit in counts/s² (rounded down).
    fn acceleration_counts(&self) -> i64 {
        (self.acceleration_deg_s2 * self.counts_per_deg().abs()).floor() as i64
    }

    fn device_limits(&self) -> DeviceLimits {
        let k = self.counts_per_deg();
        let (a, b) = ((self.limits_deg.0 * k).round() as i64, (self.limits_deg.1 * k).round() as i64);
        DeviceLimits {
            position: Some((a.min(b), a.max(b))),
            max_speed: Some(self.max_units()),
            max_current_ma: None,
            max_acceleration: Some(self.acceleration_counts()),
        }
    }
}

/// Settings of the head.
#[derive(Debug, Clone, PartialEq)]
pub struct PanTiltConfig {
    /// The pan axis (default address 1, ±60 deg).
    pub pan: HeadAxis,
    /// The tilt axis (default address 2, ±45 deg).
    pub tilt: HeadAxis,
    /// The bus scheduler.
    pub scheduler: SchedulerConfig,
    /// Longest homing.
    pub home_timeout: Duration,
}

impl Default for PanTiltConfig {
    fn default() -> Self {
        let axis = |address, limits_deg| HeadAxis {
            address,
            counts_per_rev: crate::axis::DEFAULT_COUNTS_PER_REV,
            limits_deg,
            velocity_deg_s: 30.0,
            acceleration_deg_s2: 120.0,
        };
        PanTiltConfig {
            pan: axis(1, (-60.0, 60.0)),
            tilt: axis(2, (-45.0, 45.0)),
            scheduler: SchedulerConfig::default(),
            home_timeout: Duration::from_secs(30),
        }
    }
}

/// A refused or failed head operation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PanTiltError {
    /// The line or the scheduler could not be started.
    #[error(transparent)]
    Bus(Nfv2Error),
    /// A drive operation failed.
    #[error("{axis}: {source}")]
    Drive {
        /// "pan" or "tilt".
        axis: &'static str,
        /// Why.
        source: Nfv2Error,
    },
    /// A target beyond the soft limits.
    #[error("{axis}: target {target_deg:.3} deg is beyond the limits {min} .. {max} deg")]
    BeyondLimit {
        /// "pan" or "tilt".
        axis: &'static str,
        /// Requested target.
        target_deg: f64,
        /// Lower limit.
        min: f64,
        /// Upper limit.
        max: f64,
    },
    /// Motion before homing.
    #[error("{axis} is not homed: run `home` first")]
    NotHomed {
        /// "pan" or "tilt".
        axis: &'static str,
    },
    /// "Where at t" outside the history.
    #[error("{axis}: {source}")]
    Where {
        /// "pan" or "tilt".
        axis: &'static str,
        /// Why.
        source: WhereError,
    },
    /// A bad argument (not a number, no target points).
    #[error("{0}")]
    InvalidArgument(String),
}

fn drive_err(axis: &'static str) -> impl Fn(Nfv2Error) -> PanTiltError {
    move |source| PanTiltError::Drive { axis, source }
}

/// A live target feed started by [`PanTilt::track_live`].
#[derive(Clone)]
pub struct TrackFeed {
    source: Arc<Mutex<TrackSource>>,
    origin: Instant,
}

impl TrackFeed {
    /// Adds a target; `t` is seconds from the feed's start ([`TrackFeed::origin`]).
    pub fn push(&self, point: TargetPoint) {
        self.source.lock().unwrap_or_else(PoisonError::into_inner).push(point);
    }

    /// Adds a target for host time `at`.
    pub fn push_at(&self, at: Instant, pan_deg: f64, tilt_deg: f64) {
        let t = at.saturating_duration_since(self.origin).as_secs_f64();
        self.push(TargetPoint { t, pan_deg, tilt_deg });
    }

    /// The host instant of `t = 0`.
    #[must_use]
    pub fn origin(&self) -> Instant {
        self.origin
    }

    /// Ends the feed: the head settles on the last target and holds it.
    pub fn close(&self) {
        self.source.lock().unwrap_or_else(PoisonError::into_inner).close();
    }
}

/// The pan-tilt head.
pub struct PanTilt {
    scheduler: Arc<Scheduler>,
    pan: Drive,
    tilt: Drive,
    config: PanTiltConfig,
    track: Mutex<Option<Arc<Mutex<TrackSource>>>>,
}

impl PanTilt {
    /// Opens the port at `path` and starts the head's scheduler.
    ///
    /// # Errors
    /// Opening the port, starting the scheduler.
    pub fn open(path: &str, baud: u32, bus: BusConfig, config: PanTiltConfig) -> Result<Self, PanTiltError> {
        let bus = Nfv2Bus::open(path, baud, bus).map_err(PanTiltError::Bus)?;
        Self::start(bus, config)
    }

    /// Starts the head's scheduler on `bus`. The head's waits and time-lines are on the
    /// clock of the bus master ([`Scheduler::start`]), virtual time with a master made by
    /// `motus_serial::BusMaster::with_clock`.
    ///
    /// # Errors
    /// Starting the scheduler (e.g. both axes at one address).
    pub fn start(bus: Nfv2Bus, config: PanTiltConfig) -> Result<Self, PanTiltError> {
        let drives = vec![DriveConfig::new(config.pan.address), DriveConfig::new(config.tilt.address)];
        let scheduler =
            Arc::new(Scheduler::start(bus, drives, config.scheduler.clone()).map_err(PanTiltError::Bus)?);
        let pan = scheduler.drive(config.pan.address).map_err(drive_err("pan"))?;
        let tilt = scheduler.drive(config.tilt.address).map_err(drive_err("tilt"))?;
        Ok(PanTilt { scheduler, pan, tilt, config, track: Mutex::new(None) })
    }

    /// The scheduler (plan, statistics).
    #[must_use]
    pub fn scheduler(&self) -> &Arc<Scheduler> {
        &self.scheduler
    }

    /// The pan drive.
    #[must_use]
    pub fn pan(&self) -> &Drive {
        &self.pan
    }

    /// The tilt drive.
    #[must_use]
    pub fn tilt(&self) -> &Drive {
        &self.tilt
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &PanTiltConfig {
        &self.config
    }

    fn axes(&self) -> [(&'static str, &Drive, &HeadAxis); 2] {
        [("pan", &self.pan, &self.config.pan), ("tilt", &self.tilt, &self.config.tilt)]
    }

    /// Homes both axes together, then sets the head's limits in the drives and holds.
    ///
    /// # Errors
    /// A fault, no answer, or homing not done within the configured time.
    pub fn home(&self) -> Result<(), PanTiltError> {
        self.stop_tracking();
        for (name, drive, _) in self.axes() {
            drive.home().map_err(drive_err(name))?;
        }
        for (name, drive, _) in self.axes() {
            drive.wait_homed(self.config.home_timeout).map_err(drive_err(name))?;
        }
        for (name, drive, axis) in self.axes() {
            drive.set_limits(axis.device_limits()).map_err(drive_err(name))?;
        }
        Ok(())
    }

    /// Pan and tilt now (newest samples), degrees.
    ///
    /// # Errors
    /// No sample yet.
    pub fn position(&self) -> Result<(f64, f64), PanTiltError> {
        let mut out = [0.0; 2];
        for ((name, drive, axis), slot) in self.axes().into_iter().zip(out.iter_mut()) {
            let s = drive
                .snapshot()
                .position
                .ok_or(PanTiltError::Where { axis: name, source: WhereError::NoSamples })?;
            *slot = s.counts as f64 / axis.counts_per_deg();
        }
        Ok((out[0], out[1]))
    }

    /// Pan and tilt (degrees) at host time `t`, interpolated from the sample histories
    /// (see [`crate::samples`] for the timestamp of a sample).
    ///
    /// # Errors
    /// [`PanTiltError::Where`] outside either history.
    pub fn where_at(&self, t: Instant) -> Result<(f64, f64), PanTiltError> {
        let mut out = [0.0; 2];
        for ((name, drive, axis), slot) in self.axes().into_iter().zip(out.iter_mut()) {
            let counts = drive.position_at(t).map_err(|source| PanTiltError::Where { axis: name, source })?;
            *slot = counts / axis.counts_per_deg();
        }
        Ok((out[0], out[1]))
    }

    /// Checks a motion may start and returns the present positions, degrees.
    fn ready(&self, targets: Option<[f64; 2]>) -> Result<[f64; 2], PanTiltError> {
        let mut from = [0.0; 2];
        for (i, ((name, drive, axis), slot)) in self.axes().into_iter().zip(from.iter_mut()).enumerate() {
            if let Some(t) = targets.and_then(|t| t.get(i).copied()) {
                let (min, max) = axis.limits_deg;
                if !t.is_finite() {
                    return Err(PanTiltError::InvalidArgument(format!("{name} target {t} is not a number")));
                }
                if !(min..=max).contains(&t) {
                    return Err(PanTiltError::BeyondLimit { axis: name, target_deg: t, min, max });
                }
            }
            let s = drive.snapshot();
            if let Some(f) = s.faults.first() {
                let source = Nfv2Error::Device { address: axis.address, reason: f.reason.clone() };
                return Err(PanTiltError::Drive { axis: name, source });
            }
            if !s.homed {
                return Err(PanTiltError::NotHomed { axis: name });
            }
            let p = s.position.ok_or(PanTiltError::Where { axis: name, source: WhereError::NoSamples })?;
            *slot = p.counts as f64 / axis.counts_per_deg();
        }
        Ok(from)
    }

    /// Starts streaming `source` to both drives, `t = 0` one cycle from now.
    fn follow(&self, source: SharedSource) -> Result<(), PanTiltError> {
        let gain = self.config.scheduler.stream_gain;
        let links = [
            StreamLink { source: source.clone(), index: 0, max_units: self.config.pan.max_units(), gain },
            StreamLink { source, index: 1, max_units: self.config.tilt.max_units(), gain },
        ];
        for ((name, drive, _), link) in self.axes().into_iter().zip(links) {
            drive.follow(link).map_err(drive_err(name))?;
        }
        Ok(())
    }

    /// Moves both axes to (`pan_deg`, `tilt_deg`) so that they arrive together; returns
    /// the planned duration. Use [`PanTilt::wait_idle`] to wait for the arrival.
    ///
    /// # Errors
    /// A target beyond the limits, not homed, a fault, no answer.
    pub fn goto(&self, pan_deg: f64, tilt_deg: f64) -> Result<Duration, PanTiltError> {
        self.stop_tracking();
        let to = [pan_deg, tilt_deg];
        let from = self.ready(Some(to))?;
        let (p, t) = (&self.config.pan, &self.config.tilt);
        let limits = [
            (to[0] - from[0], p.velocity_deg_s, p.acceleration_deg_s2),
            (to[1] - from[1], t.velocity_deg_s, t.acceleration_deg_s2),
        ];
        let Some(plan) = synchronised(&limits) else {
            return Ok(Duration::ZERO); // nothing moves
        };
        let duration = Duration::from_secs_f64(plan.duration());
        let start = self.scheduler.clock().now() + self.scheduler.plan().effective_cycle();
        let counts = [p.counts_per_deg(), t.counts_per_deg()];
        let source: SharedSource = Arc::new(Mutex::new(GotoSource::new(start, plan, from, to, counts)));
        self.follow(source)?;
        Ok(duration)
    }

    /// Follows `points` (`t` in seconds from one cycle from now) and settles on the last
    /// one; returns the feed (for [`TrackFeed::origin`]).
    ///
    /// # Errors
    /// No point, not homed, a fault, no answer.
    pub fn track(&self, points: Vec<TargetPoint>) -> Result<TrackFeed, PanTiltError> {
        if points.is_empty() {
            return Err(PanTiltError::InvalidArgument("no target point to track".into()));
        }
        self.start_track(points, false)
    }

    /// Starts following a live feed: push targets with [`TrackFeed::push`] as they come;
    /// between and just after them the target is interpolated and extrapolated (0.1 s).
    ///
    /// # Errors
    /// Not homed, a fault, no answer.
    pub fn track_live(&self) -> Result<TrackFeed, PanTiltError> {
        self.start_track(Vec::new(), true)
    }

    fn start_track(&self, points: Vec<TargetPoint>, live: bool) -> Result<TrackFeed, PanTiltError> {
        self.stop_tracking();
        let from = self.ready(None)?;
        let (p, t) = (&self.config.pan, &self.config.tilt);
        let origin = self.scheduler.clock().now() + self.scheduler.plan().effective_cycle();
        let setup = TrackSetup {
            origin,
            dt: self.scheduler.plan().effective_cycle().as_secs_f64(),
            start_deg: from,
            limits: [p.limits(), t.limits()],
            soft: [p.limits_deg, t.limits_deg],
            counts_per_deg: [p.counts_per_deg(), t.counts_per_deg()],
            live,
        };
        let source = Arc::new(Mutex::new(TrackSource::new(setup, points)));
        *self.track.lock().unwrap_or_else(PoisonError::into_inner) = Some(source.clone());
        let shared: SharedSource = source.clone();
        self.follow(shared)?;
        Ok(TrackFeed { source, origin })
    }

    fn stop_tracking(&self) {
        let current = self.track.lock().unwrap_or_else(PoisonError::into_inner).take();
        if let Some(source) = current {
            source.lock().unwrap_or_else(PoisonError::into_inner).close();
        }
    }

    /// The tracking filters' set-points of the current or last track, one per cycle.
    #[must_use]
    pub fn setpoint_log(&self) -> Vec<SetpointRecord> {
        let current = self.track.lock().unwrap_or_else(PoisonError::into_inner).clone();
        current.map(|s| s.lock().unwrap_or_else(PoisonError::into_inner).log()).unwrap_or_default()
    }

    /// Waits until both axes are at rest on their targets (a goto or a finite track
    /// done); returns the positions, degrees.
    ///
    /// # Errors
    /// A fault, or not done within `timeout`.
    pub fn wait_idle(&self, timeout: Duration) -> Result<(f64, f64), PanTiltError> {
        let clock = self.scheduler.clock();
        let t0 = clock.now();
        for (name, drive, _) in self.axes() {
            let left = timeout.saturating_sub(clock.elapsed(t0));
            drive.wait_idle(left).map_err(drive_err(name))?;
        }
        self.position()
    }

    /// Stops both axes (decelerating with the drives' acceleration) and holds.
    ///
    /// # Errors
    /// No answer.
    pub fn stop(&self) -> Result<(), PanTiltError> {
        self.stop_tracking();
        for (name, drive, _) in self.axes() {
            drive.stop().map_err(drive_err(name))?;
        }
        Ok(())
    }

    /// Clears the faults of both axes (leaving ERROR, holding); refused while an ENABLE
    /// input is absent.
    ///
    /// # Errors
    /// The drive's refusal, no answer.
    pub fn fault_reset(&self) -> Result<(), PanTiltError> {
        self.stop_tracking();
        for (name, drive, _) in self.axes() {
            let s = drive.snapshot();
            if !s.faults.is_empty() || !s.enabled {
                drive.fault_reset().map_err(drive_err(name))?;
            }
        }
        Ok(())
    }

    /// Stops the scheduler (the drives hold their last set-points).
    pub fn shutdown(&self) {
        self.scheduler.shutdown();
    }
}
