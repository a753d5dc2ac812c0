//! Periodic polling and keep-alive: tasks run on one thread at their own periods, each
//! transaction taking the line through the shared [`crate::BusMaster`], so commands from
//! other users interleave between polls.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

type Task = Box<dyn FnMut() + Send>;

/// A set of periodic tasks, started with [`Poller::spawn`].
#[derive(Default)]
pub struct Poller {
    tasks: Vec<(Duration, Task)>,
}

/// A running poller; dropping it stops the thread.
pub struct PollerHandle {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Poller {
    /// An empty poller.
    pub fn new() -> Self {
        Poller::default()
    }

    /// Adds a task that runs every `period`.
    pub fn every(mut self, period: Duration, task: impl FnMut() + Send + 'static) -> Self {
        self.tasks.push((period, Box::new(task)));
        self
    }

    /// Starts the polling thread.
    pub fn spawn(self) -> std::io::Result<PollerHandle> {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let mut tasks: Vec<(Duration, Instant, Task)> =
            self.tasks.into_iter().map(|(p, t)| (p, Instant::now(), t)).collect();
        let thread = std::thread::Builder::new().name("motus-poller".into()).spawn(move || {
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Device);
            while !flag.load(Ordering::Relaxed) {
                let now = Instant::now();
                for (period, due, task) in tasks.iter_mut() {
                    if *due <= now {
                        task();
                        *due = (*due + *period).max(Instant::now());
                    }
                }
                let next = tasks.iter().map(|(_, due, _)| *due).min();
                let wait = next
                    .map(|d| d.saturating_duration_since(Instant::now()))
                    .unwrap_or(Duration::from_millis(50));
                std::thread::sleep(wait.min(Duration::from_millis(50)));
            }
        })?;
        Ok(PollerHandle { stop, thread: Some(thread) })
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
            let _ = t.join();
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
    use std::sync::atomic::AtomicU32;

    #[test]
    fn tasks_run_at_their_periods_until_stopped() {
        let fast = Arc::new(AtomicU32::new(0));
        let slow = Arc::new(AtomicU32::new(0));
        let (f, s) = (fast.clone(), slow.clone());
        let handle = Poller::new()
            .every(Duration::from_millis(10), move || {
                f.fetch_add(1, Ordering::Relaxed);
            })
            .every(Duration::from_millis(100), move || {
                s.fetch_add(1, Ordering::Relaxed);
            })
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(350));
        handle.stop();
        let (f, s) = (fast.load(Ordering::Relaxed), slow.load(Ordering::Relaxed));
        assert!((20..=40).contains(&f), "fast task ran {f} times");
        assert!((3..=5).contains(&s), "slow task ran {s} times");
        std::thread::sleep(Duration::from_millis(50));
        assert_eq!(fast.load(Ordering::Relaxed), f, "stopped");
    }
}
