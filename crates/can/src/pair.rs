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
//!
//! ## Several threads: [`PairBus::threaded`]
//! On a [`motus_clock::VirtualClock::threaded`] clock several threads take part (a
//! master's receive thread, a watchdog, the driver, a simulator thread), and time moves
//! only when all of them wait. A bus made with [`PairBus::threaded`] fits that: `recv`
//! *parks* on the clock ([`motus_clock::Clock::park_until`]) and whoever queues a frame
//! (a `send`, a [`PairBus::poll_peer`]) wakes it ([`motus_clock::Clock::unpark`]) at that
//! very instant; `recv` does not run the peer's timers, so they run only at the instants of
//! the sends and of a simulator thread that calls [`PairBus::poll_peer`] at its own period
//! (every millisecond, as a device's control loop runs). Every frame then leaves and
//! arrives at an instant fixed by the simulation, not by the host's scheduling.
//!
//! Several threads can act at one instant. So that the order the OS runs them in does not
//! show, a send *settles*: the sender waits one nanosecond ([`SETTLE`]) on the clock, which
//! moves time only once every other thread waits, so everything the frame set off at that
//! instant (the peer's answer received by the receive thread and handed on, say to a
//! thread that caches a status word) has happened before the sender reads anything. Time
//! moves one nanosecond per send; on the system clock a send costs a short sleep.

use crate::{CanBus, CanError, CanFrame, Received};
use motus_clock::SharedClock;
use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::Thread;
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

/// How long a send on a threaded bus waits on the clock for what it set off (see
/// [`PairBus::threaded`]): one nanosecond, the clock's resolution.
pub const SETTLE: Duration = Duration::from_nanos(1);

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A bus endpoint whose only other member is an in-process [`PairPeer`] on a clock.
pub struct PairBus<P> {
    peer: Arc<Mutex<P>>,
    clock: SharedClock,
    queue: Mutex<VecDeque<Received>>,
    ready: Condvar,
    /// Made with [`PairBus::threaded`]: `recv` parks on the clock.
    threaded: bool,
    /// Threads parked in `recv` (threaded only), woken when a frame is queued.
    receivers: Mutex<Vec<Thread>>,
}

impl<P: PairPeer> PairBus<P> {
    /// A bus to `peer` (shared, so a test can inspect or change the peer meanwhile) on
    /// `clock`, for one thread of control: `recv` waits on *wall* time for another
    /// thread's `send` and runs the peer's timers first.
    pub fn new(peer: Arc<Mutex<P>>, clock: SharedClock) -> Self {
        Self::make(peer, clock, false)
    }

    /// A bus to `peer` on a clock that several threads take part in (a
    /// [`motus_clock::VirtualClock::threaded`], or the system clock): `recv` parks on the
    /// clock until a frame is queued or its time-out has passed on the clock (a wake for no
    /// reason returns `None` early, as a time-out does), and does not run the peer's timers
    /// (sends and [`PairBus::poll_peer`] do). See the module documentation.
    pub fn threaded(peer: Arc<Mutex<P>>, clock: SharedClock) -> Self {
        Self::make(peer, clock, true)
    }

    fn make(peer: Arc<Mutex<P>>, clock: SharedClock, threaded: bool) -> Self {
        Self {
            peer,
            clock,
            queue: Mutex::default(),
            ready: Condvar::new(),
            threaded,
            receivers: Mutex::default(),
        }
    }

    /// Whether this bus was made with [`PairBus::threaded`].
    pub fn is_threaded(&self) -> bool {
        self.threaded
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
        drop(q);
        if self.threaded {
            for t in lock(&self.receivers).iter() {
                self.clock.unpark(t);
            }
        }
    }

    /// Threaded: lets what a send set off at this instant happen before the sender goes on
    /// (the peer's answers received and handed on by the threads they are for: a receive
    /// thread, and a thread it delivers to), so that what the sender reads next does not
    /// depend on which thread the OS runs first. The sender waits [`SETTLE`] on the clock,
    /// which moves time only once every other taking part thread waits.
    fn settle(&self) {
        self.clock.sleep(SETTLE);
    }

    /// `recv` of a threaded bus: one park on the clock (it may end early: the caller
    /// receives again).
    fn recv_parked(&self, timeout: Duration) -> Option<Received> {
        let me = std::thread::current();
        {
            let mut receivers = lock(&self.receivers);
            if !receivers.iter().any(|t| t.id() == me.id()) {
                receivers.push(me.clone());
            }
        }
        let mut got = lock(&self.queue).pop_front();
        if got.is_none() {
            let now = self.clock.now();
            let deadline = now.checked_add(timeout).unwrap_or(now + Duration::from_secs(86_400));
            self.clock.park_until(deadline);
            got = lock(&self.queue).pop_front();
        }
        lock(&self.receivers).retain(|t| t.id() != me.id());
        got
    }
}

impl<P: PairPeer> CanBus for PairBus<P> {
    fn send(&self, frame: &CanFrame) -> Result<(), CanError> {
        self.send_batch(std::slice::from_ref(frame))
    }

    fn send_batch(&self, frames: &[CanFrame]) -> Result<(), CanError> {
        for frame in frames {
            self.run(|p, now| {
                let mut out = p.poll(now);
                out.extend(p.on_frame(frame, now));
                out
            });
        }
        if self.threaded && !frames.is_empty() {
            self.settle();
        }
        Ok(())
    }

    fn recv(&self, timeout: Duration) -> Result<Option<Received>, CanError> {
        if self.threaded {
            return Ok(self.recv_parked(timeout));
        }
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
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
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

    #[test]
    fn a_threaded_receiver_parks_on_the_clock_and_is_woken_at_the_instant_of_the_send() {
        let clock = VirtualClock::threaded();
        let shared = clock.shared();
        let peer = Arc::new(Mutex::new(Echo { next_tick: None }));
        let bus = Arc::new(PairBus::threaded(peer, shared.clone()));
        let rx_bus = Arc::clone(&bus);
        let rx_clock = shared.clone();
        let receiver = motus_clock::spawn(&shared, std::thread::Builder::new(), move || {
            let mut got = Vec::new();
            while got.len() < 4 {
                if let Some(r) = rx_bus.recv(Duration::from_secs(1)).unwrap() {
                    got.push((r.frame.id(), rx_clock.now() - r.at, r.at));
                }
            }
            got
        })
        .unwrap();
        // The first send also runs the peer's timers (a tick at time zero); then answers
        // about 30 and 70 ms later, each received at the very instant it was sent, and
        // before the send returns (it settles: one nanosecond, once the receiver waits).
        let mut sent = Vec::new();
        for (id, pause) in [(0x600, 30), (0x610, 40), (0x620, 0)] {
            sent.push(clock.now());
            bus.send(&CanFrame::new(id, &[1]).unwrap()).unwrap();
            assert_eq!(clock.now() - *sent.last().unwrap(), SETTLE);
            clock.sleep(Duration::from_millis(pause));
        }
        let got = motus_clock::while_blocked(&clock, || receiver.join()).unwrap();
        let ids: Vec<u32> = got.iter().map(|g| g.0).collect();
        assert_eq!(ids, vec![0x700, 0x601, 0x611, 0x621], "the tick at 100 ms was never polled");
        assert!(got.iter().all(|g| g.1 == Duration::ZERO), "received when sent: {got:?}");
        let at: Vec<Instant> = got.iter().map(|g| g.2).collect();
        assert_eq!(at, vec![sent[0], sent[0], sent[1], sent[2]]);
        assert_eq!(sent[2] - sent[0], Duration::from_millis(70) + 2 * SETTLE);
    }
}
