//! The set-point sources of the head, streamed to both drives by the scheduler:
//!
//! - `GotoSource`: one normalised trapezoid `s(t)` from [`motus_axis::profile::synchronised`]
//!   shared by both axes, `x_i(t) = x0_i + d_i s(t)`: each axis within its own velocity
//!   and acceleration limits, both arriving at the same instant. Each drive is commanded
//!   at its own send time on this common timeline, so the axes stay together although
//!   their frames leave a few milliseconds apart.
//! - `TrackSource`: the [`SecondOrderLimiter`] of each axis stepped on a fixed grid of
//!   one scheduler cycle, following the target stream; set-points between grid points are
//!   interpolated linearly. Every grid point is logged ([`SetpointRecord`]) so the limits
//!   can be checked on the exact set-points.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use motus_axis::profile::Plan;

use super::filter::{Limits, SecondOrderLimiter};
use super::targets::{TargetPoint, TargetTrack};
use crate::stream::SetpointSource;

/// Grid points kept for interpolation (the scheduler only looks a few cycles back).
const WINDOW: usize = 1024;
/// Grid points kept in the log.
const LOG: usize = 1 << 18;
/// Most grid steps taken in one call (a guard against a time far ahead).
const MAX_STEPS: u64 = 1_000_000;

/// A synchronised move of both axes (degrees inside, counts out).
#[derive(Debug, Clone)]
pub(crate) struct GotoSource {
    start: Instant,
    plan: Plan,
    from: [f64; 2],
    distance: [f64; 2],
    counts_per_deg: [f64; 2],
    end: Instant,
}

impl GotoSource {
    pub(crate) fn new(
        start: Instant,
        plan: Plan,
        from: [f64; 2],
        to: [f64; 2],
        counts_per_deg: [f64; 2],
    ) -> Self {
        let end = start + Duration::from_secs_f64(plan.duration().max(0.0));
        let distance = [to[0] - from[0], to[1] - from[1]];
        GotoSource { start, plan, from, distance, counts_per_deg, end }
    }
}

impl SetpointSource for GotoSource {
    fn position(&mut self, index: usize, t: Instant) -> f64 {
        let (s, _) = self.plan.sample(t.saturating_duration_since(self.start).as_secs_f64());
        let i = index.min(1);
        let (x0, d, k) = (
            self.from.get(i).copied().unwrap_or_default(),
            self.distance.get(i).copied().unwrap_or_default(),
            self.counts_per_deg.get(i).copied().unwrap_or(1.0),
        );
        (x0 + d * s) * k
    }

    fn velocity(&mut self, index: usize, t: Instant) -> f64 {
        let (_, sv) = self.plan.sample(t.saturating_duration_since(self.start).as_secs_f64());
        let i = index.min(1);
        let d = self.distance.get(i).copied().unwrap_or_default();
        d * sv * self.counts_per_deg.get(i).copied().unwrap_or(1.0)
    }

    fn finished(&mut self, t: Instant) -> bool {
        t >= self.end
    }
}

/// One grid point of the tracking filters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SetpointRecord {
    /// Seconds from the start of the track.
    pub t: f64,
    /// Pan set-point, degrees.
    pub pan_deg: f64,
    /// Tilt set-point, degrees.
    pub tilt_deg: f64,
    /// Pan set-point velocity, deg/s.
    pub pan_velocity: f64,
    /// Tilt set-point velocity, deg/s.
    pub tilt_velocity: f64,
}

/// Tracking a target stream with the second-order limiters.
#[derive(Debug, Clone)]
pub(crate) struct TrackSource {
    origin: Instant,
    dt: f64,
    filters: [SecondOrderLimiter; 2],
    soft: [(f64, f64); 2],
    targets: TargetTrack,
    counts_per_deg: [f64; 2],
    steps: u64,
    window: VecDeque<(f64, [f64; 2])>,
    log: VecDeque<SetpointRecord>,
    live: bool,
}

/// Settings of a [`TrackSource`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct TrackSetup {
    pub(crate) origin: Instant,
    pub(crate) dt: f64,
    pub(crate) start_deg: [f64; 2],
    pub(crate) limits: [Limits; 2],
    pub(crate) soft: [(f64, f64); 2],
    pub(crate) counts_per_deg: [f64; 2],
    /// A live feed: points keep coming until closed; the target is extrapolated a little.
    pub(crate) live: bool,
}

