//! Per-class statistics: latency histograms with percentiles, overruns, CPU time.

use std::time::Duration;

/// Histogram resolution: one bucket per microsecond.
const BUCKETS_US: usize = 5_000;

/// A histogram of durations with 1 us buckets up to 5 ms (longer values land in one
/// overflow bucket) and the exact maximum.
#[derive(Debug, Clone)]
pub struct Histogram {
    counts: Vec<u64>,
    overflow: u64,
    total: u64,
    max: Duration,
    sum_ns: u128,
}

impl Default for Histogram {
    fn default() -> Self {
        Histogram { counts: vec![0; BUCKETS_US], overflow: 0, total: 0, max: Duration::ZERO, sum_ns: 0 }
    }
}

/// Percentiles of a histogram.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Percentiles {
    /// Number of samples.
    pub count: u64,
    /// Median (1 us resolution: the bucket's lower bound).
    pub p50: Duration,
    /// 99th percentile (same resolution).
    pub p99: Duration,
    /// 99.9th percentile (same resolution).
    pub p999: Duration,
    /// Exact maximum.
    pub max: Duration,
    /// Mean.
    pub mean: Duration,
}

impl Histogram {
    /// Adds one sample.
    pub fn record(&mut self, d: Duration) {
        let us = usize::try_from(d.as_micros()).unwrap_or(usize::MAX);
        match self.counts.get_mut(us) {
            Some(c) => *c += 1,
            None => self.overflow += 1,
        }
        self.total += 1;
        self.sum_ns += d.as_nanos();
        if d > self.max {
            self.max = d;
        }
    }

    /// Number of samples.
    pub fn count(&self) -> u64 {
        self.total
    }

    /// The smallest bucket value below which at least `q` (0..=1) of the samples lie;
    /// samples in the overflow bucket report the maximum.
    pub fn quantile(&self, q: f64) -> Duration {
        if self.total == 0 {
            return Duration::ZERO;
        }
        // Rank of the sample (1-based), rounded up: p50 of 4 samples is the 2nd.
        let rank = ((q.clamp(0.0, 1.0) * self.total as f64).ceil() as u64).max(1);
        let mut seen = 0u64;
        for (us, c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                return Duration::from_micros(us as u64);
            }
        }
        self.max
    }

    /// p50, p99, p99.9, max and mean.
    pub fn percentiles(&self) -> Percentiles {
        let mean = if self.total == 0 {
            Duration::ZERO
        } else {
            Duration::from_nanos(u64::try_from(self.sum_ns / u128::from(self.total)).unwrap_or(u64::MAX))
        };
        Percentiles {
            count: self.total,
            p50: self.quantile(0.5),
            p99: self.quantile(0.99),
            p999: self.quantile(0.999),
            max: self.max,
            mean,
        }
    }
}

/// What a task class is doing.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ClassState {
    /// Cycles run.
    Running,
    /// Cycles are suspended after `degrade()` was called on every task (consecutive
    /// overruns or an operator's request); `resume()` leaves this state.
    Degraded {
        /// Why.
        reason: String,
    },
    /// The thread has not started a cycle for ten periods (a task is blocked).
    Stalled,
    /// The thread ended.
    Stopped,
}

/// A snapshot of one task class.
#[derive(Debug, Clone, PartialEq)]
pub struct ClassStats {
    /// Class name (also the thread name after `motus-`).
    pub name: String,
    /// Period.
    pub period: Duration,
    /// Current state.
    pub state: ClassState,
    /// Cycles run since the last statistics reset.
    pub cycles: u64,
    /// Releases skipped because the thread was still busy or woke too late.
    pub missed_cycles: u64,
    /// Overrun events (a cycle finished after the next release, or a release was missed).
    pub overruns: u64,
    /// Current run of consecutive overruns.
    pub consecutive_overruns: u32,
    /// Times the class degraded.
    pub degradations: u64,
    /// Task cycles that returned an error.
    pub task_errors: u64,
    /// Start lateness (actual start - release time).
    pub lateness: Percentiles,
    /// Execution time of all the class's tasks in one cycle.
    pub execution: Percentiles,
    /// CPU time of the class thread since the last reset (user + system).
    pub cpu_time: Duration,
    /// Wall time since the last reset.
    pub elapsed: Duration,
}

