//! Position samples with host timestamps, their history (a ring buffer), "position at
//! time t" by interpolation, and the plausibility gate that keeps corrupt values out.
//!
//! # When was a sample taken?
//! A sample carries the host [`Instant`] just before its request was handed to the line
//! and the one just after its answer was decoded. The instant it stands for
//! ([`PositionSample::at`]) is based on their **midpoint**, which needs no clock shared
//! with the device and is insensitive to a constant host latency on either side. The
//! 1209A answers with the values it published at the end of its last 1 ms regulator cycle
//! before the request's last byte arrived, so the true instant lies between the end of the
//! request and the start of the answer; the scheduler moves the midpoint back by what is
//! known of that interval ([`latch_correction`]): half the difference of the answer's and
//! the request's wire times, half the slave's turnaround, and the mean age of a published
//! value (half a regulator period). Over the simulated line the error left is about
//! ±0.5 ms (the regulator's quantisation) plus host scheduling jitter, i.e. a few
//! hundredths of a degree at the pan-tilt head's 30 deg/s.
//!
//! # Interpolation
//! [`SampleHistory::position_at`] fits a quadratic in time, by weighted least squares, to
//! the two samples around `t` and up to two more on each side (a local regression), and
//! evaluates it at `t`. Each sample weighs by how well its instant is known: a round trip
//! longer than the quickest one in the window means the host held the exchange up
//! somewhere (the scheduler thread descheduled before the request or after the answer), so
//! its instant is uncertain by half the excess; the weight is
//! `1 / (σ0² + (excess / 2)²)` with σ0 = 0.5 ms, the regulator's quantisation. A slowed
//! sample thus barely moves the fit, while the quadratic follows the curvature that a
//! straight line across the gap it leaves would cut. With fewer than four samples in
//! reach the two around `t` are interpolated linearly. A sample held up by more than
//! [`SampleHistory::max_delay`] (2 ms by default) is not used at all: its instant is too
//! uncertain, and when several such samples come in a row (the host stalled) no weighting
//! can recover the time between them, so it counts as a missed sample, and a time only
//! reachable through such samples is refused ([`WhereError::Delayed`]) rather than
//! answered wrongly. The exception is an axis standing still: when a held-up sample and
//! its neighbours on either side agree within [`SampleHistory::still_band`], when its
//! value was latched does not matter, and it is used. After the newest sample it
//! extrapolates from the newest two trusted ones for at most a small margin, and it
//! refuses anything else (older than the history, newer than the margin, or inside a gap
//! of missed samples longer than the allowed gap; the fit never reaches across such a gap
//! either).
//!
//! # Plausibility
//! The NFv2 CRC-8 misses some single-byte corruptions, so [`Gate`] accepts a position only
//! if it is kinematically consistent with the previous accepted one (within the speed and
//! acceleration the drive can reach); after a jump (homing resets the counter) two
//! mutually consistent samples re-anchor it.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// One position reading of one slave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PositionSample {
    /// Just before the request was handed to the line.
    pub request_at: Instant,
    /// Just after the answer was decoded.
    pub reply_at: Instant,
    /// The instant the value stands for: the midpoint, moved back by the latch correction.
    pub at: Instant,
    /// The position counter, encoder counts.
    pub counts: i64,
}

impl PositionSample {
    /// A sample standing for the midpoint of request and reply, moved back by `correction`.
    #[must_use]
    pub fn new(request_at: Instant, reply_at: Instant, counts: i64, correction: Duration) -> Self {
        let midpoint = request_at + reply_at.saturating_duration_since(request_at) / 2;
        let at = midpoint.checked_sub(correction).unwrap_or(midpoint).max(request_at);
        PositionSample { request_at, reply_at, at, counts }
    }

    /// The midpoint of request and reply.
    #[must_use]
    pub fn midpoint(&self) -> Instant {
        self.request_at + self.reply_at.saturating_duration_since(self.request_at) / 2
    }

    /// The instant the sample stands for (see the module documentation).
    #[must_use]
    pub fn at(&self) -> Instant {
        self.at
    }

    /// From the request handed to the line to the answer decoded.
    #[must_use]
    pub fn round_trip(&self) -> Duration {
        self.reply_at.saturating_duration_since(self.request_at)
    }
}

