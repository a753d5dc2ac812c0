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
//! A runtime that runs its own cyclic thread (a serial scheduler, a controller) shares a
//! [`VirtualClock::threaded`] clock with the test thread: the runtime starts its thread
//! with [`spawn`], every taking part thread sleeps on the clock, and time jumps to the
//! earliest deadline once all of them wait, as a discrete-event simulator does. A thread
//! that waits for another one (a reply over a channel) marks itself [`while_blocked`]; one
//! that waits for another one's message *with a deadline* (a receiver on an in-process link)
//! parks on the clock ([`Clock::park_until`]) and the sender wakes it ([`Clock::unpark`]) at
//! the instant it sends.
//!
//! A peer that runs its own thread with its own real-time loop (a simulator served over
//! TCP, a pty, a veth pair) cannot share a virtual clock: such tests run on
//! [`SystemClock`] with generous liveness time-outs.

#![forbid(unsafe_code)]

use std::cell::RefCell;
use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::ThreadId;
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

    /// Waits until `deadline` as precisely as the clock can: the cycle grid of a cyclic
    /// thread (a bus scheduler, a paced line). The system clock sleeps, then spins for the
    /// last 150 µs (a plain sleep wakes up to a timer slack late); a virtual clock is exact
    /// anyway. Costs up to 150 µs of CPU per wait on the system clock: not for pollers.
    fn sleep_until_precise(&self, deadline: Instant) {
        self.sleep_until(deadline);
    }

    /// The time elapsed since `earlier` (zero if `earlier` is later than now).
    fn elapsed(&self, earlier: Instant) -> Duration {
        self.now().saturating_duration_since(earlier)
    }

    /// The calling thread takes part in this clock's time (a threaded [`VirtualClock`]
    /// moves time only when every taking part thread waits). A runtime calls it first thing
    /// on each thread it starts. Nothing for the system clock.
    fn join_thread(&self) {}

    /// The calling thread stops taking part (it also stops when it ends).
    fn leave_thread(&self) {}

    /// A thread that will take part is being started (`true`), or has joined or failed to
    /// start (`false`): a threaded virtual clock does not move meanwhile. See [`spawn`].
    fn starting_thread(&self, starting: bool) {
        let _ = starting;
    }

    /// Takes the lock `key` of a [`ClockMutex`] on this clock, in the order asked, the
    /// calling thread counting as blocked while it waits; returns false when the clock does
    /// not order locks (the system clock, or a thread not taking part): the caller then
    /// blocks on the mutex itself.
    fn acquire(&self, key: u64) -> bool {
        let _ = key;
        false
    }

    /// Gives the lock `key` taken with [`Clock::acquire`] to the next waiter, which runs
    /// again at once, before time can move.
    fn release(&self, key: u64) {
        let _ = key;
    }

    /// Marks the calling thread blocked on another thread (`true`) or running again
    /// (`false`); see [`while_blocked`].
    fn blocked(&self, blocked: bool) {
        let _ = blocked;
    }

    /// Waits until `deadline`, or until another thread calls [`Clock::unpark`] for the
    /// calling one, whichever comes first: a wait with a deadline for something another
    /// thread produces (a frame on an in-process link). An `unpark` that comes before the
    /// wait ends the next wait at once, as with [`std::thread::park_timeout`] and
    /// [`std::thread::Thread::unpark`]; a wait may also end early for no reason, so callers
    /// check again what they wait for. On a threaded [`VirtualClock`] the waiting thread
    /// counts as asleep until `deadline`, and an `unpark` marks it running at once: time does
    /// not move on before it has looked at what it was woken for.
    fn park_until(&self, deadline: Instant) {
        let left = deadline.saturating_duration_since(self.now());
        if !left.is_zero() {
            std::thread::park_timeout(left);
        }
    }

    /// Ends `thread`'s [`Clock::park_until`], or its next one if it is not waiting.
    fn unpark(&self, thread: &std::thread::Thread) {
        thread.unpark();
    }

    /// Waits until every other taking part thread of a threaded [`VirtualClock`] waits (or
    /// settles too): what they do at this instant in answer to what the calling thread did
    /// (a frame it sent) is done before it goes on, so that the order of events within one
    /// instant does not depend on the OS. Nothing for other clocks. Never call it while
    /// holding a lock another taking part thread may wait for.
    fn settle(&self) {}
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

    fn sleep_until_precise(&self, deadline: Instant) {
        const SPIN: Duration = Duration::from_micros(150);
        loop {
            let now = Instant::now();
            if now >= deadline {
                return;
            }
            let left = deadline - now;
            if left > SPIN {
                std::thread::sleep(left - SPIN);
            } else {
                std::hint::spin_loop();
            }
        }
    }
}

