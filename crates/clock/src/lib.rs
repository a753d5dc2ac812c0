//! # motus-clock — time is an input
//!
//! Every runtime that waits (an SDO client's time-out, a drive's enable or homing wait, a
//! heartbeat consumer) asks a [`Clock`] for the time and sleeps through it, instead of
//! calling [`Instant::now`] and [`std::thread::sleep`]. Two clocks exist:
//!
//! - [`SystemClock`]: the real one (monotonic time, real sleeps). The default everywhere.
//! - [`VirtualClock`]: a deterministic one for tests. Time starts at a base [`Instant`]
//!   taken when the clock is made and moves only when someone advances it;
//!   [`Clock::sleep`] advances it at once. A test that simulates a minute of motion takes
//!   milliseconds of wall time, and its results do not depend on the host's load.
//!
//! ## When virtual time works
//!
//! Virtual time is deterministic when the driver and the simulated device run on **one
//! thread of control**: the driver sends a frame, the in-process link hands it to the
//! simulator *synchronously*, the simulator answers at the same virtual instant, and the
//! answer is there when the driver looks for it (a "pair", as smoltcp's `tests/netsim.rs`
//! and quinn-proto's test `Pair` do). Only the driver's thread advances the clock (by
//! sleeping); other threads (a receive thread that only moves answers along) may read it
//! but never sleep on it. Waiting for a message that an in-process peer has already
//! produced is bounded by a *wall-clock* liveness time-out (the message normally arrives
//! in microseconds); when it does not arrive, the waiter jumps the virtual clock to its
//! deadline with [`Clock::sleep_until`] and reports the time-out on virtual time.
//!
//! A peer that runs its own thread with its own real-time loop (a simulator served over
//! TCP, a pty, a veth pair) cannot share a virtual clock: such tests run on
//! [`SystemClock`] with generous liveness time-outs.

#![forbid(unsafe_code)]

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A source of time and a way to wait for it.
pub trait Clock: Send + Sync + std::fmt::Debug {
    /// The current time.
    fn now(&self) -> Instant;

    /// Waits `duration` (a virtual clock advances by it at once).
    fn sleep(&self, duration: Duration);

    /// Waits until `deadline` (returns at once when it has passed).
    fn sleep_until(&self, deadline: Instant) {
        let left = deadline.saturating_duration_since(self.now());
        if !left.is_zero() {
            self.sleep(left);
        }
    }

    /// The time elapsed since `earlier` (zero if `earlier` is later than now).
    fn elapsed(&self, earlier: Instant) -> Duration {
        self.now().saturating_duration_since(earlier)
    }
}

/// A shared clock, as runtimes hold it.
pub type SharedClock = Arc<dyn Clock>;

/// The system clock: [`Instant::now`] and [`std::thread::sleep`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SystemClock;

impl SystemClock {
    /// The system clock, shared (the default of every runtime that takes a clock).
    pub fn shared() -> SharedClock {
        Arc::new(SystemClock)
    }
}

impl Clock for SystemClock {
    fn now(&self) -> Instant {
        Instant::now()
    }

    fn sleep(&self, duration: Duration) {
        std::thread::sleep(duration);
    }
}

/// A deterministic clock: time starts at a base instant and moves only when advanced
/// ([`VirtualClock::advance`], [`Clock::sleep`], [`Clock::sleep_until`]). Clones share the
/// same time.
#[derive(Debug, Clone)]
pub struct VirtualClock {
    base: Instant,
    /// Nanoseconds since `base`.
    offset_ns: Arc<AtomicU64>,
}

impl Default for VirtualClock {
    fn default() -> Self {
        Self::new()
    }
}

impl VirtualClock {
    /// A clock at its base instant (taken now; it does not move by itself).
    pub fn new() -> Self {
        Self { base: Instant::now(), offset_ns: Arc::new(AtomicU64::new(0)) }
    }

    /// This clock as a [`SharedClock`] (sharing its time).
    pub fn shared(&self) -> SharedClock {
        Arc::new(self.clone())
    }

    /// The base instant (time zero of this clock).
    pub fn base(&self) -> Instant {
        self.base
    }

    /// Virtual time elapsed since the base instant.
    pub fn since_base(&self) -> Duration {
        Duration::from_nanos(self.offset_ns.load(Ordering::Acquire))
    }

    /// Moves time forward by `by`.
    pub fn advance(&self, by: Duration) {
        let ns = u64::try_from(by.as_nanos()).unwrap_or(u64::MAX);
        // Saturating add (an overflow would need 584 years of virtual time).
        let _ = self
            .offset_ns
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |cur| Some(cur.saturating_add(ns)));
    }
}

impl Clock for VirtualClock {
    fn now(&self) -> Instant {
        self.base + self.since_base()
    }

    fn sleep(&self, duration: Duration) {
        self.advance(duration);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn virtual_time_moves_only_when_advanced() {
        let c = VirtualClock::new();
        let t0 = c.now();
        assert_eq!(t0, c.base());
        std::thread::sleep(Duration::from_millis(2));
        assert_eq!(c.now(), t0, "wall time does not move it");
        c.sleep(Duration::from_secs(30));
        assert_eq!(c.now() - t0, Duration::from_secs(30));
        c.sleep_until(t0 + Duration::from_secs(10));
        assert_eq!(c.since_base(), Duration::from_secs(30), "a past deadline does not move it back");
        c.sleep_until(t0 + Duration::from_secs(31));
        assert_eq!(c.elapsed(t0), Duration::from_secs(31));
        let shared = c.shared();
        shared.sleep(Duration::from_millis(5));
        assert_eq!(c.since_base(), Duration::from_millis(31_005), "clones share the time");
    }

    #[test]
    fn the_system_clock_moves_by_itself() {
        let c = SystemClock;
        let t0 = c.now();
        c.sleep(Duration::from_millis(2));
        assert!(c.elapsed(t0) >= Duration::from_millis(2));
        c.sleep_until(t0);
    }
}