/// How far before the midpoint of request and reply the value of an answer was latched:
/// `(wire(answer) - wire(request)) / 2 + turnaround / 2 + latch_age`, where `latch_age` is
/// the mean age of a published value when the request arrives (half the slave's regulator
/// period). Never negative.
#[must_use]
pub fn latch_correction(
    request: Duration,
    answer: Duration,
    turnaround: Duration,
    latch_age: Duration,
) -> Duration {
    let half = |d: Duration| d / 2;
    (half(answer) + half(turnaround) + latch_age).saturating_sub(half(request))
}

/// Why a position at a given time cannot be given.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum WhereError {
    /// No sample yet.
    #[error("no position sample yet")]
    NoSamples,
    /// Older than the oldest sample kept.
    #[error("time is {before:?} before the oldest sample kept")]
    TooOld {
        /// How far before the oldest sample.
        before: Duration,
    },
    /// Newer than the newest sample by more than the extrapolation margin.
    #[error("time is {after:?} after the newest sample (extrapolation allowed up to {margin:?})")]
    TooNew {
        /// How far after the newest sample.
        after: Duration,
        /// The extrapolation margin.
        margin: Duration,
    },
    /// Only samples held up by the host or the line are near the time: when their values
    /// were latched is too uncertain to place the axis there.
    #[error(
        "the position samples around that time were held up by {delay:?} (more than {max_delay:?}): \
         their timing is too uncertain"
    )]
    Delayed {
        /// How much longer than an unhindered exchange the worst of them took.
        delay: Duration,
        /// The longest hold-up a sample may have to be used.
        max_delay: Duration,
    },
    /// Inside a gap of missed samples too long to interpolate across.
    #[error("time falls in a gap of {gap:?} without samples (at most {max_gap:?} is interpolated)")]
    Gap {
        /// Length of the gap.
        gap: Duration,
        /// The longest gap interpolated across.
        max_gap: Duration,
    },
}

/// A bounded history of samples, oldest first (a ring buffer: the oldest sample is
/// dropped when full).
#[derive(Debug, Clone)]
pub struct SampleHistory {
    samples: VecDeque<PositionSample>,
    capacity: usize,
    /// How far after the newest sample extrapolation is allowed.
    pub margin: Duration,
    /// The longest gap between two samples interpolated across.
    pub max_gap: Duration,
    /// A sample whose exchange took longer than an unhindered one nearby (the lower
    /// quartile of the round trips around it) by more than this is not used: it counts as
    /// missed (default [`DEFAULT_MAX_DELAY`]), unless the axis stood still across it
    /// (see [`SampleHistory::still_band`]).
    pub max_delay: Duration,
    /// A held-up sample is still used when its value and those of the samples on either
    /// side lie within this many counts (default [`DEFAULT_STILL_BAND`]): the exchanges of
    /// one slave follow each other on the line, so the instant its value was latched lies
    /// between its neighbours' and, the axis moving one way at most over that time, its
    /// position there was within the band whenever in the exchange it was latched. A
    /// negative band turns this off.
    pub still_band: i64,
}

/// Default [`SampleHistory::max_delay`]: a sample's instant is uncertain by half its
/// hold-up, 1 ms at this bound, plus the regulator's ±0.5 ms: 0.045 deg at the pan-tilt
/// head's 30 deg/s, inside its 0.05 deg (3 ms left 0.06 deg possible).
pub const DEFAULT_MAX_DELAY: Duration = Duration::from_millis(2);

/// Default [`SampleHistory::still_band`]: 2 counts, an encoder's dither at standstill
/// (0.004 deg on the pan-tilt head).
pub const DEFAULT_STILL_BAND: i64 = 2;

/// Samples on each side of a time whose round trips tell an unhindered one.
const UNHINDERED_REACH: usize = 32;

impl SampleHistory {
    /// An empty history of at most `capacity` samples (at least 2).
    #[must_use]
    pub fn new(capacity: usize, margin: Duration, max_gap: Duration) -> Self {
        let capacity = capacity.max(2);
        SampleHistory {
            samples: VecDeque::with_capacity(capacity),
            capacity,
            margin,
            max_gap,
            max_delay: DEFAULT_MAX_DELAY,
            still_band: DEFAULT_STILL_BAND,
        }
    }