/// A deterministic clock: time starts at a base instant and moves only when advanced
/// ([`VirtualClock::advance`], [`Clock::sleep`], [`Clock::sleep_until`]). Clones share the
/// same time.
///
/// ## One thread of control, or several
/// A clock made with [`VirtualClock::new`] serves **one thread of control**: a sleep moves
/// time forward at once. A clock made with [`VirtualClock::threaded`] serves **several
/// threads** (a driver's cyclic thread and the test thread that commands it), as a
/// discrete-event simulator does: every thread that takes part ([`Clock::join_thread`], or
/// its first sleep) waits for its deadline, and time jumps to the earliest deadline only
/// when *every* taking part thread is asleep or [blocked](Clock::blocked) on another. A
/// thread stops taking part when it ends (or calls [`Clock::leave_thread`]). Two threads
/// woken at the same instant run in an order the OS chooses, so results are reproducible to
/// within what happens at one instant.
#[derive(Debug, Clone)]
pub struct VirtualClock {
    inner: Arc<Shared>,
}

#[derive(Debug)]
struct Shared {
    base: Instant,
    /// One id per clock, for the thread-local registry of taking part threads.
    id: u64,
    threaded: bool,
    state: Mutex<State>,
    woken: Condvar,
}

#[derive(Debug, Default)]
struct State {
    /// Nanoseconds since `base`.
    now_ns: u64,
    /// Taking part threads and what each waits for: `None` while it runs, `Some(deadline)`
    /// while it sleeps (`u64::MAX` while blocked on another thread).
    threads: HashMap<ThreadId, Option<u64>>,
    /// Threads being started that will take part ([`spawn`]): time waits for them.
    starting: usize,
    /// Threads inside [`Clock::park_until`].
    parked: HashSet<ThreadId>,
    /// Threads unparked since their last park (a token each).
    unparked: HashSet<ThreadId>,
    /// Threads inside [`Clock::settle`].
    settling: HashSet<ThreadId>,
    /// [`ClockMutex`]es taken through the clock (by key): the owner and the waiters in the
    /// order they asked.
    locks: HashMap<u64, LockQueue>,
}

impl State {
    /// Jumps to the earliest deadline when every taking part thread waits; true if time moved.
    fn advance_if_all_wait(&mut self) -> bool {
        if self.starting > 0 {
            return false;
        }
        let mut earliest = u64::MAX;
        for wait in self.threads.values() {
            match wait {
                None => return false,
                Some(d) => earliest = earliest.min(*d),
            }
        }
        if earliest == u64::MAX || earliest <= self.now_ns {
            return false;
        }
        self.now_ns = earliest;
        true
    }

    /// True when every taking part thread but `me` waits or settles.
    fn others_idle(&self, me: ThreadId) -> bool {
        self.starting == 0
            && self.threads.iter().all(|(id, wait)| *id == me || wait.is_some() || self.settling.contains(id))
    }
}

/// The owner of a [`ClockMutex`] and its waiters, first come first served.
#[derive(Debug, Default)]
struct LockQueue {
    owner: Option<ThreadId>,
    waiters: std::collections::VecDeque<ThreadId>,
}

static NEXT_CLOCK_ID: AtomicU64 = AtomicU64::new(1);

thread_local! {
    /// The threaded clocks this thread takes part in; leaving them when the thread ends.
    static TAKING_PART: RefCell<Vec<Membership>> = const { RefCell::new(Vec::new()) };
}

/// A thread's membership of a threaded clock, ended when the thread ends.
struct Membership(Arc<Shared>);

impl Drop for Membership {
    fn drop(&mut self) {
        self.0.remove(std::thread::current().id());
    }
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn is_member(&self) -> bool {
        TAKING_PART.with(|m| m.borrow().iter().any(|s| s.0.id == self.id))
    }

    fn join(self: &Arc<Self>) {
        if !self.threaded || self.is_member() {
            return;
        }
        let mut state = self.lock();
        state.threads.insert(std::thread::current().id(), None);
        drop(state);
        TAKING_PART.with(|m| m.borrow_mut().push(Membership(Arc::clone(self))));
    }

