//! Statistics of the Managing Node: cycle-start jitter, PRes misses, CNs lost and found.

use std::collections::BTreeMap;

/// Percentiles of a set of durations (ns).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Percentiles {
    /// Number of samples.
    pub count: usize,
    /// Median.
    pub p50: u64,
    /// 99th percentile.
    pub p99: u64,
    /// Largest sample.
    pub max: u64,
}

impl Percentiles {
    /// Percentiles of `samples` (nearest-rank).
    pub fn of(samples: &[u64]) -> Self {
        let mut s = samples.to_vec();
        s.sort_unstable();
        let rank = |q: f64| -> u64 {
            if s.is_empty() {
                return 0;
            }
            let i = ((q * s.len() as f64).ceil() as usize).clamp(1, s.len()) - 1;
            s.get(i).copied().unwrap_or(0)
        };
        Self { count: s.len(), p50: rank(0.5), p99: rank(0.99), max: s.last().copied().unwrap_or(0) }
    }
}

/// The most recent samples of a figure, at most [`SampleWindow::CAPACITY`]: a segment that
/// runs for days keeps its memory flat (a 1 ms cycle adds 6,000 samples a second). The
/// whole window is allocated and written when it is made (by the thread that makes the
/// statistics), so that the MN's cycle thread never grows a buffer or faults in a fresh page.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SampleWindow {
    /// `CAPACITY` slots; the first `len` hold samples.
    samples: Vec<u64>,
    len: usize,
    /// Where the next sample goes once the window is full.
    next: usize,
    /// Samples ever pushed.
    total: u64,
}

impl SampleWindow {
    /// Samples kept (the most recent; 512 KiB).
    pub const CAPACITY: usize = 1 << 16;

    /// Adds a sample, replacing the oldest when the window is full.
    pub fn push(&mut self, sample: u64) {
        self.total += 1;
        if self.len < Self::CAPACITY {
            if let Some(slot) = self.samples.get_mut(self.len) {
                *slot = sample;
            }
            self.len += 1;
            return;
        }
        if let Some(slot) = self.samples.get_mut(self.next) {
            *slot = sample;
        }
        self.next = (self.next + 1) % Self::CAPACITY;
    }

    /// The samples kept (in no particular order).
    pub fn samples(&self) -> &[u64] {
        self.samples.get(..self.len).unwrap_or(&[])
    }

    /// Samples ever pushed (kept or not).
    pub fn total(&self) -> u64 {
        self.total
    }

    /// Percentiles of the samples kept.
    pub fn percentiles(&self) -> Percentiles {
        Percentiles::of(self.samples())
    }
}

impl Default for SampleWindow {
    fn default() -> Self {
        // Not zeros: a zeroed allocation comes from fresh pages that are only faulted in when
        // first written; a non-zero fill writes (and so faults in) every page now.
        Self { samples: vec![u64::MAX; Self::CAPACITY], len: 0, next: 0, total: 0 }
    }
}

/// What happened to a CN, as the Managing Node saw it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CnChange {
    /// Its PRes was missed [`super::MnConfig::lost_after`] times in a row: taken out of the
    /// cycle, invited to identify itself again.
    Lost,
    /// A lost CN answered an IdentRequest: polled again (and booted again if it has to be).
    Found,
}

/// A CN lost or found, in the cycle it happened.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CnEvent {
    /// The full cycle it happened in ([`MnStats::cycles`] at the time: 1 for the first).
    pub cycle: u64,
    /// The CN.
    pub node: u8,
    /// What happened.
    pub change: CnChange,
}

/// What the Managing Node counted.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct MnStats {
    /// Full cycles (with SoC) started.
    pub cycles: u64,
    /// Cycles started while the MN was OPERATIONAL.
    pub operational_cycles: u64,
    /// Reduced PreOp1 cycles (SoA only).
    pub reduced_cycles: u64,
    /// Lateness of each full cycle start after its deadline (ns), SoC send time (the most
    /// recent cycles).
    pub start_late_ns: SampleWindow,
    /// Cycles whose work overran the next deadline (that deadline was skipped).
    pub overruns: u64,
    /// PReq that got no PRes before the PRes time-out, per node (counted in OPERATIONAL).
    pub pres_missed: BTreeMap<u8, u64>,
    /// PRes sent by a node but received after its time-out.
    pub pres_late: u64,
    /// PReq -> PRes round-trip times in OPERATIONAL (ns; the most recent).
    pub pres_rtt_ns: SampleWindow,
    /// Frames received that failed to decode.
    pub decode_errors: u64,
    /// Send errors.
    pub send_errors: u64,
    /// CNs lost and found, oldest first (the first [`MnStats::CN_EVENTS`] kept).
    pub cn_events: Vec<CnEvent>,
}

impl MnStats {
    /// CN events kept (a CN that keeps coming and going must not grow the statistics).
    pub const CN_EVENTS: usize = 1024;

    /// Records a CN event in cycle [`MnStats::cycles`].
    pub(crate) fn cn_event(&mut self, node: u8, change: CnChange) {
        if self.cn_events.len() < Self::CN_EVENTS {
            self.cn_events.push(CnEvent { cycle: self.cycles, node, change });
        }
    }

    /// Percentiles of the cycle start lateness.
    pub fn jitter(&self) -> Percentiles {
        self.start_late_ns.percentiles()
    }

    /// Percentiles of the PReq -> PRes round trip.
    pub fn rtt(&self) -> Percentiles {
        self.pres_rtt_ns.percentiles()
    }

    /// Total PRes misses over all nodes.
    pub fn total_missed(&self) -> u64 {
        self.pres_missed.values().sum()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn nearest_rank_percentiles() {
        let v: Vec<u64> = (1..=100).collect();
        let p = Percentiles::of(&v);
        assert_eq!((p.count, p.p50, p.p99, p.max), (100, 50, 99, 100));
        assert_eq!(Percentiles::of(&[]), Percentiles::default());
    }

    #[test]
    fn a_window_keeps_the_most_recent_samples_only() {
        let mut w = SampleWindow::default();
        let n = SampleWindow::CAPACITY as u64 + 10;
        for i in 0..n {
            w.push(i);
        }
        assert_eq!(w.samples().len(), SampleWindow::CAPACITY);
        assert_eq!(w.total(), n);
        assert!(!w.samples().contains(&9), "the oldest were replaced");
        assert_eq!(w.percentiles().max, n - 1);
    }
}
