//! Jogs are leases (a dead-man): the web API documents "a jog stops unless repeated within
//! 0.5 s", and the station keeps that promise on every device family, through the `Axis`
//! trait only.
//!
//! [`JogLeases`] is the pure bookkeeping (time is an argument, so it is tested on virtual
//! time): a jog request opens or renews the lease of its axis; a repeated jog with the same
//! parameters only renews it (the drive is not commanded again, unless the axis stopped
//! meanwhile); any other jog (other direction, other speed) replaces it and is commanded; a
//! move, home, stop, E-stop or the end of a slot ends it. The station's watchdog thread
//! (every [`WATCHDOG_PERIOD`]) sends a controlled `AxisCommand::Stop` to an axis whose lease
//! was not renewed within [`JOG_LEASE`].
//!
//! Ordering: the backend decides and commands a jog while it holds the axis's lock, and the
//! watchdog re-checks a lease under the same lock before it stops the axis, so a renewal that
//! arrives while the watchdog is about to stop the axis either prevents the stop or is
//! commanded again after it. The lease table's own lock is never held while waiting for an
//! axis.

use std::collections::HashMap;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use motus_axis::AxisCommand;

use crate::{lock, Shared};

/// A jog stops unless it is renewed within this time.
pub const JOG_LEASE: Duration = Duration::from_millis(500);

/// Period of the watchdog that stops expired jogs.
pub const WATCHDOG_PERIOD: Duration = Duration::from_millis(20);

/// A renewal re-commands the drive when the axis is seen standing still this long after the
/// jog was commanded (it stopped meanwhile: a fault, a limit, a device that restarted); less
/// than this, the poller's view may simply not show the motion yet.
pub const RESTART_GRACE: Duration = Duration::from_millis(400);

/// A failed stop of an expired jog is retried this many times (one per watchdog period)
/// before the watchdog gives up on it (and says so in the log).
pub const STOP_ATTEMPTS: u32 = 25;

/// What one jog asks of the drive; two requests with equal specs are the same jog.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JogSpec {
    /// +1 or -1.
    pub direction: f64,
    /// Speed (SI).
    pub speed: f64,
    /// Acceleration (SI).
    pub acceleration: f64,
    /// The position the jog moves toward (a limit), `None` for the device's native jog.
    pub target: Option<f64>,
}

/// One axis's lease.
#[derive(Debug, Clone, PartialEq)]
pub struct Lease {
    /// The jog.
    pub spec: JogSpec,
    /// Who renewed it last.
    pub user: String,
    /// When the drive was last commanded.
    pub commanded: Instant,
    /// False when the last command failed (the next request commands again).
    pub command_ok: bool,
    /// When it was last renewed.
    pub renewed: Instant,
    /// Failed attempts to stop it after it expired.
    pub stop_attempts: u32,
}

/// What the backend must do with a jog request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JogDecision {
    /// Command the drive (a new jog, a changed jog, or one whose axis stopped meanwhile).
    Command,
    /// The lease was renewed; the drive keeps its running command.
    Renewed,
}

/// The jog leases of every axis (see the module documentation).
#[derive(Debug, Default)]
pub struct JogLeases {
    leases: HashMap<String, Lease>,
}

impl JogLeases {
    /// A jog request of `user` for `axis` at `now`; `moving`: the axis was last seen moving.
    /// Opens, renews or replaces the lease.
    pub fn request(
        &mut self,
        axis: &str,
        spec: JogSpec,
        user: &str,
        moving: bool,
        now: Instant,
    ) -> JogDecision {
        if let Some(l) = self.leases.get_mut(axis) {
            let alive = now.saturating_duration_since(l.renewed) <= JOG_LEASE;
            let stopped = !moving && now.saturating_duration_since(l.commanded) >= RESTART_GRACE;
            if alive && l.spec == spec && l.command_ok && !stopped {
                l.renewed = now;
                user.clone_into(&mut l.user);
                return JogDecision::Renewed;
            }
        }
        let lease = Lease {
            spec,
            user: user.to_owned(),
            commanded: now,
            command_ok: true,
            renewed: now,
            stop_attempts: 0,
        };
        self.leases.insert(axis.to_owned(), lease);
        JogDecision::Command
    }

    /// The command of the jog just decided failed: keep the lease (the axis may still run an
    /// earlier jog, which the watchdog then stops) and command again on the next request.
    pub fn command_failed(&mut self, axis: &str) {
        if let Some(l) = self.leases.get_mut(axis) {
            l.command_ok = false;
        }
    }