    /// The same history with [`SampleHistory::max_delay`] set.
    #[must_use]
    pub fn with_max_delay(mut self, max_delay: Duration) -> Self {
        self.max_delay = max_delay;
        self
    }

    /// The same history with [`SampleHistory::still_band`] set.
    #[must_use]
    pub fn with_still_band(mut self, still_band: i64) -> Self {
        self.still_band = still_band;
        self
    }

    /// Adds a sample; samples must come in order of [`PositionSample::at`] (older ones
    /// are ignored).
    pub fn push(&mut self, sample: PositionSample) {
        if self.samples.back().is_some_and(|last| sample.at() <= last.at()) {
            return;
        }
        if self.samples.len() == self.capacity {
            self.samples.pop_front();
        }
        self.samples.push_back(sample);
    }

    /// The newest sample.
    #[must_use]
    pub fn latest(&self) -> Option<PositionSample> {
        self.samples.back().copied()
    }

    /// Number of samples kept.
    #[must_use]
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// True if no sample is kept.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// All samples, oldest first.
    pub fn iter(&self) -> impl Iterator<Item = &PositionSample> {
        self.samples.iter()
    }

    /// The velocity over the last two samples, counts/s.
    #[must_use]
    pub fn velocity(&self) -> Option<f64> {
        let n = self.samples.len();
        let (a, b) = (self.samples.get(n.checked_sub(2)?)?, self.samples.get(n - 1)?);
        velocity(a, b)
    }

    /// The position (counts, fractional) at `t`: fitted to the trusted samples around it
    /// (see the module documentation), extrapolated from the newest trusted one for at most
    /// [`SampleHistory::margin`].
    ///
    /// # Errors
    /// [`WhereError`] when `t` is outside the history (plus margin), in a long gap, or only
    /// reachable through samples held up by more than [`SampleHistory::max_delay`].
    pub fn position_at(&self, t: Instant) -> Result<f64, WhereError> {
        let Some(first) = self.samples.front() else {
            return Err(WhereError::NoSamples);
        };
        if t < first.at() {
            return Err(WhereError::TooOld { before: first.at() - t });
        }
        // Samples at or before `t` are 0..i, after it i...
        let i = self.samples.partition_point(|s| s.at() <= t);
        let unhindered = self.unhindered_around(i);
        let delay = |s: &PositionSample| s.round_trip().saturating_sub(unhindered);
        let trusted = |j: &usize| {
            self.samples.get(*j).is_some_and(|s| delay(s) <= self.max_delay || self.still_across(*j))
        };
        // The worst delay among the samples skipped between `from` and `to` (exclusive).
        let held_up = |from: usize, to: usize| {
            (from..to)
                .filter(|j| !trusted(j))
                .filter_map(|j| self.samples.get(j))
                .map(delay)
                .max()
                .unwrap_or_default()
        };
        // A refusal: naming the hold-up if samples were skipped for it, else `otherwise`.
        let refuse = |skipped: Duration, otherwise: WhereError| {
            Err(if skipped > self.max_delay {
                WhereError::Delayed { delay: skipped, max_delay: self.max_delay }
            } else {
                otherwise
            })
        };
        let Some(ia) = (0..i).rev().find(trusted) else {
            return Err(WhereError::Delayed { delay: held_up(0, i), max_delay: self.max_delay });
        };
        let a = self.samples.get(ia).ok_or(WhereError::NoSamples)?;
        let Some(ib) = (i..self.samples.len()).find(trusted) else {
            let after = t - a.at();
            if after > self.margin {
                return refuse(
                    held_up(ia + 1, self.samples.len()),
                    WhereError::TooNew { after, margin: self.margin },
                );
            }
            // The velocity over the newest two trusted samples; without a trusted one before
            // `a` only a lone first sample may stand for a standstill.
            let before = (0..ia).rev().find(trusted).and_then(|j| self.samples.get(j));
            let v = match before.filter(|p| a.at().saturating_duration_since(p.at()) <= self.max_gap) {
                Some(p) => velocity(p, a).unwrap_or(0.0),
                None if ia == 0 => 0.0,
                None => {
                    let skipped = held_up(0, ia).max(held_up(ia + 1, self.samples.len()));
                    let gap = before.map_or(Duration::ZERO, |p| a.at().saturating_duration_since(p.at()));
                    return refuse(skipped, WhereError::Gap { gap, max_gap: self.max_gap });
                }
            };
            return Ok(a.counts as f64 + v * after.as_secs_f64());
        };
        let b = self.samples.get(ib).ok_or(WhereError::NoSamples)?;
        let gap = b.at() - a.at();
        if gap > self.max_gap {
            return refuse(held_up(ia + 1, ib), WhereError::Gap { gap, max_gap: self.max_gap });
        }
        if let Some(fitted) = self.local_fit(ia, ib, &trusted, t) {
            return Ok(fitted);
        }
        let f = (t - a.at()).as_secs_f64() / gap.as_secs_f64().max(f64::MIN_POSITIVE);
        Ok(a.counts as f64 + f * (b.counts - a.counts) as f64)
    }

