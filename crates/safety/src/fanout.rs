//! Quick-stop fan-out: turns the supervisor's decisions into actions on every drive, whatever
//! its protocol.
//!
//! A [`StopTarget`] is anything that can quick-stop drives: an axis of the axis model
//! ([`AxisStop`] sends [`motus_axis::AxisCommand::QuickStop`], which each driver maps to its
//! protocol: the CiA 402 controlword, the serial devices' stop command...), or a field-bus
//! broadcast (the POWERLINK safety lease). [`Fanout::apply`] is called with every new
//! [`Decision`]:
//! * when SafeToRun falls (or the first decision is unsafe), every target gets
//!   [`StopTarget::quick_stop`], at once and in order; a failing target does not keep the
//!   others from stopping, its error is reported;
//! * while SafeToRun holds, every target gets [`StopTarget::renew`] with the lease, so drives
//!   that keep their own watchdog stop by themselves when the renewals stop coming;
//! * [`Fanout::check_expiry`], called between decisions, stops every target when the last
//!   lease has expired without a newer decision (the evaluation stalled);
//! * after a stop, [`Restart::Manual`] (the default) holds the drives stopped even when the
//!   decisions are safe again, until [`Fanout::reset`] (an operator's deliberate action):
//!   a machine must not start by itself because the condition that stopped it went away.
//!   [`Restart::Automatic`] resumes with the next safe decision (test rigs).
//!
//! Pure logic: time is passed in; the targets do the IO.

use crate::supervisor::{Decision, Lease};
use motus_axis::{Axis, AxisCommand};
use std::time::Duration;
use thiserror::Error;

/// A target refused or failed a stop or renewal.
#[derive(Debug, Error)]
#[error("{target}: {message}")]
pub struct StopError {
    /// Target name.
    pub target: String,
    /// What went wrong.
    pub message: String,
}

/// Something that can quick-stop one or more drives.
pub trait StopTarget: Send {
    /// Name for diagnostics.
    fn name(&self) -> String;
    /// Stops now, as fast as the drives allow.
    fn quick_stop(&mut self) -> Result<(), StopError>;
    /// Permission to run until `lease` expires. Default: nothing to do (the host-side
    /// [`Fanout::check_expiry`] still stops the target when renewals stop).
    fn renew(&mut self, lease: &Lease) -> Result<(), StopError> {
        let _ = lease;
        Ok(())
    }
}

/// An axis of the axis model as a stop target.
pub struct AxisStop<A: Axis>(pub A);

impl<A: Axis> StopTarget for AxisStop<A> {
    fn name(&self) -> String {
        self.0.name().to_owned()
    }
    fn quick_stop(&mut self) -> Result<(), StopError> {
        self.0
            .execute(&AxisCommand::QuickStop)
            .map_err(|e| StopError { target: self.0.name().to_owned(), message: e.to_string() })
    }
}

/// What [`Fanout::apply`] or [`Fanout::check_expiry`] did.
#[derive(Debug, Default)]
pub struct FanoutReport {
    /// Every target was told to stop now.
    pub stopped: bool,
    /// Targets renewed.
    pub renewed: usize,
    /// Targets that failed (they may not have stopped: alarm).
    pub errors: Vec<StopError>,
}

/// What happens after a stop when the decisions become safe again.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Restart {
    /// Stay stopped until [`Fanout::reset`].
    #[default]
    Manual,
    /// Resume with the next safe decision.
    Automatic,
}

/// Applies decisions to every target (see the module documentation).
pub struct Fanout {
    targets: Vec<Box<dyn StopTarget>>,
    running: bool,
    lease: Option<Lease>,
    stops: u64,
    restart: Restart,
    held: bool,
}

impl Fanout {
    /// A fan-out over `targets`; starts in the stopped state (nothing may run before the first
    /// safe decision).
    pub fn new(targets: Vec<Box<dyn StopTarget>>) -> Self {
        Self { targets, running: false, lease: None, stops: 0, restart: Restart::Manual, held: false }
    }

    /// Sets the restart behaviour after a stop.
    pub fn with_restart(mut self, restart: Restart) -> Self {
        self.restart = restart;
        self
    }

    /// True when stopped and waiting for [`Fanout::reset`].
    pub fn held(&self) -> bool {
        self.held
    }

    /// The operator's reset after a stop: the next safe decision lets the drives run again.
    pub fn reset(&mut self) {
        if self.held {
            tracing::info!("safety stop reset by the operator");
        }
        self.held = false;
    }

    /// Target names.
    pub fn names(&self) -> Vec<String> {
        self.targets.iter().map(|t| t.name()).collect()
    }

    /// True while the last decision allowed running and its lease has not expired.
    pub fn running(&self) -> bool {
        self.running
    }

    /// How many times the targets were stopped.
    pub fn stops(&self) -> u64 {
        self.stops
    }

    /// Applies a new decision.
    pub fn apply(&mut self, decision: &Decision) -> FanoutReport {
        match decision.lease() {
            Some(_) if self.held => FanoutReport::default(),
            Some(lease) => {
                self.running = true;
                self.lease = Some(lease);
                let mut report = FanoutReport::default();
                for t in &mut self.targets {
                    match t.renew(&lease) {
                        Ok(()) => report.renewed += 1,
                        Err(e) => report.errors.push(e),
                    }
                }
                report
            }
            None => self.stop_if_running(true),
        }
    }

    /// Stops every target if the last lease has expired at `now` (no newer decision came).
    pub fn check_expiry(&mut self, now: Duration) -> FanoutReport {
        match self.lease {
            Some(l) if self.running && !l.is_valid(now) => {
                tracing::warn!("SafeToRun lease expired without renewal: quick stop");
                self.stop_if_running(false)
            }
            _ => FanoutReport::default(),
        }
    }

    /// Stops every target now (an operator's emergency stop); the next safe decision
    /// releases them again.
    pub fn stop_all(&mut self) -> FanoutReport {
        self.running = true;
        self.stop_if_running(false)
    }

    fn stop_if_running(&mut self, first_time_too: bool) -> FanoutReport {
        // The very first unsafe decision also stops (drives may be moving from before).
        let must = self.running || (first_time_too && self.stops == 0 && self.lease.is_none());
        // Only a stop of drives that were allowed to run latches (start-up does not).
        let was_running = self.running;
        self.running = false;
        self.lease = None;
        let mut report = FanoutReport::default();
        if !must {
            return report;
        }
        self.stops += 1;
        report.stopped = true;
        self.held = was_running && self.restart == Restart::Manual;
        for t in &mut self.targets {
            if let Err(e) = t.quick_stop() {
                tracing::error!(target = %e.target, "quick stop failed: {}", e.message);
                report.errors.push(e);
            }
        }
        report
    }
}
