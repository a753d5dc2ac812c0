//! Motion programs: what the Managing Node puts into each drive's PReq every cycle once the
//! segment is OPERATIONAL. [`CamProgram`] is the juggler-style periodic pattern (each axis
//! coupled to a virtual time axis by a sinusoidal cam); [`SetpointList`] is a "student
//! program": timed set-points, held between entries.

use std::f64::consts::TAU;
use std::time::Duration;

/// Produces position set-points for the drives, in the order the drives were added to the
/// segment.
pub trait MotionProgram: Send {
    /// Fills `out[i]` with the target position of drive `i` at `t` after the program started.
    fn setpoints(&mut self, t: Duration, out: &mut [i32]);

    /// Drive `i`'s answer (PRes) of the cycle just run: what a controller watches to hold
    /// its program when a drive stops on its own. Ignored by default.
    fn actual(&mut self, _drive: usize, _actual: &super::pdo::Actual) {}
}

/// One axis of a [`CamProgram`]: `center + amplitude * sin(2π (t / period + phase))`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CamAxis {
    /// Center position (units).
    pub center: f64,
    /// Amplitude (units).
    pub amplitude: f64,
    /// Period of the pattern (s).
    pub period: f64,
    /// Phase as a fraction of the period (0.0 to 1.0).
    pub phase: f64,
}

impl CamAxis {
    /// The position at `t` seconds.
    pub fn at(&self, t: f64) -> f64 {
        let phase = if self.period > 0.0 { t / self.period + self.phase } else { self.phase };
        self.center + self.amplitude * (TAU * phase).sin()
    }
}

/// A periodic cam pattern, one [`CamAxis`] per drive.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CamProgram {
    /// The axes, in drive order; drives beyond the list get 0.
    pub axes: Vec<CamAxis>,
}

impl CamProgram {
    /// A program with these axes.
    pub fn new(axes: Vec<CamAxis>) -> Self {
        Self { axes }
    }
}

fn to_units(x: f64) -> i32 {
    // `as` saturates at the i32 range, which is what a set-point should do.
    x.round() as i32
}

impl MotionProgram for CamProgram {
    fn setpoints(&mut self, t: Duration, out: &mut [i32]) {
        let secs = t.as_secs_f64();
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.axes.get(i).map_or(0, |a| to_units(a.at(secs)));
        }
    }
}

/// Timed set-points: from each entry's time on, its positions are the targets (held until the
/// next entry). Before the first entry, and for drives an entry does not list, the target is 0.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct SetpointList {
    /// (time since start, positions in drive order), sorted by time.
    pub entries: Vec<(Duration, Vec<i32>)>,
}

impl SetpointList {
    /// A list from entries (sorted by time here).
    pub fn new(mut entries: Vec<(Duration, Vec<i32>)>) -> Self {
        entries.sort_by_key(|(t, _)| *t);
        Self { entries }
    }
}

impl MotionProgram for SetpointList {
    fn setpoints(&mut self, t: Duration, out: &mut [i32]) {
        let current = self.entries.iter().take_while(|(at, _)| *at <= t).last();
        for (i, o) in out.iter_mut().enumerate() {
            *o = current.and_then(|(_, v)| v.get(i).copied()).unwrap_or(0);
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn cam_quarter_period_is_center_plus_amplitude() {
        let mut p =
            CamProgram::new(vec![CamAxis { center: 100.0, amplitude: 50.0, period: 2.0, phase: 0.0 }]);
        let mut out = [7; 2];
        p.setpoints(Duration::from_millis(500), &mut out); // sin(π/2) = 1
        assert_eq!(out, [150, 0]);
    }

    #[test]
    fn list_holds_last_entry() {
        let mut p =
            SetpointList::new(vec![(Duration::from_secs(1), vec![10, 20]), (Duration::ZERO, vec![1])]);
        let mut out = [9; 2];
        p.setpoints(Duration::from_millis(999), &mut out);
        assert_eq!(out, [1, 0]);
        p.setpoints(Duration::from_secs(5), &mut out);
        assert_eq!(out, [10, 20]);
    }
}