    fn remove(&self, thread: ThreadId) {
        let mut state = self.lock();
        state.threads.remove(&thread);
        state.unparked.remove(&thread);
        if state.advance_if_all_wait() || !state.settling.is_empty() {
            self.woken.notify_all();
        }
    }

    /// Sets what the calling (taking part) thread waits for and moves time if all wait.
    fn set_wait(&self, state: &mut State, wait: Option<u64>) {
        if let Some(w) = state.threads.get_mut(&std::thread::current().id()) {
            *w = wait;
        }
        if state.advance_if_all_wait() || !state.settling.is_empty() {
            self.woken.notify_all();
        }
    }
}

impl Default for VirtualClock {
    fn default() -> Self {
        Self::new()
    }
}

impl VirtualClock {
    /// A clock for one thread of control, at its base instant (taken now): a sleep moves
    /// time forward at once.
    pub fn new() -> Self {
        Self::make(false)
    }

    /// A clock for several threads (see the type's documentation); the calling thread takes
    /// part.
    pub fn threaded() -> Self {
        let clock = Self::make(true);
        clock.inner.join();
        clock
    }

    fn make(threaded: bool) -> Self {
        Self {
            inner: Arc::new(Shared {
                base: Instant::now(),
                id: NEXT_CLOCK_ID.fetch_add(1, Ordering::Relaxed),
                threaded,
                state: Mutex::new(State::default()),
                woken: Condvar::new(),
            }),
        }
    }

    /// This clock as a [`SharedClock`] (sharing its time).
    pub fn shared(&self) -> SharedClock {
        Arc::new(self.clone())
    }

    /// The base instant (time zero of this clock).
    pub fn base(&self) -> Instant {
        self.inner.base
    }

    /// Virtual time elapsed since the base instant.
    pub fn since_base(&self) -> Duration {
        Duration::from_nanos(self.inner.lock().now_ns)
    }

    /// Moves time forward by `by` (wakes the threads whose deadline it passes).
    pub fn advance(&self, by: Duration) {
        let ns = u64::try_from(by.as_nanos()).unwrap_or(u64::MAX);
        let mut state = self.inner.lock();
        // Saturating add (an overflow would need 584 years of virtual time).
        state.now_ns = state.now_ns.saturating_add(ns);
        drop(state);
        self.inner.woken.notify_all();
    }

    fn deadline_ns(&self, deadline: Instant) -> u64 {
        u64::try_from(deadline.saturating_duration_since(self.inner.base).as_nanos()).unwrap_or(u64::MAX)
    }
}

/// How long a thread of a threaded clock waits, in wall time, before it checks again that
/// time can move (a liveness bound, never a figure).
const WAKE_CHECK: Duration = Duration::from_millis(50);

impl Clock for VirtualClock {
    fn now(&self) -> Instant {
        self.inner.base + self.since_base()
    }

    fn sleep(&self, duration: Duration) {
        if !self.inner.threaded {
            self.advance(duration);
            return;
        }
        let deadline = self.now() + duration;
        self.sleep_until(deadline);
    }

    fn sleep_until(&self, deadline: Instant) {
        let target = self.deadline_ns(deadline);
        if !self.inner.threaded {
            let mut state = self.inner.lock();
            state.now_ns = state.now_ns.max(target);
            return;
        }
        self.inner.join();
        let mut state = self.inner.lock();
        if state.now_ns >= target {
            return;
        }
        self.inner.set_wait(&mut state, Some(target));
        while state.now_ns < target {
            state = match self.inner.woken.wait_timeout(state, WAKE_CHECK) {
                Ok((s, _)) => s,
                Err(poisoned) => poisoned.into_inner().0,
            };
        }
        self.inner.set_wait(&mut state, None);
    }

    fn join_thread(&self) {
        self.inner.join();
    }

    fn leave_thread(&self) {
        let id = self.inner.id;
        // Dropping the membership removes the thread and lets time move.
        let left = TAKING_PART.with(|m| {
            let mut m = m.borrow_mut();
            m.iter().position(|s| s.0.id == id).map(|i| m.remove(i))
        });
        drop(left);
    }

    fn starting_thread(&self, starting: bool) {
        if !self.inner.threaded {
            return;
        }
        let mut state = self.inner.lock();
        if starting {
            state.starting += 1;
        } else {
            state.starting = state.starting.saturating_sub(1);
            if state.advance_if_all_wait() {
                self.inner.woken.notify_all();
            }
        }
    }