impl TrackSource {
    pub(crate) fn new(setup: TrackSetup, points: Vec<TargetPoint>) -> Self {
        let [l0, l1] = setup.limits;
        let [s0, s1] = setup.start_deg;
        let mut window = VecDeque::with_capacity(WINDOW);
        window.push_back((0.0, setup.start_deg));
        TrackSource {
            origin: setup.origin,
            dt: setup.dt.max(1e-4),
            filters: [SecondOrderLimiter::new(s0, l0, setup.dt), SecondOrderLimiter::new(s1, l1, setup.dt)],
            soft: setup.soft,
            targets: TargetTrack::new(points, if setup.live { 0.1 } else { 0.0 }),
            counts_per_deg: setup.counts_per_deg,
            steps: 0,
            window,
            log: VecDeque::new(),
            live: setup.live,
        }
    }

    /// Adds a point of a live feed (seconds from the origin).
    pub(crate) fn push(&mut self, p: TargetPoint) {
        self.targets.push(p);
    }

    /// Ends a live feed: the head settles on the last point.
    pub(crate) fn close(&mut self) {
        self.live = false;
        self.targets.extrapolate = 0.0;
    }

    /// Every grid point so far (the newest [`LOG`] ones).
    pub(crate) fn log(&self) -> Vec<SetpointRecord> {
        self.log.iter().copied().collect()
    }

    fn tau(&self, t: Instant) -> f64 {
        match t.checked_duration_since(self.origin) {
            Some(d) => d.as_secs_f64(),
            None => -self.origin.saturating_duration_since(t).as_secs_f64(),
        }
    }

    /// Steps the filters until the grid covers `tau`.
    fn advance_to(&mut self, tau: f64) {
        let mut taken = 0;
        while (self.steps as f64) * self.dt < tau && taken < MAX_STEPS {
            let t = self.steps as f64 * self.dt;
            let targets = self.targets.at(t);
            let mut out = [(0.0, 0.0); 2];
            for (i, (f, slot)) in self.filters.iter_mut().zip(out.iter_mut()).enumerate() {
                let here = f.state().position;
                let (mut p, mut v) = targets.and_then(|t| t.get(i).copied()).unwrap_or((here, 0.0));
                let (lo, hi) = self.soft.get(i).copied().unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
                if p < lo || p > hi {
                    p = p.clamp(lo, hi);
                    v = 0.0;
                }
                let s = f.step(p, v);
                *slot = (s.position, s.velocity);
            }
            self.steps += 1;
            taken += 1;
            let tk = self.steps as f64 * self.dt;
            let [(p0, v0), (p1, v1)] = out;
            if self.window.len() == WINDOW {
                self.window.pop_front();
            }
            self.window.push_back((tk, [p0, p1]));
            if self.log.len() == LOG {
                self.log.pop_front();
            }
            self.log.push_back(SetpointRecord {
                t: tk,
                pan_deg: p0,
                tilt_deg: p1,
                pan_velocity: v0,
                tilt_velocity: v1,
            });
        }
    }

    /// The slope of the grid segment containing `tau`, deg/s.
    fn slope(&mut self, index: usize, tau: f64) -> f64 {
        self.advance_to(tau + self.dt);
        let i = index.min(1);
        let pick = |e: &(f64, [f64; 2])| e.1.get(i).copied().unwrap_or_default();
        let k = self.window.partition_point(|e| e.0 <= tau);
        match (k.checked_sub(1).and_then(|j| self.window.get(j)), self.window.get(k)) {
            (Some(a), Some(b)) if b.0 > a.0 => (pick(b) - pick(a)) / (b.0 - a.0),
            _ => 0.0,
        }
    }

