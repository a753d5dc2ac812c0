//! [`ExecutedPath`]: the tool's executed path of the current run, thinned to points at least
//! [`ExecutedPath::SPACING`] apart, for the HMI to draw over the program's preview.

use serde::Serialize;

use crate::AXES;

/// Points of the executed path since a cursor.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct PathBatch {
    /// The run these points belong to (a new run starts a new path: drop the old one).
    pub run: u64,
    /// Cursor of the first point returned.
    pub from: u64,
    /// Cursor to ask from next time.
    pub next: u64,
    /// X, Y, Z in mm.
    pub points: Vec<[f64; AXES]>,
}

/// The executed path of one run (bounded: the oldest points go first).
#[derive(Debug, Clone, Default)]
pub struct ExecutedPath {
    run: u64,
    first: u64,
    points: std::collections::VecDeque<[f64; AXES]>,
}

impl ExecutedPath {
    /// Least distance between two kept points, mm.
    pub const SPACING: f64 = 0.1;
    /// Points kept at most.
    pub const CAPACITY: usize = 50_000;
    /// Points returned by one [`ExecutedPath::since`] at most.
    pub const BATCH: usize = 5_000;

    /// A new run starting at `start`.
    pub fn restart(&mut self, start: [f64; AXES]) {
        self.run += 1;
        self.first = 0;
        self.points.clear();
        self.points.push_back(start);
    }

    /// The tool is at `p`: kept when it moved [`ExecutedPath::SPACING`] from the last point,
    /// or when `last` (the run's end).
    pub fn record(&mut self, p: [f64; AXES], last: bool) {
        let far = match self.points.back() {
            None => true,
            Some(q) => {
                let d2: f64 = p.iter().zip(q).map(|(a, b)| (a - b) * (a - b)).sum();
                d2 >= Self::SPACING * Self::SPACING
            }
        };
        if far || (last && self.points.back() != Some(&p)) {
            if self.points.len() == Self::CAPACITY {
                self.points.pop_front();
                self.first += 1;
            }
            self.points.push_back(p);
        }
    }

    /// Points from `cursor` on (at most [`ExecutedPath::BATCH`]); a cursor of another run
    /// or older than the oldest point kept starts at the oldest.
    pub fn since(&self, run: u64, cursor: u64) -> PathBatch {
        let from = if run == self.run { cursor.max(self.first) } else { self.first };
        let skip = usize::try_from(from - self.first).unwrap_or(usize::MAX);
        let points: Vec<_> = self.points.iter().skip(skip).take(Self::BATCH).copied().collect();
        let next = from + points.len() as u64;
        PathBatch { run: self.run, from, next, points }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn keeps_points_apart_and_pages_by_cursor() {
        let mut p = ExecutedPath::default();
        p.restart([0.0; 3]);
        for k in 1..=100 {
            p.record([f64::from(k) * 0.01, 0.0, 0.0], false); // 1 mm in 0.01 mm steps
        }
        p.record([1.0, 0.0, 0.0], true);
        let b = p.since(1, 0);
        assert_eq!(b.points.len(), 11, "{b:?}"); // 0, 0.1, ..., 1.0
        assert_eq!(p.since(1, b.next).points.len(), 0);
        assert_eq!(p.since(0, 5).from, 0, "another run's cursor starts at the oldest point");
        p.restart([2.0, 0.0, 0.0]);
        assert_eq!(p.since(1, 11).run, 2);
        assert_eq!(p.since(1, 11).points, vec![[2.0, 0.0, 0.0]]);
    }
}
