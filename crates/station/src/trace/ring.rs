//! A fixed-capacity ring of samples addressed by sequence number.

use std::time::Duration;

/// One recorded value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Time since the recorder's epoch.
    pub t: Duration,
    /// Value (SI units, or 0/1 for booleans).
    pub value: f64,
}

/// A ring buffer; sample number `s` (counting from 0 since the start) lives at
/// `s % capacity` while `s >= total - capacity`.
#[derive(Debug, Clone)]
pub(crate) struct Ring {
    buf: Vec<Sample>,
    capacity: usize,
    total: u64,
}

impl Ring {
    pub(crate) fn new(capacity: usize) -> Self {
        Ring { buf: Vec::with_capacity(capacity), capacity: capacity.max(1), total: 0 }
    }

    #[inline]
    pub(crate) fn push(&mut self, s: Sample) {
        if self.buf.len() < self.capacity {
            self.buf.push(s);
        } else {
            let i = (self.total % self.capacity as u64) as usize;
            if let Some(slot) = self.buf.get_mut(i) {
                *slot = s;
            }
        }
        self.total += 1;
    }

    /// Samples recorded since the start.
    pub(crate) fn total(&self) -> u64 {
        self.total
    }

    /// Sequence number of the oldest sample still held.
    pub(crate) fn first_seq(&self) -> u64 {
        self.total.saturating_sub(self.buf.len() as u64)
    }

    /// Sample number `seq`, if still held.
    pub(crate) fn get(&self, seq: u64) -> Option<Sample> {
        if seq < self.first_seq() || seq >= self.total {
            return None;
        }
        self.buf.get((seq % self.capacity as u64) as usize).copied()
    }

    /// Samples `from..total` still held, oldest first, and how many of the requested
    /// ones were already overwritten.
    pub(crate) fn since(&self, from: u64) -> (Vec<Sample>, u64) {
        let first = self.first_seq();
        let lost = first.saturating_sub(from);
        let start = from.max(first);
        ((start..self.total).filter_map(|s| self.get(s)).collect(), lost)
    }

    /// The newest sample.
    pub(crate) fn latest(&self) -> Option<Sample> {
        self.total.checked_sub(1).and_then(|s| self.get(s))
    }

    /// Samples with `from <= t <= to`, oldest first.
    pub(crate) fn window(&self, from: Duration, to: Duration) -> Vec<Sample> {
        (self.first_seq()..self.total)
            .filter_map(|s| self.get(s))
            .filter(|s| s.t >= from && s.t <= to)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    fn s(i: u64) -> Sample {
        Sample { t: Duration::from_millis(i), value: i as f64 }
    }

    #[test]
    fn wraps_and_reports_lost_samples() {
        let mut r = Ring::new(4);
        for i in 0..10 {
            r.push(s(i));
        }
        // 10 pushed into 4 slots: samples 6..=9 remain.
        assert_eq!(r.total(), 10);
        assert_eq!(r.first_seq(), 6);
        assert_eq!(r.get(5), None);
        assert_eq!(r.get(6), Some(s(6)));
        assert_eq!(r.latest(), Some(s(9)));
        let (v, lost) = r.since(3);
        assert_eq!(lost, 3); // 3, 4, 5 were overwritten
        assert_eq!(v, vec![s(6), s(7), s(8), s(9)]);
        let (v, lost) = r.since(8);
        assert_eq!((v, lost), (vec![s(8), s(9)], 0));
        assert_eq!(r.window(Duration::from_millis(7), Duration::from_millis(8)), vec![s(7), s(8)]);
    }
}
