//! A small pool of dedicated threads for the Argon2 work (password checks and new hashes).
//!
//! Argon2 is slow and memory-hungry on purpose (19 MiB and tens of milliseconds per hash by
//! default). Run on the callers' threads, a burst of logins runs as many hashes at once as
//! there are callers (a web runtime allows hundreds of blocking threads): the CPU is starved
//! for everything else, and each thread gets its own allocator arena whose memory is kept
//! after the burst. The pool runs at most `workers` jobs at once, on its own long-lived
//! threads (so few arenas), and holds at most `queue` more waiting; [`HashPool::try_run`]
//! refuses at once beyond that with [`HashPoolError::Busy`].
//!
//! The threads start with the first job and end when the pool is dropped (after the job
//! they are running).

use std::fmt;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};

type Job = Box<dyn FnOnce() + Send + 'static>;

/// Why a job did not run (or gave no result).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum HashPoolError {
    /// Every worker is busy and the queue is full: try again shortly (HTTP 503).
    #[error("password hashing is busy; retry shortly")]
    Busy,
    /// No worker could be started, or the job panicked.
    #[error("password hashing failed: {0}")]
    Failed(String),
}

/// Jobs accepted and not yet finished (running or waiting), at most workers + queue.
#[derive(Debug, Default)]
struct Slots {
    taken: Mutex<usize>,
    freed: Condvar,
}

impl Slots {
    fn lock(&self) -> MutexGuard<'_, usize> {
        self.taken.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// One taken slot, given back when the job ends (also by a panic, or if it never runs).
struct Slot(Arc<Slots>);

impl Drop for Slot {
    fn drop(&mut self) {
        let mut taken = self.0.lock();
        *taken = taken.saturating_sub(1);
        drop(taken);
        self.0.freed.notify_one();
    }
}

/// The pool. Shared between callers (`&self` methods).
pub struct HashPool {
    workers: usize,
    queue: usize,
    slots: Arc<Slots>,
    sender: Mutex<Option<Sender<Job>>>,
    completed: Arc<AtomicU64>,
    rejected: AtomicU64,
}

impl fmt::Debug for HashPool {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("HashPool")
            .field("workers", &self.workers)
            .field("queue", &self.queue)
            .field("completed", &self.completed())
            .field("rejected", &self.rejected())
            .finish_non_exhaustive()
    }
}

impl HashPool {
    /// A pool of `workers` threads (at least 1) with room for `queue` waiting jobs (0: a job
    /// is accepted only when a worker is free). No thread starts before the first job.
    #[must_use]
    pub fn new(workers: usize, queue: usize) -> Self {
        HashPool {
            workers: workers.max(1),
            queue,
            slots: Arc::new(Slots::default()),
            sender: Mutex::new(None),
            completed: Arc::new(AtomicU64::new(0)),
            rejected: AtomicU64::new(0),
        }
    }

    /// Number of worker threads.
    #[must_use]
    pub fn workers(&self) -> usize {
        self.workers
    }

    /// Room for waiting jobs.
    #[must_use]
    pub fn queue(&self) -> usize {
        self.queue
    }

    /// Jobs run to their end (or panic) so far.
    #[must_use]
    pub fn completed(&self) -> u64 {
        self.completed.load(Ordering::Relaxed)
    }

    /// Jobs refused with [`HashPoolError::Busy`] so far.
    #[must_use]
    pub fn rejected(&self) -> u64 {
        self.rejected.load(Ordering::Relaxed)
    }

    /// Runs `job` on a worker and waits for its result; refuses at once when every worker is
    /// busy and the queue is full.
    ///
    /// # Errors
    /// [`HashPoolError::Busy`] (the job was not run), or [`HashPoolError::Failed`].
    pub fn try_run<T, F>(&self, job: F) -> Result<T, HashPoolError>
    where
        T: Send + 'static,
        F: FnOnce() -> T + Send + 'static,
    {
        self.submit(job, false)
    }

    /// Runs `job` on a worker and waits for its result, first waiting for room if the pool
    /// is full (for administrative work, which must not fail because of a login burst).
    ///
    /// # Errors
    /// [`HashPoolError::Failed`].
    pub fn run<T, F>(&self, job: F) -> Result<T, HashPoolError>
    where
        T: Send + 'static,
        F: FnOnce() -> T + Send + 'static,
    {
        self.submit(job, true)
    }

