//! Streaming a host trajectory to 1209A drives, one speed set-point per cycle.
//!
//! The 1209A's POSITION mode plans its own trapezoid to rest at each new target, so a
//! target streamed every cycle makes it brake and restart ("chase"), with a lag of
//! `v² / 2a`. The driver therefore streams in **POS_INCREMENT** mode (SPEED before the
//! 2014 revision): the drive ramps its speed reference at its maximum acceleration and
//! integrates it into the position reference of its own 1 kHz position loop.
//!
//! The drive ramps its speed reference towards each command at its acceleration `a` (set
//! to the axis limit, i.e. at least the set-point's acceleration). The host knows where
//! that ramp starts (its previous command, `v0`), so it sends, each cycle, the speed whose
//! ramp covers exactly the set-point's displacement over the coming cycle, plus a position
//! correction:
//!
//! ```text
//! t0 = send time + delivery (wire time of the request + half a regulator period)
//! D  = p(t0 + T) - p(t0) - v0 T          (what the ramp must add to v0 T)
//! v  = v0 + dv,  with  dv T - |dv| dv / 2a = D,   plus  gain * (p(t_s) - x_s)
//! ```
//!
//! where `p` is the set-point of the [`SetpointSource`], `T` the cycle, and `x_s` the
//! latest position sample at its time `t_s` (see [`crate::samples`]). For an axis
//! accelerating at the limit `v` is the set-point's own velocity at the end of the cycle;
//! with a fast ramp it tends to the mean speed over the cycle. (The mean speed with a ramp
//! as slow as the set-point's acceleration would lag half a cycle, and an axis at its
//! speed limit could never catch up.) Each drive is evaluated at its own send time, so
//! axes served later in the cycle still follow the same absolute timeline. The command is
//! clamped to the axis speed limit; the drive's speed limit and acceleration (set to the
//! axis limits) bound its reference whatever the host sends, also when a request is
//! corrupted on the way.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use crate::samples::PositionSample;

/// Counts per second of one NFv2 speed unit (1/100 count per 1 ms regulator cycle).
pub const COUNTS_PER_S_PER_SPEED_UNIT: f64 = 10.0;

/// Set-points of a group of axes as functions of host time, in encoder counts.
pub trait SetpointSource: Send {
    /// Position set-point of axis `index` at `t`, counts.
    fn position(&mut self, index: usize, t: Instant) -> f64;
    /// Velocity of the set-point of axis `index` at `t`, counts/s.
    fn velocity(&mut self, index: usize, t: Instant) -> f64;
    /// True once the motion is over at `t`: the drives then hold the final set-point in
    /// POSITION mode.
    fn finished(&mut self, t: Instant) -> bool;
}

/// A source shared by the scheduler and its owner.
pub type SharedSource = Arc<Mutex<dyn SetpointSource>>;

/// Locks a shared source (a panic elsewhere does not stop the scheduler).
pub fn lock_source(source: &SharedSource) -> MutexGuard<'_, dyn SetpointSource + 'static> {
    source.lock().unwrap_or_else(PoisonError::into_inner)
}

/// One speed set-point sent while streaming.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StreamCommand {
    /// When the frame carrying it was built.
    pub at: Instant,
    /// The speed sent, speed units (10 counts/s).
    pub speed_units: i64,
    /// The source's position set-point at the command's start, counts.
    pub setpoint: f64,
    /// Position error used for the correction, counts (0 without a fresh sample).
    pub error: f64,
}

/// How one drive follows a source.
#[derive(Clone)]
pub(crate) struct StreamLink {
    pub(crate) source: SharedSource,
    pub(crate) index: usize,
    /// Speed limit, speed units.
    pub(crate) max_units: i64,
    /// Position gain, 1/s.
    pub(crate) gain: f64,
}

impl std::fmt::Debug for StreamLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StreamLink").field("index", &self.index).field("max_units", &self.max_units).finish()
    }
}

/// The speed change `dv` whose ramp at `acceleration` adds `extra` to the distance covered
/// in `period` seconds (beyond `v0 * period`): `dv T - |dv| dv / 2a = extra`, or, beyond
/// what a full-cycle ramp can add, the rest spread over the cycle.
fn ramp_change(extra: f64, acceleration: f64, period: f64) -> f64 {
    let (sign, r) = (extra.signum(), extra.abs());
    if !(acceleration.is_finite() && acceleration > 0.0) {
        return extra / period;
    }
    let full = acceleration * period * period / 2.0;
    let dv = if r <= full {
        acceleration * (period - (period * period - 2.0 * r / acceleration).max(0.0).sqrt())
    } else {
        acceleration * period + (r - full) / period
    };
    sign * dv
}