    /// True if sample `j` and its neighbours on either side, each within the allowed gap,
    /// lie within [`SampleHistory::still_band`] (the axis stood still across it).
    fn still_across(&self, j: usize) -> bool {
        let (Some(before), Some(s), Some(after)) = (
            j.checked_sub(1).and_then(|k| self.samples.get(k)),
            self.samples.get(j),
            self.samples.get(j + 1),
        ) else {
            return false;
        };
        let near =
            |a: &PositionSample, b: &PositionSample| b.at().saturating_duration_since(a.at()) <= self.max_gap;
        let lo = before.counts.min(s.counts).min(after.counts);
        let hi = before.counts.max(s.counts).max(after.counts);
        near(before, s) && near(s, after) && hi.saturating_sub(lo) <= self.still_band
    }

    /// The round trip of an unhindered exchange near index `i`: the lower quartile of the
    /// round trips nearby (robust against a sample too quick to be true, such as an answer
    /// taken for the next request's).
    fn unhindered_around(&self, i: usize) -> Duration {
        let lo = i.saturating_sub(UNHINDERED_REACH);
        let hi = (i + UNHINDERED_REACH).min(self.samples.len());
        let mut trips = [Duration::ZERO; 2 * UNHINDERED_REACH];
        let mut n = 0;
        for (slot, s) in trips.iter_mut().zip(self.samples.range(lo..hi)) {
            *slot = s.round_trip();
            n += 1;
        }
        match trips.get_mut(..n) {
            Some(trips) if n > 0 => *trips.select_nth_unstable(n / 4).1,
            _ => Duration::ZERO,
        }
    }

    /// The weighted quadratic fit of the module documentation around the trusted bracket
    /// `(ia, ib)`, over up to [`FIT_REACH`] more trusted samples on each side; `None` with
    /// fewer than four samples in reach or a degenerate system.
    fn local_fit(&self, ia: usize, ib: usize, trusted: &dyn Fn(&usize) -> bool, t: Instant) -> Option<f64> {
        let a = self.samples.get(ia)?;
        let b = self.samples.get(ib)?;
        let mut window = vec![*a, *b];
        // Walks away from the bracket, one trusted sample after another, as long as each
        // step stays within the allowed gap.
        let mut extend = |mut edge: PositionSample, indices: &mut dyn Iterator<Item = usize>| {
            for p in indices.filter(trusted).filter_map(|j| self.samples.get(j)).take(FIT_REACH) {
                let step = if p.at() < edge.at() { edge.at() - p.at() } else { p.at() - edge.at() };
                if step > self.max_gap {
                    break;
                }
                window.push(*p);
                edge = *p;
            }
        };
        extend(*a, &mut (0..ia).rev());
        extend(*b, &mut (ib + 1..self.samples.len()));
        if window.len() < 4 {
            return None;
        }
        let quickest = window.iter().map(PositionSample::round_trip).min()?;
        let origin = a.counts;
        // Normal equations of y = c0 + c1 τ + c2 τ², τ in ms from t, y in counts from origin.
        let (mut s, mut r) = ([0.0f64; 5], [0.0f64; 3]);
        for p in &window {
            let tau = signed_ms(p.at(), t);
            let excess = (p.round_trip() - quickest).as_secs_f64() * 1000.0;
            let w = 1.0 / (FIT_FLOOR_MS * FIT_FLOOR_MS + 0.25 * excess * excess);
            let y = (p.counts - origin) as f64;
            let mut tk = w;
            for (k, sk) in s.iter_mut().enumerate() {
                *sk += tk;
                if let Some(rk) = r.get_mut(k) {
                    *rk += tk * y;
                }
                tk *= tau;
            }
        }
        let [s0, s1, s2, s3, s4] = s;
        let [r0, r1, r2] = r;
        let det3 = |a: [f64; 9]| {
            a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6])
                + a[2] * (a[3] * a[7] - a[4] * a[6])
        };
        let det = det3([s0, s1, s2, s1, s2, s3, s2, s3, s4]);
        let scale = s0 * s2 * s4;
        if !det.is_finite() || det.abs() <= 1e-9 * scale.abs() {
            return None;
        }
        // Cramer's rule for c0 alone: the value at τ = 0.
        let c0 = det3([r0, s1, s2, r1, s2, s3, r2, s3, s4]) / det;
        c0.is_finite().then_some(origin as f64 + c0)
    }
}

