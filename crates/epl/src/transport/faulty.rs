//! [`FaultyLink`]: a decorator that injects faults on send with a seeded generator, so test
//! runs are reproducible: drop a frame, delay it (the sender sleeps on the link's clock before
//! sending), or corrupt it (one random byte after the Ethernet header is XORed with a non-zero
//! value). Every fault is counted.

use std::io;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

use motus_clock::{SharedClock, SystemClock};
use motus_epl_protocol::MacAddr;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use super::EthLink;

/// Fault probabilities (0.0 to 1.0, per sent frame) and the delay length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaultConfig {
    /// Seed of the generator.
    pub seed: u64,
    /// Probability that a frame is dropped.
    pub drop: f64,
    /// Probability that a frame is delayed by [`FaultConfig::delay_by`].
    pub delay: f64,
    /// Delay applied to a delayed frame.
    pub delay_by: Duration,
    /// Probability that a frame is corrupted.
    pub corrupt: f64,
}

impl Default for FaultConfig {
    fn default() -> Self {
        Self { seed: 0, drop: 0.0, delay: 0.0, delay_by: Duration::from_micros(500), corrupt: 0.0 }
    }
}

/// Counts of the faults injected so far.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FaultCounters {
    /// Frames passed to `send`.
    pub sent: u64,
    /// Frames dropped.
    pub dropped: u64,
    /// Frames delayed.
    pub delayed: u64,
    /// Frames corrupted.
    pub corrupted: u64,
}

/// Injects faults into the frames sent on an inner link (see the module documentation).
#[derive(Debug)]
pub struct FaultyLink<L> {
    inner: L,
    config: FaultConfig,
    clock: SharedClock,
    rng: Mutex<SmallRng>,
    sent: AtomicU64,
    dropped: AtomicU64,
    delayed: AtomicU64,
    corrupted: AtomicU64,
}

impl<L: EthLink> FaultyLink<L> {
    /// Wraps `inner` (delays on the system clock).
    pub fn new(inner: L, config: FaultConfig) -> Self {
        Self::with_clock(inner, config, SystemClock::shared())
    }

    /// Wraps `inner`, delaying frames on `clock` (the segment's).
    pub fn with_clock(inner: L, config: FaultConfig, clock: SharedClock) -> Self {
        Self {
            inner,
            config,
            clock,
            rng: Mutex::new(SmallRng::seed_from_u64(config.seed)),
            sent: AtomicU64::new(0),
            dropped: AtomicU64::new(0),
            delayed: AtomicU64::new(0),
            corrupted: AtomicU64::new(0),
        }
    }

    /// The faults injected so far.
    pub fn counters(&self) -> FaultCounters {
        FaultCounters {
            sent: self.sent.load(Ordering::Relaxed),
            dropped: self.dropped.load(Ordering::Relaxed),
            delayed: self.delayed.load(Ordering::Relaxed),
            corrupted: self.corrupted.load(Ordering::Relaxed),
        }
    }
}

impl<L: EthLink> EthLink for FaultyLink<L> {
    fn send(&self, frame: &[u8]) -> io::Result<()> {
        self.sent.fetch_add(1, Ordering::Relaxed);
        let (drop, delay, corrupt_at) = {
            let mut rng = self.rng.lock().unwrap_or_else(PoisonError::into_inner);
            let drop = rng.gen_bool(self.config.drop.clamp(0.0, 1.0));
            let delay = rng.gen_bool(self.config.delay.clamp(0.0, 1.0));
            let corrupt = rng.gen_bool(self.config.corrupt.clamp(0.0, 1.0)) && frame.len() > 14;
            let at = corrupt.then(|| (rng.gen_range(14..frame.len()), rng.gen_range(1..=255u8)));
            (drop, delay, at)
        };
        if drop {
            self.dropped.fetch_add(1, Ordering::Relaxed);
            return Ok(());
        }
        if delay {
            self.delayed.fetch_add(1, Ordering::Relaxed);
            self.clock.sleep(self.config.delay_by);
        }
        match corrupt_at {
            Some((i, x)) => {
                self.corrupted.fetch_add(1, Ordering::Relaxed);
                let mut copy = frame.to_vec();
                if let Some(b) = copy.get_mut(i) {
                    *b ^= x;
                }
                self.inner.send(&copy)
            }
            None => self.inner.send(frame),
        }
    }

    fn recv(&self, buf: &mut [u8], timeout: Duration) -> io::Result<Option<(usize, Instant)>> {
        self.inner.recv(buf, timeout)
    }

    fn mac(&self) -> MacAddr {
        self.inner.mac()
    }

    fn describe(&self) -> String {
        format!("faulty({})", self.inner.describe())
    }
}
