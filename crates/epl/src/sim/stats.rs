//! Statistics of the Managing Node: cycle-start jitter and PRes misses.

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

/// What the Managing Node counted.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct MnStats {
    /// Full cycles (with SoC) started.
    pub cycles: u64,
    /// Cycles started while the MN was OPERATIONAL.
    pub operational_cycles: u64,
    /// Reduced PreOp1 cycles (SoA only).
    pub reduced_cycles: u64,
    /// Lateness of each full cycle start after its deadline (ns), SoC send time.
    pub start_late_ns: Vec<u64>,
    /// Cycles whose work overran the next deadline (that deadline was skipped).
    pub overruns: u64,
    /// PReq that got no PRes before the PRes time-out, per node (counted in OPERATIONAL).
    pub pres_missed: BTreeMap<u8, u64>,
    /// PRes sent by a node but received after its time-out.
    pub pres_late: u64,
    /// PReq -> PRes round-trip times in OPERATIONAL (ns).
    pub pres_rtt_ns: Vec<u64>,
    /// Frames received that failed to decode.
    pub decode_errors: u64,
    /// Send errors.
    pub send_errors: u64,
}

impl MnStats {
    /// Percentiles of the cycle start lateness.
    pub fn jitter(&self) -> Percentiles {
        Percentiles::of(&self.start_late_ns)
    }

    /// Percentiles of the PReq -> PRes round trip.
    pub fn rtt(&self) -> Percentiles {
        Percentiles::of(&self.pres_rtt_ns)
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
}
