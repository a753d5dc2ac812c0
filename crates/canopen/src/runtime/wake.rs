//! Handing something to a waiting thread on the master's clock.
//!
//! On the system clock (and a one-thread-of-control virtual clock) a waiter blocks on its
//! channel for at most its time-out of *wall* time. On a clock several threads take part
//! in ([`crate::Master::with_threaded_clock`]) a waiting thread instead *parks on the
//! clock* until its deadline ([`Clock::park_until`]), so that time can move while it waits,
//! and whoever delivers to it wakes it at that instant ([`Clock::unpark`]): the receive
//! thread for answers, events and frames, the heartbeat path for node states.

use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, TryRecvError};
use std::sync::{Arc, Mutex};
use std::thread::Thread;
use std::time::{Duration, Instant};

use motus_clock::{Clock, SharedClock};

use super::lock;

/// The thread to wake when something is delivered (none: nobody parks).
#[derive(Debug, Default)]
pub(crate) struct WakeSlot(Mutex<Option<Thread>>);

impl WakeSlot {
    /// A slot holding the calling thread.
    pub(crate) fn current() -> Arc<WakeSlot> {
        Arc::new(WakeSlot(Mutex::new(Some(std::thread::current()))))
    }

    /// The calling thread is the one to wake from now on.
    pub(crate) fn set_current(&self) {
        *lock(&self.0) = Some(std::thread::current());
    }

    /// Wakes the thread, if any, on `clock`.
    pub(crate) fn wake(&self, clock: &dyn Clock) {
        if let Some(t) = lock(&self.0).as_ref() {
            clock.unpark(t);
        }
    }
}

/// A channel's sending end that also wakes the receiving thread (when it parks on the
/// clock).
pub(crate) struct Waiter<T> {
    tx: Sender<T>,
    slot: Option<Arc<WakeSlot>>,
}

impl<T> Waiter<T> {
    /// Delivers through `tx`, waking `slot`'s thread if given.
    pub(crate) fn new(tx: Sender<T>, slot: Option<Arc<WakeSlot>>) -> Self {
        Self { tx, slot }
    }

    /// Sends `value` and wakes the receiver; false once the receiver is gone.
    pub(crate) fn send(&self, value: T, clock: &dyn Clock) -> bool {
        let sent = self.tx.send(value).is_ok();
        if sent {
            if let Some(slot) = &self.slot {
                slot.wake(clock);
            }
        }
        sent
    }
}

impl<T> Clone for Waiter<T> {
    fn clone(&self) -> Self {
        Self { tx: self.tx.clone(), slot: self.slot.clone() }
    }
}

/// Receives from `rx` until `deadline` on `clock`. Parked on the clock (`parked`: the
/// sender wakes the thread), or, otherwise, blocked for the remaining time of wall time
/// (a liveness bound when the clock is virtual: the message normally comes in
/// microseconds) and then, with `jump`, the clock moved to the deadline (the caller is
/// the one thread of control of a virtual clock, which reports the time-out on it).
pub(crate) fn recv_until<T>(
    rx: &Receiver<T>,
    clock: &dyn Clock,
    deadline: Instant,
    parked: bool,
    jump: bool,
) -> Result<T, RecvTimeoutError> {
    if !parked {
        let left = deadline.saturating_duration_since(clock.now());
        let got = rx.recv_timeout(left);
        if jump && matches!(got, Err(RecvTimeoutError::Timeout)) {
            clock.sleep_until(deadline);
        }
        return got;
    }
    loop {
        match rx.try_recv() {
            Ok(v) => return Ok(v),
            Err(TryRecvError::Disconnected) => return Err(RecvTimeoutError::Disconnected),
            Err(TryRecvError::Empty) => {}
        }
        if clock.now() >= deadline {
            return Err(RecvTimeoutError::Timeout);
        }
        clock.park_until(deadline);
    }
}

/// What the master delivers (its events, or frames of a subscription), received with
/// time-outs on the master's clock.
///
/// On a master made with [`crate::Master::with_threaded_clock`] a receiving thread parks
/// on the clock and the master's receive thread wakes it at the instant it delivers, so a
/// thread that takes part in a [`motus_clock::VirtualClock::threaded`] clock (started with
/// [`motus_clock::spawn`]) reacts at the virtual instant of the event. Otherwise it is a
/// channel with wall-time time-outs, as [`crate::Master::events`] returns.
pub struct ClockReceiver<T> {
    rx: Receiver<T>,
    slot: Arc<WakeSlot>,
    clock: SharedClock,
    parked: bool,
}

impl<T> ClockReceiver<T> {
    pub(crate) fn new(rx: Receiver<T>, slot: Arc<WakeSlot>, clock: SharedClock, parked: bool) -> Self {
        Self { rx, slot, clock, parked }
    }

    /// Takes what has arrived, without waiting.
    ///
    /// # Errors
    /// Nothing has arrived, or the master is gone.
    pub fn try_recv(&self) -> Result<T, TryRecvError> {
        self.rx.try_recv()
    }

    /// Waits at most `timeout` on the master's clock.
    ///
    /// # Errors
    /// The time-out passed, or the master is gone.
    pub fn recv_timeout(&self, timeout: Duration) -> Result<T, RecvTimeoutError> {
        let now = self.clock.now();
        let deadline = now.checked_add(timeout).unwrap_or(now + Duration::from_secs(86_400));
        self.recv_until(deadline)
    }

    /// Waits until `deadline` of the master's clock.
    ///
    /// # Errors
    /// The deadline passed, or the master is gone.
    pub fn recv_until(&self, deadline: Instant) -> Result<T, RecvTimeoutError> {
        if self.parked {
            self.slot.set_current();
        }
        recv_until(&self.rx, &*self.clock, deadline, self.parked, false)
    }

    /// The clock of the time-outs.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }
}

impl<T> std::fmt::Debug for ClockReceiver<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ClockReceiver").field("parked", &self.parked).finish_non_exhaustive()
    }
}