    /// Ends the lease of `axis` (a move, home or stop replaced the jog); true if there was one.
    pub fn end(&mut self, axis: &str) -> bool {
        self.leases.remove(axis).is_some()
    }

    /// Ends every lease (E-stop, end of a slot).
    pub fn end_all(&mut self) {
        self.leases.clear();
    }

    /// The lease of `axis`, if any.
    #[must_use]
    pub fn get(&self, axis: &str) -> Option<&Lease> {
        self.leases.get(axis)
    }

    /// The axes whose lease has expired at `now` (the watchdog stops them).
    #[must_use]
    pub fn expired(&self, now: Instant) -> Vec<String> {
        let mut v: Vec<String> = self
            .leases
            .iter()
            .filter(|(_, l)| now.saturating_duration_since(l.renewed) > JOG_LEASE)
            .map(|(a, _)| a.clone())
            .collect();
        v.sort();
        v
    }

    /// Takes the lease of `axis` out if it has still expired at `now` (the watchdog, under
    /// the axis's lock, right before it stops the axis).
    pub fn take_expired(&mut self, axis: &str, now: Instant) -> Option<Lease> {
        let l = self.leases.get(axis)?;
        if now.saturating_duration_since(l.renewed) > JOG_LEASE {
            self.leases.remove(axis)
        } else {
            None
        }
    }

    /// The stop of an expired lease failed: puts it back for another attempt unless it has
    /// had [`STOP_ATTEMPTS`]; true if it will be retried.
    pub fn stop_failed(&mut self, axis: &str, mut lease: Lease) -> bool {
        lease.stop_attempts += 1;
        if lease.stop_attempts >= STOP_ATTEMPTS || self.leases.contains_key(axis) {
            return false;
        }
        self.leases.insert(axis.to_owned(), lease);
        true
    }

    /// Number of open leases.
    #[must_use]
    pub fn len(&self) -> usize {
        self.leases.len()
    }

    /// True when no jog is leased.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.leases.is_empty()
    }
}

