//! Periodic polling and keep-alive: tasks run on one thread at their own periods, each
//! transaction taking the line through the shared [`crate::BusMaster`], so commands from
//! other users interleave between polls.
//!
//! The periods are on a [clock](motus_clock::Clock) (the system clock unless made with
//! [`Poller::with_clock`]); the thread is started with [`motus_clock::spawn`], so it takes
//! part in a threaded virtual clock's time.

use motus_clock::{SharedClock, SystemClock};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// The longest sleep of the polling thread, so that a stop is seen quickly.
const STOP_CHECK: Duration = Duration::from_millis(50);

type Task = Box<dyn FnMut() + Send>;

/// A set of periodic tasks, started with [`Poller::spawn`].
pub struct Poller {
    tasks: Vec<(Duration, Task)>,
    clock: SharedClock,
}

impl Default for Poller {
    fn default() -> Self {
        Poller::with_clock(SystemClock::shared())
    }
}

/// A running poller; dropping it stops the thread.
pub struct PollerHandle {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    clock: SharedClock,
}

impl Poller {
    /// An empty poller on the system clock.
    pub fn new() -> Self {
        Poller::default()
    }

    /// An empty poller whose periods are on `clock` (e.g. a threaded virtual clock shared
    /// with the test thread and the bus master).
    pub fn with_clock(clock: SharedClock) -> Self {
        Poller { tasks: Vec::new(), clock }
    }

    /// Adds a task that runs every `period`.
    pub fn every(mut self, period: Duration, task: impl FnMut() + Send + 'static) -> Self {
        self.tasks.push((period, Box::new(task)));
        self
    }

    /// Starts the polling thread.
    ///
    /// # Errors
    /// The thread could not be spawned.
    pub fn spawn(self) -> std::io::Result<PollerHandle> {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let clock = self.clock;
        let start = clock.now();
        let mut tasks: Vec<(Duration, Instant, Task)> =
            self.tasks.into_iter().map(|(p, t)| (p, start, t)).collect();
        let thread_clock = Arc::clone(&clock);
        let builder = std::thread::Builder::new().name("motus-poller".into());
        let thread = motus_clock::spawn(&clock, builder, move || {
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Device);
            let clock = thread_clock;
            while !flag.load(Ordering::Relaxed) {
                let now = clock.now();
                for (period, due, task) in tasks.iter_mut() {
                    if *due <= now {
                        task();
                        *due = (*due + *period).max(clock.now());
                    }
                }
                let now = clock.now();
                let next = tasks.iter().map(|(_, due, _)| *due).min().unwrap_or(now + STOP_CHECK);
                clock.sleep_until(next.min(now + STOP_CHECK));
            }
        })?;
        Ok(PollerHandle { stop, thread: Some(thread), clock })
    }
}

impl PollerHandle {
    /// Stops the thread and waits for it.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = motus_clock::while_blocked(&*self.clock, || t.join());
        }
    }
}

impl Drop for PollerHandle {
    fn drop(&mut self) {
        self.shutdown();
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use motus_clock::{Clock, VirtualClock};
    use std::sync::atomic::AtomicU32;

    #[test]
    fn tasks_run_at_their_periods_until_stopped() {
        // The poller's thread and this one share a threaded virtual clock: the counts are
        // exact, whatever the host's load.
        let clock = VirtualClock::threaded();
        let fast = Arc::new(AtomicU32::new(0));
        let slow = Arc::new(AtomicU32::new(0));
        let (f, s) = (fast.clone(), slow.clone());
        let handle = Poller::with_clock(clock.shared())
            .every(Duration::from_millis(10), move || {
                f.fetch_add(1, Ordering::Relaxed);
            })
            .every(Duration::from_millis(100), move || {
                s.fetch_add(1, Ordering::Relaxed);
            })
            .spawn()
            .unwrap();
        clock.sleep(Duration::from_millis(355));
        // At 0, 10, ..., 350 ms and at 0, 100, 200, 300 ms.
        assert_eq!((fast.load(Ordering::Relaxed), slow.load(Ordering::Relaxed)), (36, 4));
        handle.stop();
        assert_eq!(fast.load(Ordering::Relaxed), 36, "stopped");
    }

    #[test]
    fn tasks_run_on_the_system_clock_by_default() {
        let runs = Arc::new(AtomicU32::new(0));
        let r = runs.clone();
        let handle = Poller::new()
            .every(Duration::from_millis(5), move || {
                r.fetch_add(1, Ordering::Relaxed);
            })
            .spawn()
            .unwrap();
        // A liveness bound: a few runs within seconds.
        let t0 = std::time::Instant::now();
        while runs.load(Ordering::Relaxed) < 3 && t0.elapsed() < Duration::from_secs(10) {
            std::thread::sleep(Duration::from_millis(5));
        }
        handle.stop();
        assert!(runs.load(Ordering::Relaxed) >= 3);
    }
}
