//! What the scheduler achieved: cycle times (mean, p99, max) against the requested cycle
//! and the wire limit, missed cycles (overruns), missed and rejected answers per slave,
//! and the line utilisation at the configured baud rate.

use std::collections::VecDeque;
use std::fmt;
use std::time::{Duration, Instant};

use motus_nfv2_protocol::wire_time;

/// Cycle durations kept for the percentiles (the newest ones).
const KEPT_CYCLES: usize = 1 << 17;

/// Counters of one slave.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SlaveStats {
    /// Slave address.
    pub address: u8,
    /// Frames sent to it.
    pub exchanges: u64,
    /// Valid answers used.
    pub answers: u64,
    /// Expected answers that did not come, came corrupt or with the wrong shape: each is
    /// a missed sample for its cycle.
    pub missed: u64,
    /// Answers whose position failed the plausibility gate (not used).
    pub rejected: u64,
}

/// The scheduler's statistics over a window.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleStats {
    /// Cycles completed.
    pub cycles: u64,
    /// Length of the window.
    pub window: Duration,
    /// The cycle asked for.
    pub requested: Duration,
    /// The shortest cycle the line allows for the scheduler's steady frames.
    pub min_cycle: Duration,
    /// `requested >= min_cycle`.
    pub feasible: bool,
    /// Mean time between cycle starts.
    pub mean: Duration,
    /// 99th percentile of the time between cycle starts.
    pub p99: Duration,
    /// Longest time between cycle starts.
    pub max: Duration,
    /// Cycles whose exchanges outlasted the cycle period (the next one started late).
    pub overruns: u64,
    /// Expected answers missed over all slaves.
    pub missed_answers: u64,
    /// Cycles with at least one missed answer.
    pub cycles_with_missed: u64,
    /// Answers rejected by the plausibility checks.
    pub rejected_values: u64,
    /// Per slave.
    pub slaves: Vec<SlaveStats>,
    /// Bytes sent and received.
    pub bytes: u64,
    /// Wire time of those bytes at the baud rate.
    pub wire_busy: Duration,
    /// Fraction of the window the line carried bytes (against the wire limit).
    pub utilisation: f64,
}

impl CycleStats {
    /// How close the achieved cycle is to the wire limit: `min_cycle / mean` (1.0 = at
    /// the limit; 0.9 = 10 % slower than the line allows).
    #[must_use]
    pub fn efficiency(&self) -> f64 {
        let mean = self.mean.as_secs_f64();
        if mean > 0.0 {
            self.min_cycle.as_secs_f64() / mean
        } else {
            0.0
        }
    }
}

impl fmt::Display for CycleStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let ms = |d: Duration| d.as_secs_f64() * 1000.0;
        write!(
            f,
            "{} cycles in {:.1} s: mean {:.3} ms, p99 {:.3} ms, max {:.3} ms (requested {:.3} ms, wire limit {:.3} ms{}); \
             {} overrun(s), {} missed answer(s) in {} cycle(s), {} rejected value(s); line utilisation {:.1} %",
            self.cycles,
            self.window.as_secs_f64(),
            ms(self.mean),
            ms(self.p99),
            ms(self.max),
            ms(self.requested),
            ms(self.min_cycle),
            if self.feasible { "" } else { ", requested cycle IMPOSSIBLE" },
            self.overruns,
            self.missed_answers,
            self.cycles_with_missed,
            self.rejected_values,
            self.utilisation * 100.0
        )
    }
}

/// Collects the statistics (inside the scheduler's shared state).
#[derive(Debug, Clone)]
pub(crate) struct Recorder {
    since: Instant,
    last_start: Option<Instant>,
    durations: VecDeque<Duration>,
    cycles: u64,
    overruns: u64,
    cycles_with_missed: u64,
    bytes: u64,
    pub(crate) slaves: Vec<SlaveStats>,
}

impl Recorder {
    /// A window starting at `now`.
    pub(crate) fn new(addresses: &[u8], now: Instant) -> Self {
        Recorder {
            since: now,
            last_start: None,
            durations: VecDeque::with_capacity(1024),
            cycles: 0,
            overruns: 0,
            cycles_with_missed: 0,
            bytes: 0,
            slaves: addresses
                .iter()
                .map(|&address| SlaveStats { address, ..SlaveStats::default() })
                .collect(),
        }
    }

