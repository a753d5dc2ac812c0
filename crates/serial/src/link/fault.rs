//! Fault injection on any link: drop whole writes (a lost frame) or corrupt bytes at a
//! given rate, with a seeded random generator so a failing run can be repeated.

use super::{LineSettings, Link};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use std::io;
use std::time::Duration;

/// Fault rates (probabilities 0..=1).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FaultConfig {
    /// Probability that one `write_all` (one frame) is dropped entirely.
    pub drop_rate: f64,
    /// Probability that each written byte is replaced by a different random byte.
    pub corrupt_rate: f64,
    /// Seed of the random generator.
    pub seed: u64,
}

/// What the injector did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FaultStats {
    /// Writes dropped.
    pub dropped_writes: u64,
    /// Bytes corrupted.
    pub corrupted_bytes: u64,
}

/// Injects faults into the bytes written through it (reads pass unchanged).
pub struct FaultInjector<L> {
    inner: L,
    config: FaultConfig,
    rng: SmallRng,
    stats: FaultStats,
    scratch: Vec<u8>,
}

impl<L: Link> FaultInjector<L> {
    /// Wraps `inner`. Rates outside 0..=1 are clamped.
    pub fn new(inner: L, config: FaultConfig) -> Self {
        let config = FaultConfig {
            drop_rate: config.drop_rate.clamp(0.0, 1.0),
            corrupt_rate: config.corrupt_rate.clamp(0.0, 1.0),
            seed: config.seed,
        };
        FaultInjector {
            inner,
            rng: SmallRng::seed_from_u64(config.seed),
            config,
            stats: FaultStats::default(),
            scratch: Vec::new(),
        }
    }

    /// What was injected so far.
    pub fn stats(&self) -> FaultStats {
        self.stats
    }
}

impl<L: Link> Link for FaultInjector<L> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        if self.config.drop_rate > 0.0 && self.rng.gen_bool(self.config.drop_rate) {
            self.stats.dropped_writes += 1;
            tracing::debug!(bytes = bytes.len(), "fault injection: dropped a frame");
            return Ok(());
        }
        if self.config.corrupt_rate <= 0.0 {
            return self.inner.write_all(bytes);
        }
        self.scratch.clear();
        self.scratch.extend_from_slice(bytes);
        for b in self.scratch.iter_mut() {
            if self.rng.gen_bool(self.config.corrupt_rate) {
                *b ^= self.rng.gen_range(1..=255u8);
                self.stats.corrupted_bytes += 1;
            }
        }
        self.inner.write_all(&self.scratch)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        self.inner.read(buf, timeout)
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.inner.discard_input()
    }

    fn line(&self) -> LineSettings {
        self.inner.line()
    }

    fn describe(&self) -> String {
        format!("faulty({})", self.inner.describe())
    }
}