/// The watchdog thread's loop: every [`WATCHDOG_PERIOD`], a controlled stop for every axis
/// whose jog lease expired, until the station stops.
pub(crate) fn run_watchdog(s: &Shared) {
    let mut next = Instant::now();
    while !s.stop.load(Ordering::Relaxed) {
        let due = lock(&s.jogs).expired(Instant::now());
        for id in due {
            let Some(entry) = s.axes.iter().find(|a| a.view.id == id) else {
                lock(&s.jogs).end(&id);
                continue;
            };
            let mut axis = lock(&entry.axis);
            // Re-checked under the axis's lock: a renewal may have come in meanwhile.
            let Some(lease) = lock(&s.jogs).take_expired(&id, Instant::now()) else { continue };
            let late = lease.renewed.elapsed();
            match axis.execute(&AxisCommand::Stop) {
                Ok(()) => {
                    tracing::info!(axis = %id, user = %lease.user, ?late, "jog not renewed: stopped (dead-man)");
                }
                Err(e) => {
                    let attempt = lease.stop_attempts + 1;
                    if lock(&s.jogs).stop_failed(&id, lease) {
                        if attempt == 1 {
                            tracing::warn!(axis = %id, "jog not renewed, stop failed (retrying): {e}");
                        }
                    } else {
                        tracing::error!(axis = %id, attempt, "jog not renewed and the stop failed: {e}");
                    }
                }
            }
        }
        next += WATCHDOG_PERIOD;
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        } else {
            next = now;
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    fn spec(direction: f64) -> JogSpec {
        JogSpec { direction, speed: 0.5, acceleration: 2.0, target: Some(direction) }
    }

    fn ms(t0: Instant, ms: u64) -> Instant {
        t0 + Duration::from_millis(ms)
    }

    #[test]
    fn a_jog_not_renewed_expires_after_the_lease() {
        let t0 = Instant::now();
        let mut j = JogLeases::default();
        assert_eq!(j.request("tilt", spec(1.0), "s", false, t0), JogDecision::Command);
        assert!(j.expired(ms(t0, 500)).is_empty());
        assert_eq!(j.expired(ms(t0, 501)), vec!["tilt".to_owned()]);
        // Taken out once, by the watchdog.
        assert!(j.take_expired("tilt", ms(t0, 499)).is_none());
        let l = j.take_expired("tilt", ms(t0, 520)).unwrap();
        assert_eq!(l.user, "s");
        assert!(j.is_empty());
        assert!(j.take_expired("tilt", ms(t0, 540)).is_none());
    }

    #[test]
    fn renewals_keep_the_lease_without_commanding_again() {
        let t0 = Instant::now();
        let mut j = JogLeases::default();
        assert_eq!(j.request("pan", spec(1.0), "s", false, t0), JogDecision::Command);
        // Renewed every 200 ms for 3 s (the view shows the motion after the first poll).
        for k in 1..=15 {
            let now = ms(t0, 200 * k);
            assert!(j.expired(now).is_empty(), "at {k}");
            assert_eq!(j.request("pan", spec(1.0), "s", true, now), JogDecision::Renewed, "at {k}");
        }
        assert!(j.expired(ms(t0, 3400)).is_empty());
        assert_eq!(j.expired(ms(t0, 3501)), vec!["pan".to_owned()]);
        // A renewal that arrives before the watchdog took the expired lease is a new jog.
        assert_eq!(j.request("pan", spec(1.0), "s", true, ms(t0, 3600)), JogDecision::Command);
        assert_eq!(j.len(), 1);
    }

    #[test]
    fn an_axis_seen_standing_still_is_commanded_again_after_the_grace() {
        let t0 = Instant::now();
        let mut j = JogLeases::default();
        j.request("x", spec(1.0), "s", false, t0);
        // Not moving yet, within the grace: the poller may not have seen the motion.
        assert_eq!(j.request("x", spec(1.0), "s", false, ms(t0, 200)), JogDecision::Renewed);
        // Still standing still after the grace: it stopped meanwhile.
        assert_eq!(j.request("x", spec(1.0), "s", false, ms(t0, 400)), JogDecision::Command);
        assert_eq!(j.get("x").unwrap().commanded, ms(t0, 400));
        assert_eq!(j.request("x", spec(1.0), "s", true, ms(t0, 600)), JogDecision::Renewed);
    }

    #[test]
    fn another_direction_or_speed_replaces_the_jog_and_a_failure_commands_again() {
        let t0 = Instant::now();
        let mut j = JogLeases::default();
        j.request("x", spec(1.0), "a", true, t0);
        assert_eq!(j.request("x", spec(-1.0), "a", true, ms(t0, 100)), JogDecision::Command);
        assert_eq!(j.get("x").unwrap().spec.direction, -1.0);
        let faster = JogSpec { speed: 1.0, ..spec(-1.0) };
        assert_eq!(j.request("x", faster, "a", true, ms(t0, 200)), JogDecision::Command);
        j.command_failed("x");
        // The lease stays (the watchdog stops whatever runs) and the next request commands.
        assert_eq!(j.expired(ms(t0, 701)), vec!["x".to_owned()]);
        assert_eq!(j.request("x", faster, "a", true, ms(t0, 300)), JogDecision::Command);
        assert_eq!(j.request("x", faster, "a", true, ms(t0, 400)), JogDecision::Renewed);
    }

    #[test]
    fn moves_stops_and_estops_end_leases() {
        let t0 = Instant::now();
        let mut j = JogLeases::default();
        j.request("a", spec(1.0), "s", true, t0);
        j.request("b", spec(1.0), "s", true, t0);
        assert!(j.end("a"));
        assert!(!j.end("a"));
        assert_eq!(j.expired(ms(t0, 600)), vec!["b".to_owned()]);
        j.end_all();
        assert!(j.expired(ms(t0, 600)).is_empty());
        assert_eq!(j.request("a", spec(1.0), "s", true, ms(t0, 700)), JogDecision::Command);
    }

    #[test]
    fn a_failed_stop_is_retried_a_bounded_number_of_times() {
        let t0 = Instant::now();
        let mut j = JogLeases::default();
        j.request("a", spec(1.0), "s", true, t0);
        let mut now = ms(t0, 520);
        let mut attempts = 0;
        while let Some(l) = j.take_expired("a", now) {
            attempts += 1;
            if !j.stop_failed("a", l) {
                break;
            }
            now += WATCHDOG_PERIOD;
        }
        assert_eq!(attempts, STOP_ATTEMPTS);
        assert!(j.is_empty());
        // A new jog meanwhile is not overwritten by the retry.
        j.request("b", spec(1.0), "s", true, t0);
        let l = j.take_expired("b", ms(t0, 520)).unwrap();
        j.request("b", spec(-1.0), "s", true, ms(t0, 530));
        assert!(!j.stop_failed("b", l));
        assert_eq!(j.get("b").unwrap().spec.direction, -1.0);
    }
}