    fn acquire(&self, key: u64) -> bool {
        if !self.inner.threaded || !self.inner.is_member() {
            return false;
        }
        let me = std::thread::current().id();
        let mut state = self.inner.lock();
        let queue = state.locks.entry(key).or_default();
        if queue.owner.is_none() && queue.waiters.is_empty() {
            queue.owner = Some(me);
            return true;
        }
        queue.waiters.push_back(me);
        self.inner.set_wait(&mut state, Some(u64::MAX));
        while state.locks.get(&key).and_then(|q| q.owner) != Some(me) {
            state = match self.inner.woken.wait_timeout(state, WAKE_CHECK) {
                Ok((s, _)) => s,
                Err(poisoned) => poisoned.into_inner().0,
            };
        }
        // `release` marked this thread running already.
        self.inner.set_wait(&mut state, None);
        true
    }

    fn release(&self, key: u64) {
        let mut state = self.inner.lock();
        let Some(queue) = state.locks.get_mut(&key) else { return };
        queue.owner = queue.waiters.pop_front();
        if let Some(next) = queue.owner {
            if let Some(w) = state.threads.get_mut(&next) {
                *w = None;
            }
        }
        drop(state);
        self.inner.woken.notify_all();
    }

    fn blocked(&self, blocked: bool) {
        if !self.inner.threaded || !self.inner.is_member() {
            return;
        }
        let mut state = self.inner.lock();
        self.inner.set_wait(&mut state, blocked.then_some(u64::MAX));
    }

    fn park_until(&self, deadline: Instant) {
        let target = self.deadline_ns(deadline);
        let me = std::thread::current().id();
        if !self.inner.threaded {
            let mut state = self.inner.lock();
            if !state.unparked.remove(&me) {
                state.now_ns = state.now_ns.max(target);
            }
            return;
        }
        self.inner.join();
        let mut state = self.inner.lock();
        if state.unparked.remove(&me) || state.now_ns >= target {
            return;
        }
        state.parked.insert(me);
        self.inner.set_wait(&mut state, Some(target));
        while state.now_ns < target && !state.unparked.contains(&me) {
            state = match self.inner.woken.wait_timeout(state, WAKE_CHECK) {
                Ok((s, _)) => s,
                Err(poisoned) => poisoned.into_inner().0,
            };
        }
        state.unparked.remove(&me);
        state.parked.remove(&me);
        self.inner.set_wait(&mut state, None);
    }

    fn settle(&self) {
        if !self.inner.threaded || !self.inner.is_member() {
            return;
        }
        let me = std::thread::current().id();
        let mut state = self.inner.lock();
        state.settling.insert(me);
        // Another settling thread may be waiting for this one.
        self.inner.woken.notify_all();
        while !state.others_idle(me) {
            state = match self.inner.woken.wait_timeout(state, WAKE_CHECK) {
                Ok((s, _)) => s,
                Err(poisoned) => poisoned.into_inner().0,
            };
        }
        state.settling.remove(&me);
    }

    fn unpark(&self, thread: &std::thread::Thread) {
        let id = thread.id();
        let mut state = self.inner.lock();
        state.unparked.insert(id);
        if state.parked.contains(&id) {
            // Running from now on: time waits until it has looked and waits again.
            if let Some(wait) = state.threads.get_mut(&id) {
                *wait = None;
            }
        }
        drop(state);
        self.inner.woken.notify_all();
    }
}

/// Starts a thread that takes part in `clock`'s time from its first instruction (a
/// threaded virtual clock does not move between the spawn and the thread's start).
///
/// # Errors
/// The thread could not be spawned.
pub fn spawn<T, F>(
    clock: &SharedClock,
    builder: std::thread::Builder,
    f: F,
) -> std::io::Result<std::thread::JoinHandle<T>>
where
    F: FnOnce() -> T + Send + 'static,
    T: Send + 'static,
{
    clock.starting_thread(true);
    let thread_clock = Arc::clone(clock);
    let spawned = builder.spawn(move || {
        thread_clock.join_thread();
        thread_clock.starting_thread(false);
        f()
    });
    if spawned.is_err() {
        clock.starting_thread(false);
    }
    spawned
}

static NEXT_LOCK_KEY: AtomicU64 = AtomicU64::new(1);

