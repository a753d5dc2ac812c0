//! Fault injection: frames dropped, corrupted (caught by CAN's CRC, so never delivered,
//! only counted), mangled (delivered with damaged content, to test upper layers'
//! validation) or delayed. Seeded, so a failing test can be replayed.

use crate::{CanBus, CanError, CanFrame, Received};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use std::collections::VecDeque;
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// Probabilities (0.0-1.0, checked in this order) and parameters of the faults.
#[derive(Debug, Clone, PartialEq)]
pub struct FaultConfig {
    /// The frame vanishes.
    pub drop: f64,
    /// The frame is damaged on the wire: the CRC catches it, it is counted, not delivered.
    pub corrupt: f64,
    /// The frame is delivered with a flipped data bit or a wrong length.
    pub mangle: f64,
    /// The frame is delivered late (later frames queue behind it: CAN keeps order).
    pub delay: f64,
    /// Largest extra latency of a delayed frame.
    pub max_delay: Duration,
    /// Also apply the faults to frames sent (a delayed send blocks the sender).
    pub on_send: bool,
    /// Seed of the random generator.
    pub seed: u64,
}

impl Default for FaultConfig {
    fn default() -> Self {
        FaultConfig {
            drop: 0.0,
            corrupt: 0.0,
            mangle: 0.0,
            delay: 0.0,
            max_delay: Duration::from_millis(10),
            on_send: false,
            seed: 1,
        }
    }
}

/// What the injector did so far.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FaultStats {
    /// Frames passed through unchanged (including delayed ones).
    pub passed: u64,
    /// Frames dropped.
    pub dropped: u64,
    /// Frames corrupted on the wire (counted, never delivered).
    pub corrupted: u64,
    /// Frames delivered with damaged content.
    pub mangled: u64,
    /// Frames delayed.
    pub delayed: u64,
}

enum Fate {
    Drop,
    Corrupt,
    Deliver(CanFrame, Duration),
}

struct State {
    rng: SmallRng,
    stats: FaultStats,
    pending: VecDeque<(Instant, Received)>,
}

/// A [`CanBus`] that injects faults into the frames of the inner bus.
pub struct FaultyBus<B> {
    inner: B,
    config: FaultConfig,
    state: Mutex<State>,
}

fn mangle(frame: &CanFrame, rng: &mut SmallRng) -> CanFrame {
    let mut data = frame.data().to_vec();
    let flip = !data.is_empty() && rng.gen_bool(0.5);
    if flip {
        let bit = rng.gen_range(0..data.len() * 8);
        if let Some(b) = data.get_mut(bit / 8) {
            *b ^= 1 << (bit % 8);
        }
    } else if data.len() == 8 || (!data.is_empty() && rng.gen_bool(0.5)) {
        data.pop();
    } else {
        data.push(rng.gen());
    }
    CanFrame::with_format(frame.id(), frame.is_extended(), &data).unwrap_or_else(|_| frame.clone())
}

impl<B: CanBus> FaultyBus<B> {
    /// Wraps `inner`.
    pub fn new(inner: B, config: FaultConfig) -> Self {
        let rng = SmallRng::seed_from_u64(config.seed);
        FaultyBus {
            inner,
            config,
            state: Mutex::new(State { rng, stats: FaultStats::default(), pending: VecDeque::new() }),
        }
    }

    /// What was injected so far.
    pub fn stats(&self) -> FaultStats {
        self.lock().stats
    }

    /// The wrapped bus.
    pub fn inner(&self) -> &B {
        &self.inner
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn fate(&self, state: &mut State, frame: &CanFrame) -> Fate {
        let c = &self.config;
        let rng = &mut state.rng;
        let roll = |rng: &mut SmallRng, p: f64| p > 0.0 && rng.gen_bool(p.min(1.0));
        if roll(rng, c.drop) {
            state.stats.dropped += 1;
            return Fate::Drop;
        }
        if roll(rng, c.corrupt) {
            state.stats.corrupted += 1;
            return Fate::Corrupt;
        }
        let mut out = frame.clone();
        if roll(rng, c.mangle) && !frame.is_remote() {
            state.stats.mangled += 1;
            out = mangle(frame, rng);
        } else {
            state.stats.passed += 1;
        }
        let mut delay = Duration::ZERO;
        if roll(rng, c.delay) {
            state.stats.delayed += 1;
            delay = c.max_delay.mul_f64(rng.gen_range(0.0..=1.0));
        }
        Fate::Deliver(out, delay)
    }
}

impl<B: CanBus> CanBus for FaultyBus<B> {
    fn send_batch(&self, frames: &[CanFrame]) -> Result<(), CanError> {
        if !self.config.on_send {
            return self.inner.send_batch(frames);
        }
        // Each frame meets its own fate (drop, corrupt, delay).
        frames.iter().try_for_each(|f| self.send(f))
    }

    fn send(&self, frame: &CanFrame) -> Result<(), CanError> {
        if !self.config.on_send {
            return self.inner.send(frame);
        }
        let fate = {
            let mut state = self.lock();
            self.fate(&mut state, frame)
        };
        match fate {
            Fate::Drop | Fate::Corrupt => Ok(()),
            Fate::Deliver(f, delay) => {
                if !delay.is_zero() {
                    std::thread::sleep(delay);
                }
                self.inner.send(&f)
            }
        }
    }

    fn recv(&self, timeout: Duration) -> Result<Option<Received>, CanError> {
        let deadline = Instant::now() + timeout;
        loop {
            let now = Instant::now();
            let wait_until = {
                let mut state = self.lock();
                match state.pending.front() {
                    Some((release, _)) if *release <= now => {
                        return Ok(state.pending.pop_front().map(|(_, r)| r))
                    }
                    Some((release, _)) => (*release).min(deadline),
                    None => deadline,
                }
            };
            let got = self.inner.recv(wait_until.saturating_duration_since(now))?;
            if let Some(r) = got {
                let mut state = self.lock();
                if let Fate::Deliver(frame, delay) = self.fate(&mut state, &r.frame) {
                    let last = state.pending.back().map_or(r.at, |(t, _)| *t);
                    let release = last.max(Instant::now() + delay);
                    state.pending.push_back((release, Received { frame, at: r.at }));
                }
            } else if Instant::now() >= deadline
                && !matches!(self.lock().pending.front(), Some((t, _)) if *t <= deadline)
            {
                return Ok(None);
            }
        }
    }

    fn describe(&self) -> String {
        format!("{} (fault injection)", self.inner.describe())
    }
}
