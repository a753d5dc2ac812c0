//! An in-process *pair*: a bus whose other end is a peer (a simulated device, or several)
//! that runs inside [`CanBus::send`] and [`CanBus::recv`] rather than on a thread of its
//! own. A frame sent is handed to the peer synchronously, at the current time of the
//! [`motus_clock::Clock`], and the peer's answers are queued before `send` returns; `recv`
//! first runs the peer's timers up to the clock's time (heartbeats, event-timer PDOs,
//! motion), then returns the oldest queued frame.
//!
//! With a [`motus_clock::VirtualClock`] this makes a driver-versus-simulator test
//! deterministic and fast: time moves only when the driver sleeps on the clock, the
//! simulator integrates exactly up to that time, and nothing depends on the host's load
//! (smoltcp's `tests/netsim.rs` and quinn-proto's test `Pair` work the same way). With a
//! [`motus_clock::SystemClock`] it is an in-process bus on real time.
//!
//! Frames are time-stamped ([`Received::at`]) with the clock's time. When the queue is
//! empty, `recv` waits up to `timeout` of *wall* time for another thread's `send` (the
//! answer to a request normally arrives within that very call): it never advances the
//! clock itself, so a receive thread that polls the bus does not move virtual time.
//!
//! The rule for determinism: one thread advances the clock (the driver, by sleeping on
//! it), and after each advance it exchanges a frame with the peer (a statusword read) before
//! it advances again, so the peer's timers run at every step and their frames are
//! delivered before the next one. The driver's waits ([`motus_clock::Clock::sleep`] then
//! a poll) do exactly that.

use crate::{CanBus, CanError, CanFrame, Received};
use motus_clock::SharedClock;
use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

/// The far end of a [`PairBus`]: a sans-IO device that answers frames and runs timers at
/// the times it is given.
pub trait PairPeer: Send {
    /// Handles a frame the bus's user sent at `now`; returns the frames sent in reaction.
    fn on_frame(&mut self, frame: &CanFrame, now: Instant) -> Vec<CanFrame>;
    /// Runs the peer's timers up to `now`; returns the frames it sends.
    fn poll(&mut self, now: Instant) -> Vec<CanFrame>;
}

impl<P: PairPeer> PairPeer for Vec<P> {
    fn on_frame(&mut self, frame: &CanFrame, now: Instant) -> Vec<CanFrame> {
        self.iter_mut().flat_map(|p| p.on_frame(frame, now)).collect()
    }
    fn poll(&mut self, now: Instant) -> Vec<CanFrame> {
        self.iter_mut().flat_map(|p| p.poll(now)).collect()
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A bus endpoint whose only other member is an in-process [`PairPeer`] on a clock.
pub struct PairBus<P> {
    peer: Arc<Mutex<P>>,
    clock: SharedClock,
    queue: Mutex<VecDeque<Received>>,
    ready: Condvar,
}

impl<P: PairPeer> PairBus<P> {
    /// A bus to `peer` (shared, so a test can inspect or change the peer meanwhile) on
    /// `clock`.
    pub fn new(peer: Arc<Mutex<P>>, clock: SharedClock) -> Self {
        Self { peer, clock, queue: Mutex::default(), ready: Condvar::new() }
    }

    /// The peer.
    pub fn peer(&self) -> &Arc<Mutex<P>> {
        &self.peer
    }

    /// The clock.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }

    /// Runs the peer's timers up to the clock's time and queues what it sends.
    pub fn poll_peer(&self) {
        self.run(|p, now| p.poll(now));
    }

    fn run(&self, f: impl FnOnce(&mut P, Instant) -> Vec<CanFrame>) {
        let now = self.clock.now();
        let out = f(&mut lock(&self.peer), now);
        if out.is_empty() {
            return;
        }
        let mut q = lock(&self.queue);
        q.extend(out.into_iter().map(|frame| Received { frame, at: now }));
        self.ready.notify_all();
    }
}

impl<P: PairPeer> CanBus for PairBus<P> {
    fn send(&self, frame: &CanFrame) -> Result<(), CanError> {
        self.run(|p, now| {
            let mut out = p.poll(now);
            out.extend(p.on_frame(frame, now));
            out
        });
        Ok(())
    }

    fn recv(&self, timeout: Duration) -> Result<Option<Received>, CanError> {
        self.poll_peer();
        let q = lock(&self.queue);
        let (mut q, _) = self
            .ready
            .wait_timeout_while(q, timeout, |q| q.is_empty())
            .unwrap_or_else(PoisonError::into_inner);
        Ok(q.pop_front())
    }

    fn describe(&self) -> String {
        "in-process pair".into()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use motus_clock::{Clock, VirtualClock};

    /// Echoes every frame with id + 1, and sends a tick every 100 ms of clock time.
    struct Echo {
        next_tick: Option<Instant>,
    }

    impl PairPeer for Echo {
        fn on_frame(&mut self, frame: &CanFrame, _now: Instant) -> Vec<CanFrame> {
            vec![CanFrame::new(frame.id() + 1, frame.data()).unwrap()]
        }
        fn poll(&mut self, now: Instant) -> Vec<CanFrame> {
            let next = self.next_tick.get_or_insert(now);
            let mut out = Vec::new();
            while *next <= now {
                out.push(CanFrame::new(0x700, &[5]).unwrap());
                *next += Duration::from_millis(100);
            }
            out
        }
    }

    #[test]
    fn answers_come_back_in_the_same_call_and_timers_follow_the_clock() {
        let clock = VirtualClock::new();
        let bus = PairBus::new(Arc::new(Mutex::new(Echo { next_tick: None })), clock.shared());
        bus.send(&CanFrame::new(0x600, &[1, 2]).unwrap()).unwrap();
        let tick = bus.recv(Duration::ZERO).unwrap().unwrap();
        assert_eq!(tick.frame.id(), 0x700, "the first poll's tick");
        let answer = bus.recv(Duration::ZERO).unwrap().unwrap();
        assert_eq!((answer.frame.id(), answer.frame.data()), (0x601, &[1u8, 2][..]));
        assert_eq!(answer.at, clock.base());
        assert!(bus.recv(Duration::ZERO).unwrap().is_none(), "time did not move: no tick");
        clock.sleep(Duration::from_millis(250));
        let ticks: Vec<_> = std::iter::from_fn(|| bus.recv(Duration::ZERO).unwrap()).collect();
        assert_eq!(ticks.len(), 2, "ticks at 100 and 200 ms");
        assert!(ticks.iter().all(|r| r.at == clock.now()));
    }
}