    fn degrees(&mut self, index: usize, tau: f64) -> f64 {
        self.advance_to(tau);
        let i = index.min(1);
        let pick = |e: &(f64, [f64; 2])| e.1.get(i).copied().unwrap_or_default();
        let k = self.window.partition_point(|e| e.0 <= tau);
        match (k.checked_sub(1).and_then(|j| self.window.get(j)), self.window.get(k)) {
            (Some(a), Some(b)) => {
                let f = (tau - a.0) / (b.0 - a.0);
                pick(a) + f * (pick(b) - pick(a))
            }
            (Some(a), None) => pick(a),
            (None, Some(b)) => pick(b),
            (None, None) => self.filters.get(i).map(|f| f.state().position).unwrap_or_default(),
        }
    }
}

impl SetpointSource for TrackSource {
    fn position(&mut self, index: usize, t: Instant) -> f64 {
        let tau = self.tau(t);
        let k = self.counts_per_deg.get(index.min(1)).copied().unwrap_or(1.0);
        self.degrees(index, tau) * k
    }

    fn velocity(&mut self, index: usize, t: Instant) -> f64 {
        let tau = self.tau(t);
        let k = self.counts_per_deg.get(index.min(1)).copied().unwrap_or(1.0);
        self.slope(index, tau) * k
    }

    fn finished(&mut self, t: Instant) -> bool {
        if self.live {
            return false;
        }
        let tau = self.tau(t);
        let Some(last) = self.targets.last_time() else { return true };
        if tau < last {
            return false;
        }
        self.advance_to(tau);
        let end = self.targets.at(last);
        self.filters.iter().enumerate().all(|(i, f)| {
            let s = f.state();
            let goal = end.and_then(|e| e.get(i).copied()).map_or(s.position, |(p, _)| p);
            let (lo, hi) = self.soft.get(i).copied().unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
            (s.position - goal.clamp(lo, hi)).abs() < 1e-6 && s.velocity.abs() < 1e-6
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use motus_axis::profile::synchronised;

    #[test]
    fn goto_axes_share_one_timeline() {
        let start = motus_clock::VirtualClock::new().base();
        let plan = synchronised(&[(40.0, 30.0, 120.0), (-10.0, 30.0, 120.0)]).unwrap();
        let mut g = GotoSource::new(start, plan.clone(), [0.0, 5.0], [40.0, -5.0], [100.0, 100.0]);
        let half = start + Duration::from_secs_f64(plan.duration() / 2.0);
        let (p, t) = (g.position(0, half), g.position(1, half));
        // Both halfway at half time (symmetric trapezoid).
        assert!((p - 2000.0).abs() < 1e-3 && t.abs() < 1e-3, "{p} {t}");
        assert!(!g.finished(half));
        let end = start + Duration::from_secs_f64(plan.duration());
        assert!(g.finished(end));
        assert!((g.position(0, end) - 4000.0).abs() < 1e-9 && (g.position(1, end) + 500.0).abs() < 1e-9);
    }

    #[test]
    fn track_follows_points_and_settles() {
        let origin = motus_clock::VirtualClock::new().base();
        let setup = TrackSetup {
            origin,
            dt: 0.01,
            start_deg: [0.0, 0.0],
            limits: [Limits { velocity: 30.0, acceleration: 120.0 }; 2],
            soft: [(-60.0, 60.0), (-10.0, 10.0)],
            counts_per_deg: [1.0, 1.0],
            live: false,
        };
        let points = vec![
            TargetPoint { t: 0.0, pan_deg: 0.0, tilt_deg: 0.0 },
            TargetPoint { t: 1.0, pan_deg: 20.0, tilt_deg: 20.0 },
        ];
        let mut s = TrackSource::new(setup, points);
        let late = origin + Duration::from_secs(5);
        assert!(s.finished(late));
        assert!((s.position(0, late) - 20.0).abs() < 1e-6);
        // The tilt target is clamped to its soft limit.
        assert!((s.position(1, late) - 10.0).abs() < 1e-6);
        let log = s.log();
        assert_eq!(log.len(), 500);
        for w in log.windows(2) {
            let (a, b) = (w[0], w[1]);
            assert!(((b.pan_deg - a.pan_deg) / 0.01).abs() <= 30.0 * (1.0 + 1e-9));
            assert!(((b.pan_velocity - a.pan_velocity) / 0.01).abs() <= 120.0 * (1.0 + 1e-9));
        }
    }
}
