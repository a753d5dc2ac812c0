//! Fault injection on any link: drop whole writes (a lost frame), corrupt bytes written and
//! bytes received at a given rate, with seeded random generators so a failing run can be
//! repeated.

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
    /// Probability that each byte, written or received, is replaced by a different random
    /// byte.
    pub corrupt_rate: f64,
    /// Seed of the random generators.
    pub seed: u64,
}

/// A fault rate that is not a probability.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("{name} must be within 0..=1, got {rate}")]
pub struct RateError {
    /// Which rate ("drop rate", "corrupt rate").
    pub name: &'static str,
    /// The rate given.
    pub rate: f64,
}

impl FaultConfig {
    /// True if it injects anything.
    pub fn is_active(&self) -> bool {
        self.drop_rate > 0.0 || self.corrupt_rate > 0.0
    }

    /// Checks that both rates are within 0..=1.
    pub fn check(&self) -> Result<(), RateError> {
        for (name, rate) in [("drop rate", self.drop_rate), ("corrupt rate", self.corrupt_rate)] {
            if !(0.0..=1.0).contains(&rate) {
                return Err(RateError { name, rate });
            }
        }
        Ok(())
    }
}

/// What the injector did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FaultStats {
    /// Writes dropped.
    pub dropped_writes: u64,
    /// Written bytes corrupted.
    pub corrupted_bytes: u64,
    /// Received bytes corrupted.
    pub corrupted_received: u64,
}

/// Injects faults into the bytes written through it and the bytes read through it. Each
/// direction draws from its own generator (seeded from the one seed), so the faults of one
/// direction do not depend on the traffic of the other.
pub struct FaultInjector<L> {
    inner: L,
    config: FaultConfig,
    tx_rng: SmallRng,
    rx_rng: SmallRng,
    stats: FaultStats,
    scratch: Vec<u8>,
}

/// Derives the receive generator's seed from the configured one.
const RX_SEED: u64 = 0x5eed;

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
            tx_rng: SmallRng::seed_from_u64(config.seed),
            rx_rng: SmallRng::seed_from_u64(config.seed ^ RX_SEED),
            config,
            stats: FaultStats::default(),
            scratch: Vec::new(),
        }
    }

    /// What was injected so far.
    pub fn stats(&self) -> FaultStats {
        self.stats
    }

    /// The wrapped link.
    pub fn inner(&self) -> &L {
        &self.inner
    }

    /// The wrapped link, mutably.
    pub fn inner_mut(&mut self) -> &mut L {
        &mut self.inner
    }
}

/// Replaces each byte of `bytes` with probability `rate` by a different one; returns how many.
fn corrupt(rng: &mut SmallRng, rate: f64, bytes: &mut [u8]) -> u64 {
    let mut n = 0;
    if rate > 0.0 {
        for b in bytes.iter_mut() {
            if rng.gen_bool(rate) {
                *b ^= rng.gen_range(1..=255u8);
                n += 1;
            }
        }
    }
    n
}

impl<L: Link> Link for FaultInjector<L> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        if self.config.drop_rate > 0.0 && self.tx_rng.gen_bool(self.config.drop_rate) {
            self.stats.dropped_writes += 1;
            tracing::debug!(bytes = bytes.len(), "fault injection: dropped a frame");
            return Ok(());
        }
        if self.config.corrupt_rate <= 0.0 {
            return self.inner.write_all(bytes);
        }
        self.scratch.clear();
        self.scratch.extend_from_slice(bytes);
        self.stats.corrupted_bytes += corrupt(&mut self.tx_rng, self.config.corrupt_rate, &mut self.scratch);
        self.inner.write_all(&self.scratch)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let n = self.inner.read(buf, timeout)?;
        let received = buf.get_mut(..n).unwrap_or_default();
        self.stats.corrupted_received += corrupt(&mut self.rx_rng, self.config.corrupt_rate, received);
        Ok(n)
    }

    fn describe(&self) -> String {
        format!("faulty({})", self.inner.describe())
    }

    pass_through!(discard_input, line);
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// Keeps what is written; every read receives 16 zero bytes.
    #[derive(Default)]
    struct Zeros(Vec<u8>);

    impl Link for Zeros {
        fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
            self.0.extend_from_slice(bytes);
            Ok(())
        }
        fn read(&mut self, buf: &mut [u8], _: Duration) -> io::Result<usize> {
            let n = buf.len().min(16);
            buf.iter_mut().take(n).for_each(|b| *b = 0);
            Ok(n)
        }
        fn discard_input(&mut self) -> io::Result<()> {
            Ok(())
        }
        fn line(&self) -> LineSettings {
            LineSettings::n81(9600)
        }
        fn describe(&self) -> String {
            "zeros".into()
        }
    }

    /// Writes `writes` zero frames of 16 bytes, then reads once: (written, received, stats).
    fn run(config: FaultConfig, writes: usize) -> (Vec<u8>, Vec<u8>, FaultStats) {
        let mut link = FaultInjector::new(Zeros::default(), config);
        for _ in 0..writes {
            link.write_all(&[0u8; 16]).unwrap();
        }
        let mut buf = [0u8; 64];
        let n = link.read(&mut buf, Duration::ZERO).unwrap();
        let stats = link.stats();
        (link.inner.0, buf.get(..n).unwrap().to_vec(), stats)
    }

    fn nonzero(bytes: &[u8]) -> u64 {
        bytes.iter().filter(|b| **b != 0).count() as u64
    }

    #[test]
    fn written_and_received_bytes_are_corrupted_and_a_seed_repeats_the_run() {
        let config = FaultConfig { drop_rate: 0.0, corrupt_rate: 0.25, seed: 7 };
        let (sent, received, stats) = run(config, 4);
        assert_eq!((sent.len(), received.len()), (64, 16));
        assert_eq!(nonzero(&sent), stats.corrupted_bytes);
        assert_eq!(nonzero(&received), stats.corrupted_received);
        assert!(stats.corrupted_bytes > 0 && stats.corrupted_received > 0, "{stats:?}");
        assert_eq!(run(config, 4), (sent, received.clone(), stats), "same seed, same faults");
        assert_ne!(run(FaultConfig { seed: 8, ..config }, 4).1, received, "another seed, other faults");
    }

    #[test]
    fn the_faults_of_one_direction_do_not_depend_on_the_other() {
        let config = FaultConfig { drop_rate: 0.0, corrupt_rate: 0.25, seed: 3 };
        let (_, quiet, _) = run(config, 0);
        let (_, after_writes, _) = run(config, 5);
        let (sent, after_drops, stats) = run(FaultConfig { drop_rate: 1.0, ..config }, 3);
        assert_eq!((sent.len(), stats.dropped_writes), (0, 3));
        assert_eq!(quiet, after_writes);
        assert_eq!(quiet, after_drops);
    }

    #[test]
    fn rates_are_checked() {
        assert!(FaultConfig { drop_rate: 1.5, ..FaultConfig::default() }.check().is_err());
        assert!(FaultConfig { corrupt_rate: -0.1, ..FaultConfig::default() }.check().is_err());
        assert!(FaultConfig { drop_rate: 1.0, corrupt_rate: 0.0, seed: 1 }.check().is_ok());
        assert!(!FaultConfig::default().is_active());
    }
}