/// Samples taken into the fit on each side beyond the two around `t`.
const FIT_REACH: usize = 2;
/// The timing uncertainty of an unhindered exchange (the regulator's quantisation), ms.
const FIT_FLOOR_MS: f64 = 0.5;

/// `a - b` in milliseconds, signed.
fn signed_ms(a: Instant, b: Instant) -> f64 {
    match a.checked_duration_since(b) {
        Some(d) => d.as_secs_f64() * 1000.0,
        None => -(b.saturating_duration_since(a).as_secs_f64() * 1000.0),
    }
}

fn velocity(a: &PositionSample, b: &PositionSample) -> Option<f64> {
    let dt = b.at().checked_duration_since(a.at())?.as_secs_f64();
    (dt > 0.0).then(|| (b.counts - a.counts) as f64 / dt)
}

/// Kinematic bounds of the plausibility gate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GateBounds {
    /// Fastest plausible speed, counts/s.
    pub speed: f64,
    /// Largest plausible acceleration, counts/s².
    pub acceleration: f64,
    /// Allowance for encoder noise and servo jitter, counts.
    pub base: f64,
    /// Uncertainty of a sample's time (host scheduling), applied to the speed.
    pub jitter: Duration,
}

/// What the gate did with a sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Consistent with the history: use it.
    Accept,
    /// Inconsistent: a corrupt value (or the first of a real jump); do not use it.
    Reject,
}

/// The plausibility gate of one slave's positions (see the module documentation).
#[derive(Debug, Clone, Default)]
pub struct Gate {
    last: Option<PositionSample>,
    velocity: Option<f64>,
    suspect: Option<PositionSample>,
}

impl Gate {
    /// Judges `sample` against the last accepted one.
    pub fn check(&mut self, sample: PositionSample, bounds: &GateBounds) -> Verdict {
        let agrees = match self.last {
            Some(last) => consistent(&last, self.velocity, &sample, bounds),
            None => false,
        };
        if agrees {
            self.accept(sample);
            return Verdict::Accept;
        }
        // A jump (or the first sample): accept once two samples agree with each other.
        let confirmed = self.suspect.is_some_and(|s| consistent(&s, None, &sample, bounds));
        if confirmed {
            self.velocity = None;
            self.last = None;
            self.accept(sample);
            self.suspect = None;
            Verdict::Accept
        } else {
            self.suspect = Some(sample);
            Verdict::Reject
        }
    }

    /// Forgets the history (after a known jump such as homing).
    pub fn reset(&mut self) {
        *self = Gate::default();
    }

    fn accept(&mut self, sample: PositionSample) {
        if let Some(last) = self.last {
            self.velocity = velocity(&last, &sample);
        }
        self.last = Some(sample);
        self.suspect = None;
    }
}