/// A mutex for data that threads of a [threaded](VirtualClock::threaded) virtual clock
/// share while they sleep on it (a bus line held across a transaction's wire time).
///
/// On such a clock the lock is handed over first come first served: a thread waiting for it
/// counts as blocked, so time can move for the holder, and the holder's release gives it to
/// the first waiter, which counts as running again *at once*, before the holder's next sleep
/// can move time past it (with a plain mutex and [`while_blocked`], a waiter stayed marked
/// blocked until the OS ran it, and time jumped meanwhile), and in the order asked, so a run
/// repeats. On the system clock it is a plain mutex (a handover to a waiter the OS has not
/// run yet would hold the line for everyone behind it).
#[derive(Debug)]
pub struct ClockMutex<T> {
    clock: SharedClock,
    key: u64,
    inner: Mutex<T>,
}

/// The guard of a [`ClockMutex`]; releasing it wakes the waiters on the clock.
#[derive(Debug)]
pub struct ClockMutexGuard<'a, T> {
    guard: Option<MutexGuard<'a, T>>,
    lock: &'a ClockMutex<T>,
    /// Taken through the clock's queue ([`Clock::acquire`]).
    via_clock: bool,
}

impl<T> ClockMutex<T> {
    /// A mutex around `value` whose waiters wait on `clock`.
    pub fn new(value: T, clock: SharedClock) -> Self {
        Self { clock, key: NEXT_LOCK_KEY.fetch_add(1, Ordering::Relaxed), inner: Mutex::new(value) }
    }

    /// The clock the waiters wait on.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }

    /// Takes the lock (a poisoned lock is taken all the same: the data is plain state).
    pub fn lock(&self) -> ClockMutexGuard<'_, T> {
        let via_clock = self.clock.acquire(self.key);
        let guard = self.inner.lock().unwrap_or_else(PoisonError::into_inner);
        ClockMutexGuard { guard: Some(guard), lock: self, via_clock }
    }
}

impl<T> std::ops::Deref for ClockMutexGuard<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        // The guard is `Some` until drop.
        match &self.guard {
            Some(g) => g,
            None => unreachable_guard(),
        }
    }
}

impl<T> std::ops::DerefMut for ClockMutexGuard<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        match &mut self.guard {
            Some(g) => g,
            None => unreachable_guard(),
        }
    }
}

#[allow(clippy::panic)]
fn unreachable_guard() -> ! {
    panic!("a ClockMutexGuard is used after its release")
}

impl<T> Drop for ClockMutexGuard<'_, T> {
    fn drop(&mut self) {
        drop(self.guard.take());
        if self.via_clock {
            self.lock.clock.release(self.lock.key);
        }
    }
}