/// The speed command for a frame built at `now` (see the module documentation):
/// `previous` is the last speed sent (counts/s), where the drive's ramp at
/// `acceleration` (counts/s²) starts.
#[allow(clippy::too_many_arguments)]
pub(crate) fn speed_command(
    link: &StreamLink,
    source: &mut dyn SetpointSource,
    now: Instant,
    delivery: Duration,
    period: Duration,
    sample: Option<PositionSample>,
    previous: f64,
    acceleration: f64,
) -> StreamCommand {
    let t0 = now + delivery;
    let period = period.max(Duration::from_millis(1));
    let p0 = source.position(link.index, t0);
    let p1 = source.position(link.index, t0 + period);
    let t = period.as_secs_f64();
    let feed_forward = previous + ramp_change(p1 - p0 - previous * t, acceleration, t);
    let fresh = sample.filter(|s| now.saturating_duration_since(s.at()) <= period * 4);
    let error = fresh.map_or(0.0, |s| source.position(link.index, s.at()) - s.counts as f64);
    let speed = feed_forward + link.gain * error;
    let units = (speed / COUNTS_PER_S_PER_SPEED_UNIT).round();
    let max = link.max_units.max(0) as f64;
    let speed_units = if units.is_finite() { units.clamp(-max, max) as i64 } else { 0 };
    StreamCommand { at: now, speed_units, setpoint: p0, error }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ramp at 1000 counts/s from `start`.
    struct Ramp(Instant);

    impl SetpointSource for Ramp {
        fn position(&mut self, _: usize, t: Instant) -> f64 {
            t.saturating_duration_since(self.0).as_secs_f64() * 1000.0
        }
        fn velocity(&mut self, _: usize, _: Instant) -> f64 {
            1000.0
        }
        fn finished(&mut self, _: Instant) -> bool {
            false
        }
    }

    #[test]
    fn the_ramp_covers_the_set_point_displacement() {
        // From 0 at 100 counts/s² over 1 s: a full ramp adds 50 counts (dv = 100).
        assert!((ramp_change(50.0, 100.0, 1.0) - 100.0).abs() < 1e-9);
        // 32 counts: dv = 100 (1 - sqrt(1 - 0.64)) = 40; check: 40 - 40²/200 = 32.
        assert!((ramp_change(-32.0, 100.0, 1.0) + 40.0).abs() < 1e-9);
        // Beyond a full ramp the rest is spread over the cycle.
        assert!((ramp_change(70.0, 100.0, 1.0) - 120.0).abs() < 1e-9);
        // A very fast ramp gives the mean speed.
        assert!((ramp_change(30.0, 1e12, 1.0) - 30.0).abs() < 1e-3);
    }

    #[test]
    fn feed_forward_plus_correction_clamped() {
        let start = motus_clock::VirtualClock::new().base();
        let src: SharedSource = Arc::new(Mutex::new(Ramp(start)));
        let link = StreamLink { source: src.clone(), index: 0, max_units: 150, gain: 10.0 };
        let now = start + Duration::from_millis(100);
        let period = Duration::from_millis(10);
        // On track: 1000 counts/s = 100 units (the previous command, so no ramp).
        let command = |sample| {
            let mut source = lock_source(&src);
            let delivery = Duration::from_millis(2);
            speed_command(&link, &mut *source, now, delivery, period, Some(sample), 1000.0, 1e5)
        };
        let on_track = PositionSample::new(now, now, 100, Duration::ZERO);
        let c = command(on_track);
        assert_eq!((c.speed_units, c.error), (100, 0.0));
        // 30 counts behind: + 300 counts/s.
        let c = command(PositionSample { counts: 70, ..on_track });
        assert_eq!(c.speed_units, 130);
        // 100 counts behind: clamped to the limit.
        let c = command(PositionSample { counts: 0, ..on_track });
        assert_eq!(c.speed_units, 150);
        // A stale sample is not used.
        let c = command(PositionSample::new(start, start, -5000, Duration::ZERO));
        assert_eq!(c.speed_units, 100);
    }
}