fn consistent(a: &PositionSample, v: Option<f64>, b: &PositionSample, bounds: &GateBounds) -> bool {
    let Some(dt) = b.at().checked_duration_since(a.at()) else { return false };
    let dt = dt.as_secs_f64();
    let moved = (b.counts - a.counts) as f64;
    match v {
        Some(v) => {
            let predicted = v * dt;
            let allowed =
                bounds.base + v.abs() * bounds.jitter.as_secs_f64() + 0.5 * bounds.acceleration * dt * dt;
            (moved - predicted).abs() <= allowed
        }
        None => moved.abs() <= bounds.base + bounds.speed * (dt + bounds.jitter.as_secs_f64()),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn sample(t0: Instant, ms: u64, counts: i64) -> PositionSample {
        // A 2 ms exchange whose midpoint is at `ms`.
        let at = t0 + Duration::from_millis(ms);
        let (request_at, reply_at) = (at - Duration::from_millis(1), at + Duration::from_millis(1));
        PositionSample::new(request_at, reply_at, counts, Duration::ZERO)
    }

    #[test]
    fn the_latch_correction() {
        // Request 15 B, answer 19 B at 57600 Bd: (3.299 - 2.604) / 2 + 0.1 + 0.5 ms.
        let (rq, an) =
            (motus_nfv2_protocol::wire_time(15, 57_600), motus_nfv2_protocol::wire_time(19, 57_600));
        let c = latch_correction(rq, an, Duration::from_micros(200), Duration::from_micros(500));
        assert_eq!(c.as_micros(), 947);
        let t0 = motus_clock::VirtualClock::new().base();
        let s = PositionSample::new(t0, t0 + Duration::from_millis(6), 0, c);
        assert_eq!(s.midpoint() - s.at(), c);
        // Never before the request.
        let s = PositionSample::new(t0, t0 + Duration::from_micros(100), 0, c);
        assert_eq!(s.at(), t0);
    }

    #[test]
    fn interpolates_between_samples_and_refuses_outside() {
        let t0 = motus_clock::VirtualClock::new().base() + Duration::from_secs(1);
        let mut h = SampleHistory::new(3, Duration::from_millis(5), Duration::from_millis(50));
        assert_eq!(h.position_at(t0), Err(WhereError::NoSamples));
        h.push(sample(t0, 0, 0));
        h.push(sample(t0, 10, 100));
        h.push(sample(t0, 20, 300));
        assert_eq!(h.position_at(t0 + Duration::from_millis(5)), Ok(50.0));
        assert_eq!(h.position_at(t0 + Duration::from_millis(15)), Ok(200.0));
        // Extrapolated from the last two samples (20 counts/ms) within the margin.
        assert_eq!(h.position_at(t0 + Duration::from_millis(24)), Ok(380.0));
        assert!(matches!(h.position_at(t0 + Duration::from_millis(26)), Err(WhereError::TooNew { .. })));
        assert!(matches!(h.position_at(t0 - Duration::from_millis(1)), Err(WhereError::TooOld { .. })));
        // The ring drops the oldest sample.
        h.push(sample(t0, 30, 400));
        assert_eq!(h.len(), 3);
        assert!(matches!(h.position_at(t0 + Duration::from_millis(5)), Err(WhereError::TooOld { .. })));
        // A gap longer than max_gap is not interpolated across.
        h.push(sample(t0, 100, 400));
        assert!(matches!(h.position_at(t0 + Duration::from_millis(60)), Err(WhereError::Gap { .. })));
        // Out-of-order samples are ignored.
        h.push(sample(t0, 90, 0));
        assert_eq!(h.latest().map(|s| s.counts), Some(400));
    }

    /// A sample whose exchange took `rtt_ms`, standing for `at_ms` (the midpoint, no latch
    /// correction), of the trajectory `x`.
    fn exchange(t0: Instant, at_ms: f64, rtt_ms: f64, x: impl Fn(f64) -> f64) -> PositionSample {
        let at = t0 + Duration::from_secs_f64(at_ms / 1000.0);
        let half = Duration::from_secs_f64(rtt_ms / 2000.0);
        PositionSample::new(at - half, at + half, x(at_ms).round() as i64, Duration::ZERO)
    }

    #[test]
    fn the_local_fit_follows_curvature_that_a_straight_line_cuts() {
        // x = 4 t² counts (t in ms): a constant acceleration, samples every 15 ms.
        let x = |t: f64| 4.0 * t * t;
        let t0 = motus_clock::VirtualClock::new().base();
        let mut h = SampleHistory::new(64, Duration::from_millis(5), Duration::from_millis(40));
        for k in 0..8 {
            h.push(exchange(t0, 15.0 * f64::from(k), 5.5, x));
        }
        let q = 52.5; // between the samples at 45 and 60 ms
        let got = h.position_at(t0 + Duration::from_secs_f64(q / 1000.0)).unwrap();
        // A straight line between 45 and 60 ms is off by a h² / 8 = 225 counts.
        let line = (x(45.0) + x(60.0)) / 2.0;
        assert!((line - x(q)).abs() > 200.0);
        assert!((got - x(q)).abs() < 1.0, "fit {got}, truth {}", x(q));
    }

    /// An exchange like [`exchange`], answered `late_ms` late (the host held it up).
    fn held(t0: Instant, at_ms: f64, late_ms: f64, x: impl Fn(f64) -> f64) -> PositionSample {
        let s = exchange(t0, at_ms, 5.5, x);
        PositionSample::new(
            s.request_at,
            s.reply_at + Duration::from_secs_f64(late_ms / 1000.0),
            s.counts,
            Duration::ZERO,
        )
    }

    #[test]
    fn a_slowed_exchange_barely_moves_the_fit() {
        // 30 counts/ms with curvature; one exchange held up by the host: its answer was
        // decoded 6 ms late, so its midpoint is 3 ms after the instant its value stands for.
        let x = |t: f64| 30.0 * t + 0.2 * t * t;
        let t0 = motus_clock::VirtualClock::new().base();
        let mut h = SampleHistory::new(64, Duration::from_millis(5), Duration::from_millis(40));
        for k in 0..8u32 {
            let at = 15.0 * f64::from(k);
            h.push(if k == 3 { held(t0, at, 6.0, x) } else { exchange(t0, at, 5.5, x) });
        }
        for q in [40.0, 47.0, 52.0] {
            let got = h.position_at(t0 + Duration::from_secs_f64(q / 1000.0)).unwrap();
            // Unweighted, the slowed sample would put its value 3 ms late: ~100 counts off.
            assert!((got - x(q)).abs() < 8.0, "at {q} ms: fit {got}, truth {}", x(q));
        }
    }

    #[test]
    fn a_held_up_sample_counts_as_missed() {
        // 30 counts/ms with curvature, samples every 15 ms.
        let x = |t: f64| 30.0 * t + 0.2 * t * t;
        let t0 = motus_clock::VirtualClock::new().base();
        let mut h = SampleHistory::new(64, Duration::from_millis(10), Duration::from_millis(40));
        for k in 0..6u32 {
            h.push(exchange(t0, 15.0 * f64::from(k), 5.5, x));
        }
        // Two exchanges in a row held up 8 ms (the host stalled): their values are 4 ms
        // older than their midpoints.
        h.push(held(t0, 90.0, 8.0, x));
        h.push(held(t0, 105.0, 8.0, x));
        // Extrapolating from them would be 120 counts off; the newest trusted sample is
        // 25 ms back, beyond the 10 ms margin: refused, naming the hold-up.
        let q = t0 + Duration::from_millis(114);
        let refused = h.position_at(q);
        assert!(
            matches!(refused, Err(WhereError::Delayed { delay, max_delay })
                if delay >= Duration::from_millis(7) && max_delay == DEFAULT_MAX_DELAY),
            "expected a refusal naming the hold-up, got {refused:?}"
        );
        // Between them too: the trusted neighbours are 45 ms apart, beyond max_gap.
        assert!(matches!(h.position_at(t0 + Duration::from_millis(96)), Err(WhereError::Delayed { .. })));
        // One held-up sample among good ones: the time around it is bridged by its trusted
        // neighbours (30 ms apart).
        let mut g = SampleHistory::new(64, Duration::from_millis(10), Duration::from_millis(40));
        for k in 0..10u32 {
            let at = 15.0 * f64::from(k);
            g.push(if k == 6 { held(t0, at, 8.0, x) } else { exchange(t0, at, 5.5, x) });
        }
        for q in [80.0, 88.0, 97.0, 103.0] {
            let got = g.position_at(t0 + Duration::from_secs_f64(q / 1000.0)).unwrap();
            assert!((got - x(q)).abs() < 2.0, "at {q} ms: {got}, truth {}", x(q));
        }
        // With no limit, the held-up sample is used (weighted down): a looser answer.
        let loose = g.clone().with_max_delay(Duration::MAX);
        assert!(loose.position_at(t0 + Duration::from_millis(97)).is_ok());
    }

    #[test]
    fn held_up_samples_of_an_axis_standing_still_are_used() {
        // The axis stands at 5000 counts (dithering by a count) while the host stalls every
        // exchange by 5 ms, then starts to move at 30 counts/ms from 90 ms on.
        let x = |t: f64| if t < 90.0 { 5000.0 + (t / 15.0) % 2.0 } else { 5000.0 + 30.0 * (t - 90.0) };
        let t0 = motus_clock::VirtualClock::new().base();
        let mut h = SampleHistory::new(64, Duration::from_millis(10), Duration::from_millis(40));
        for k in 0..3u32 {
            h.push(exchange(t0, 15.0 * f64::from(k), 5.5, x));
        }
        for k in 3..10u32 {
            h.push(held(t0, 15.0 * f64::from(k), 5.0, x));
        }
        for q in [20.0, 50.0, 70.0] {
            let got = h.position_at(t0 + Duration::from_secs_f64(q / 1000.0)).unwrap();
            assert!((got - 5000.5).abs() <= 1.0, "at {q} ms: {got}");
        }
        // Once it moves, the held-up samples are untrustworthy again: refused.
        for q in [100.0, 118.0] {
            let got = h.position_at(t0 + Duration::from_secs_f64(q / 1000.0));
            assert!(matches!(got, Err(WhereError::Delayed { .. })), "at {q} ms: {got:?}");
        }
        // Without the band, the standstill is refused like any held-up stretch.
        let strict = h.clone().with_still_band(-1);
        assert!(matches!(
            strict.position_at(t0 + Duration::from_millis(70)),
            Err(WhereError::Delayed { .. })
        ));
    }

    #[test]
    fn one_exchange_too_quick_to_be_true_does_not_make_the_others_held_up() {
        let x = |t: f64| 30.0 * t;
        let t0 = motus_clock::VirtualClock::new().base();
        let mut h = SampleHistory::new(64, Duration::from_millis(10), Duration::from_millis(40));
        for k in 0..8u32 {
            let at = 15.0 * f64::from(k);
            h.push(exchange(t0, at, if k == 4 { 0.5 } else { 5.5 }, x));
        }
        for q in [50.0, 70.0, 100.0, 110.0] {
            let got = h.position_at(t0 + Duration::from_secs_f64(q / 1000.0)).unwrap();
            assert!((got - x(q)).abs() < 1.0, "at {q} ms: {got}");
        }
    }

    #[test]
    fn gate_rejects_a_corrupt_low_byte_and_follows_a_real_jump() {
        let t0 = motus_clock::VirtualClock::new().base();
        let bounds = GateBounds {
            speed: 120_000.0,
            acceleration: 111_112.0,
            base: 20.0,
            jitter: Duration::from_millis(1),
        };
        let mut g = Gate::default();
        // The first sample needs a second one to agree with it.
        assert_eq!(g.check(sample(t0, 0, 1000), &bounds), Verdict::Reject);
        assert_eq!(g.check(sample(t0, 10, 1100), &bounds), Verdict::Accept);
        assert_eq!(g.check(sample(t0, 20, 1200), &bounds), Verdict::Accept);
        // 1300 = 0x0514 with its low byte XORed by 0xEC (a pattern CRC-8 0xD8 misses):
        // 0x05F8 = 1528, 228 counts off the 10 counts/ms line.
        assert_eq!(g.check(sample(t0, 30, 0x05F8), &bounds), Verdict::Reject);
        assert_eq!(g.check(sample(t0, 40, 1400), &bounds), Verdict::Accept);
        // Homing resets the counter: the first new value is refused, the second agrees.
        assert_eq!(g.check(sample(t0, 50, -3), &bounds), Verdict::Reject);
        assert_eq!(g.check(sample(t0, 60, 0), &bounds), Verdict::Accept);
        assert_eq!(g.check(sample(t0, 70, 1), &bounds), Verdict::Accept);
    }
}