impl ClassStats {
    /// CPU load of the class thread in percent of one core.
    pub fn cpu_percent(&self) -> f64 {
        if self.elapsed.is_zero() {
            0.0
        } else {
            100.0 * self.cpu_time.as_secs_f64() / self.elapsed.as_secs_f64()
        }
    }

    /// One line for logs and examples.
    pub fn summary(&self) -> String {
        format!(
            "{} ({:?}): {:?}, {} cycles, lateness p50 {} us p99 {} us max {} us, exec p50 {} us p99 {} us max {} us, {} overruns, {} missed, CPU {:.1} %",
            self.name,
            self.period,
            self.state,
            self.cycles,
            self.lateness.p50.as_micros(),
            self.lateness.p99.as_micros(),
            self.lateness.max.as_micros(),
            self.execution.p50.as_micros(),
            self.execution.p99.as_micros(),
            self.execution.max.as_micros(),
            self.overruns,
            self.missed_cycles,
            self.cpu_percent()
        )
    }
}

/// CPU time (user + system) of the calling thread, where the OS reports it.
pub fn thread_cpu_time() -> Option<Duration> {
    use nix::sys::resource::{getrusage, UsageWho};
    let u = getrusage(UsageWho::RUSAGE_THREAD).ok()?;
    let tv = |t: nix::sys::time::TimeVal| {
        Duration::from_secs(u64::try_from(t.tv_sec()).unwrap_or(0))
            + Duration::from_micros(u64::try_from(t.tv_usec()).unwrap_or(0))
    };
    Some(tv(u.user_time()) + tv(u.system_time()))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn percentiles_of_known_samples() {
        // Samples 1..=100 us: p50 is the 50th sample (50 us), p99 the 99th (99 us),
        // mean 50.5 us, max 100 us.
        let mut h = Histogram::default();
        for us in 1..=100u64 {
            h.record(Duration::from_micros(us));
        }
        let p = h.percentiles();
        assert_eq!(p.count, 100);
        assert_eq!(p.p50, Duration::from_micros(50));
        assert_eq!(p.p99, Duration::from_micros(99));
        assert_eq!(p.p999, Duration::from_micros(100));
        assert_eq!(p.max, Duration::from_micros(100));
        assert_eq!(p.mean, Duration::from_nanos(50_500));
    }

    #[test]
    fn overflow_reports_max_and_empty_is_zero() {
        let mut h = Histogram::default();
        assert_eq!(h.percentiles(), Percentiles::default());
        h.record(Duration::from_micros(3));
        h.record(Duration::from_millis(20));
        assert_eq!(h.quantile(0.5), Duration::from_micros(3));
        assert_eq!(h.quantile(1.0), Duration::from_millis(20));
    }

    #[test]
    fn cpu_time_advances_while_busy_and_never_exceeds_wall_time() {
        let before = thread_cpu_time().unwrap();
        let start = std::time::Instant::now();
        let mut x = 0u64;
        // Busy until this thread has used 20 ms of CPU (the machine may be loaded, so wall
        // time can be longer), at most 10 s.
        let mut used = Duration::ZERO;
        while used < Duration::from_millis(20) && start.elapsed() < Duration::from_secs(10) {
            x = x.wrapping_add(std::hint::black_box(1));
            used = thread_cpu_time().unwrap() - before;
        }
        std::hint::black_box(x);
        let wall = start.elapsed();
        assert!(used >= Duration::from_millis(20), "{used:?} in {wall:?}");
        // One thread cannot use more CPU than wall time (plus one accounting tick).
        assert!(used <= wall + Duration::from_millis(10), "{used:?} > {wall:?}");
    }
}