    /// Restarts the window at `now`.
    pub(crate) fn reset(&mut self, now: Instant) {
        let addresses: Vec<u8> = self.slaves.iter().map(|s| s.address).collect();
        *self = Recorder::new(&addresses, now);
    }

    /// A cycle starts at `at`.
    pub(crate) fn cycle_started(&mut self, at: Instant) {
        if let Some(last) = self.last_start {
            if self.durations.len() == KEPT_CYCLES {
                self.durations.pop_front();
            }
            self.durations.push_back(at.saturating_duration_since(last));
        }
        self.last_start = Some(at);
    }

    /// A cycle ended; `overran` if its exchanges outlasted the period, `missed` if an
    /// answer was missed.
    pub(crate) fn cycle_ended(&mut self, overran: bool, missed: bool) {
        self.cycles += 1;
        self.overruns += u64::from(overran);
        self.cycles_with_missed += u64::from(missed);
    }

    pub(crate) fn slave(&mut self, address: u8) -> Option<&mut SlaveStats> {
        self.slaves.iter_mut().find(|s| s.address == address)
    }

    pub(crate) fn bytes(&mut self, n: usize) {
        self.bytes += n as u64;
    }

    /// The statistics of the window up to `now`.
    pub(crate) fn snapshot(
        &self,
        requested: Duration,
        min_cycle: Duration,
        baud: u32,
        now: Instant,
    ) -> CycleStats {
        let mut sorted: Vec<Duration> = self.durations.iter().copied().collect();
        sorted.sort_unstable();
        let n = sorted.len();
        let mean = if n > 0 {
            sorted.iter().sum::<Duration>() / u32::try_from(n).unwrap_or(u32::MAX)
        } else {
            Duration::ZERO
        };
        // Nearest rank: the smallest value with at least 99 % of the cycles at or below it.
        let p99 =
            (n * 99).div_ceil(100).checked_sub(1).and_then(|i| sorted.get(i)).copied().unwrap_or_default();
        let window = now.saturating_duration_since(self.since);
        let wire_busy = wire_time(usize::try_from(self.bytes).unwrap_or(usize::MAX), baud);
        let missed_answers = self.slaves.iter().map(|s| s.missed).sum();
        let rejected_values = self.slaves.iter().map(|s| s.rejected).sum();
        CycleStats {
            cycles: self.cycles,
            window,
            requested,
            min_cycle,
            feasible: requested >= min_cycle,
            mean,
            p99,
            max: sorted.last().copied().unwrap_or_default(),
            overruns: self.overruns,
            missed_answers,
            cycles_with_missed: self.cycles_with_missed,
            rejected_values,
            slaves: self.slaves.clone(),
            bytes: self.bytes,
            wire_busy,
            utilisation: if window.is_zero() { 0.0 } else { wire_busy.as_secs_f64() / window.as_secs_f64() },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_and_counters() {
        let t0 = motus_clock::VirtualClock::new().base();
        let mut r = Recorder::new(&[1, 2], t0);
        for i in 0..=100u32 {
            // 99 cycles of 10 ms, then one of 30 ms.
            let at = t0 + Duration::from_millis(u64::from(i) * 10 + if i == 100 { 20 } else { 0 });
            r.cycle_started(at);
            r.cycle_ended(i == 100, i % 50 == 0);
        }
        if let Some(s) = r.slave(2) {
            s.missed = 3;
        }
        r.bytes(5760);
        let s = r.snapshot(
            Duration::from_millis(10),
            Duration::from_millis(9),
            57_600,
            t0 + Duration::from_secs(2),
        );
        assert_eq!(s.cycles, 101);
        assert_eq!(s.max, Duration::from_millis(30));
        assert_eq!(s.p99, Duration::from_millis(10));
        assert_eq!(s.mean, Duration::from_micros(10_200));
        assert_eq!((s.overruns, s.cycles_with_missed, s.missed_answers), (1, 3, 3));
        assert_eq!(s.wire_busy, Duration::from_secs(1));
        assert_eq!(s.window, Duration::from_secs(2));
        assert!((s.utilisation - 0.5).abs() < 1e-9);
        assert!((s.efficiency() - 9.0 / 10.2).abs() < 1e-9);
    }
}