/// Runs `wait` (a wait for another thread: a channel, a lock held across a cycle) with the
/// calling thread marked blocked on `clock`, so that a threaded virtual clock can move
/// time for the thread it waits for.
pub fn while_blocked<T>(clock: &dyn Clock, wait: impl FnOnce() -> T) -> T {
    clock.blocked(true);
    let result = wait();
    clock.blocked(false);
    result
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
    fn threaded_time_moves_when_every_thread_waits() -> std::io::Result<()> {
        let c = VirtualClock::threaded();
        let t0 = c.now();
        let shared = c.shared();
        let worker = {
            let c = c.clone();
            spawn(&shared, std::thread::Builder::new(), move || {
                let mut wakes = Vec::new();
                for _ in 0..5 {
                    c.sleep(Duration::from_millis(10));
                    wakes.push(c.since_base());
                }
                wakes
            })?
        };
        // The test thread sleeps 25 ms while the worker wakes every 10 ms.
        c.sleep(Duration::from_millis(25));
        assert_eq!(c.elapsed(t0), Duration::from_millis(25));
        let wakes = while_blocked(&c, || worker.join().unwrap_or_default());
        let ms: Vec<u128> = wakes.iter().map(Duration::as_millis).collect();
        assert_eq!(ms, vec![10, 20, 30, 40, 50]);
        assert_eq!(c.since_base(), Duration::from_millis(50), "the worker's last sleep");
        Ok(())
    }

    #[test]
    fn an_unpark_ends_a_park_at_the_instant_it_is_made() -> std::io::Result<()> {
        let c = VirtualClock::threaded();
        let shared = c.shared();
        let worker = {
            let c = c.clone();
            spawn(&shared, std::thread::Builder::new(), move || {
                // Woken at 2 ms, then nobody wakes it: it reaches its deadline.
                c.park_until(c.base() + Duration::from_millis(10));
                let woken = c.since_base();
                c.park_until(c.base() + Duration::from_millis(10));
                (woken, c.since_base())
            })?
        };
        let thread = worker.thread().clone();
        c.sleep(Duration::from_millis(2));
        c.unpark(&thread);
        let (woken, reached) = while_blocked(&c, || worker.join()).unwrap_or_default();
        assert_eq!(woken, Duration::from_millis(2));
        assert_eq!(reached, Duration::from_millis(10));
        // One thread of control: a token ends the next park at once, else it jumps.
        let one = VirtualClock::new();
        one.unpark(&std::thread::current());
        one.park_until(one.base() + Duration::from_secs(1));
        assert_eq!(one.since_base(), Duration::ZERO);
        one.park_until(one.base() + Duration::from_secs(1));
        assert_eq!(one.since_base(), Duration::from_secs(1));
        Ok(())
    }

    #[test]
    fn settle_waits_for_what_other_threads_do_in_the_same_instant() -> std::io::Result<()> {
        let c = VirtualClock::threaded();
        let shared = c.shared();
        let log = Arc::new(Mutex::new(Vec::new()));
        let worker = {
            let (c, log) = (c.clone(), Arc::clone(&log));
            spawn(&shared, std::thread::Builder::new(), move || {
                for _ in 0..3 {
                    c.park_until(c.base() + Duration::from_secs(1));
                    // Slow work in answer to the wake-up, in the same instant.
                    std::thread::sleep(Duration::from_millis(5));
                    log.lock().unwrap_or_else(PoisonError::into_inner).push(("answer", c.since_base()));
                }
            })?
        };
        let thread = worker.thread().clone();
        for _ in 0..3 {
            c.sleep(Duration::from_millis(1));
            c.unpark(&thread);
            c.settle();
            log.lock().unwrap_or_else(PoisonError::into_inner).push(("after", c.since_base()));
        }
        while_blocked(&c, || worker.join()).ok();
        let ms = Duration::from_millis;
        let log = log.lock().unwrap_or_else(PoisonError::into_inner).clone();
        assert_eq!(
            log,
            [
                ("answer", ms(1)),
                ("after", ms(1)),
                ("answer", ms(2)),
                ("after", ms(2)),
                ("answer", ms(3)),
                ("after", ms(3))
            ]
        );
        Ok(())
    }

    /// 100 transactions on `line`: each holds it for 1 ms of virtual time, then sleeps
    /// 0.1 ms. Returns the longest wait for the line.
    fn take_turns(c: &VirtualClock, line: &ClockMutex<u32>) -> Duration {
        let mut worst = Duration::ZERO;
        for _ in 0..100 {
            let asked = c.now();
            let mut l = line.lock();
            worst = worst.max(c.elapsed(asked));
            c.sleep(Duration::from_millis(1));
            *l += 1;
            drop(l);
            c.sleep(Duration::from_micros(100));
        }
        worst
    }

    #[test]
    fn a_lock_held_across_sleeps_is_handed_over_before_time_moves() -> std::io::Result<()> {
        // Two threads take turns on a "line": each holds it for 1 ms of virtual time per
        // transaction, then sleeps 0.1 ms. Each of 100 transactions must find the line at
        // the time it asked for it plus at most one other transaction (the hand-over never
        // lets time jump past a waiter).
        let c = VirtualClock::threaded();
        let shared = c.shared();
        let line = Arc::new(ClockMutex::new(0u32, c.shared()));
        let worker = {
            let (c, line) = (c.clone(), Arc::clone(&line));
            spawn(&shared, std::thread::Builder::new(), move || take_turns(&c, &line))?
        };
        let worst = take_turns(&c, &line);
        let other = while_blocked(&c, || worker.join().unwrap_or(Duration::MAX));
        assert_eq!(*line.lock(), 200);
        assert!(worst <= Duration::from_millis(1), "waited {worst:?}");
        assert!(other <= Duration::from_millis(1), "the worker waited {other:?}");
        // 200 transactions of 1 ms, one at a time.
        assert!(c.since_base() >= Duration::from_millis(200));
        assert!(c.since_base() <= Duration::from_millis(202), "{:?}", c.since_base());
        Ok(())
    }

    #[test]
    fn a_thread_that_ends_stops_holding_time_back() {
        let c = VirtualClock::threaded();
        let other = c.clone();
        // Takes part, then ends without sleeping.
        std::thread::spawn(move || other.join_thread()).join().ok();
        c.sleep(Duration::from_secs(1));
        assert_eq!(c.since_base(), Duration::from_secs(1));
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