    fn submit<T, F>(&self, job: F, wait: bool) -> Result<T, HashPoolError>
    where
        T: Send + 'static,
        F: FnOnce() -> T + Send + 'static,
    {
        let sender = self.sender()?;
        let capacity = self.workers.saturating_add(self.queue);
        {
            let mut taken = self.slots.lock();
            while *taken >= capacity {
                if !wait {
                    self.rejected.fetch_add(1, Ordering::Relaxed);
                    return Err(HashPoolError::Busy);
                }
                taken = self.slots.freed.wait(taken).unwrap_or_else(PoisonError::into_inner);
            }
            *taken += 1;
        }
        let slot = Slot(Arc::clone(&self.slots));
        let (result_tx, result_rx) = mpsc::sync_channel::<T>(1);
        let boxed: Job = Box::new(move || {
            let result = job();
            // The slot is free before the caller has its result, so that the caller's next
            // job finds it free.
            drop(slot);
            // The caller waits for this unless it went away (nothing to do then).
            let _ = result_tx.send(result);
        });
        // A job that cannot be sent is dropped here, which frees its slot.
        sender.send(boxed).map_err(|_| HashPoolError::Failed("the hashing workers stopped".to_string()))?;
        result_rx.recv().map_err(|_| HashPoolError::Failed("the hashing job panicked".to_string()))
    }

    /// The job channel, starting the workers at the first call.
    fn sender(&self) -> Result<Sender<Job>, HashPoolError> {
        let mut guard = self.sender.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(s) = guard.as_ref() {
            return Ok(s.clone());
        }
        let (tx, rx) = mpsc::channel::<Job>();
        let rx = Arc::new(Mutex::new(rx));
        let mut started = 0;
        let mut last_error = None;
        for i in 0..self.workers {
            let rx = Arc::clone(&rx);
            let completed = Arc::clone(&self.completed);
            match std::thread::Builder::new().name(format!("motus-hash-{i}")).spawn(move || {
                // Hashing is web work: it yields to the machine (motus_realtime).
                motus_realtime::demote_current_thread_for_web();
                worker(&rx, &completed)
            }) {
                Ok(_) => started += 1,
                Err(e) => {
                    tracing::error!(error = %e, "cannot start a password hashing worker");
                    last_error = Some(e.to_string());
                }
            }
        }
        if started == 0 {
            return Err(HashPoolError::Failed(format!(
                "no hashing worker could be started: {}",
                last_error.unwrap_or_default()
            )));
        }
        tracing::debug!(workers = started, queue = self.queue, "password hashing pool started");
        *guard = Some(tx.clone());
        Ok(tx)
    }
}

fn worker(rx: &Mutex<Receiver<Job>>, completed: &AtomicU64) {
    loop {
        // The lock is held while waiting, so one idle worker waits on the channel and the
        // others on the lock; it is released before the job runs.
        let job = rx.lock().unwrap_or_else(PoisonError::into_inner).recv();
        let Ok(job) = job else { return };
        if catch_unwind(AssertUnwindSafe(job)).is_err() {
            tracing::error!("a password hashing job panicked");
        }
        completed.fetch_add(1, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use std::time::Duration;

    const LIVENESS: Duration = Duration::from_secs(30);

    #[test]
    fn runs_jobs_and_refuses_beyond_workers_plus_queue() {
        let pool = Arc::new(HashPool::new(1, 1));
        assert_eq!(pool.try_run(|| 2 + 2), Ok(4));
        // Occupy the worker until `release` is sent.
        let (started_tx, started_rx) = mpsc::channel();
        let (release_tx, release_rx) = mpsc::channel::<()>();
        let p = Arc::clone(&pool);
        let busy = std::thread::spawn(move || {
            p.try_run(move || {
                started_tx.send(()).unwrap();
                release_rx.recv().unwrap();
                1
            })
        });
        started_rx.recv_timeout(LIVENESS).unwrap();
        // Five callers at once: one job fits in the queue (it waits), four are refused at
        // once, while the worker is still occupied.
        let (done_tx, done_rx) = mpsc::channel();
        for _ in 0..5 {
            let p = Arc::clone(&pool);
            let done = done_tx.clone();
            std::thread::spawn(move || done.send(p.try_run(|| 2)).unwrap());
        }
        for _ in 0..4 {
            assert_eq!(done_rx.recv_timeout(LIVENESS).unwrap(), Err(HashPoolError::Busy));
        }
        release_tx.send(()).unwrap();
        assert_eq!(busy.join().unwrap(), Ok(1));
        assert_eq!(done_rx.recv_timeout(LIVENESS).unwrap(), Ok(2));
        assert_eq!(pool.rejected(), 4);
    }

    #[test]
    fn a_panicking_job_is_an_error_and_the_worker_survives() {
        let pool = HashPool::new(1, 0);
        let r: Result<(), _> = pool.run(|| panic!("boom"));
        assert!(matches!(r, Err(HashPoolError::Failed(_))), "{r:?}");
        assert_eq!(pool.run(|| 7), Ok(7));
    }
}
