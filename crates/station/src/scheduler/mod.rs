//! The cyclic scheduler: task classes (e.g. 1 ms, 10 ms, 100 ms), each on its own
//! thread, releasing its tasks on absolute deadlines.
//!
//! * Sleeping: `std::thread::sleep` until shortly before the release (the thread's timer
//!   slack is set to 1 ns on Linux), then a short spin (`TaskClass::with_spin`).
//! * Statistics per class ([`ClassStats`]): start lateness and execution-time histograms
//!   (p50/p99/p99.9/max), overruns, missed cycles, CPU time of the thread (`getrusage(
//!   RUSAGE_THREAD)`).
//! * Overrun policy: a cycle that ends after the next release is an overrun; it is
//!   counted, raises [`AlarmCode::CycleOverrun`] (once per run of overruns), and the
//!   missed releases are skipped, never queued. After `overrun_limit` consecutive
//!   overruns the class **degrades**: every task's [`CyclicTask::degrade`] is called
//!   (stop motion) and cycles are suspended, with [`AlarmCode::TaskDegraded`] raised.
//! * Always recoverable: [`Scheduler::reset_alarms`] clears the alarms and counters,
//!   [`Scheduler::resume`] calls each task's [`CyclicTask::resume`] and restarts cycles.
//!   No state needs a restart of the process.
//! * [`Scheduler::stop`] (or drop) sets the stop flag and joins every thread.

mod stats;
mod thread;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

pub use stats::{thread_cpu_time, ClassState, ClassStats, Histogram, Percentiles};

use crate::alarm::{AlarmCode, AlarmSink};

/// A task's cycle failed; the class goes on, an alarm is raised.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{reason}")]
pub struct TaskError {
    /// What went wrong.
    pub reason: String,
}

impl TaskError {
    /// A task error with a reason.
    pub fn new(reason: impl Into<String>) -> Self {
        TaskError { reason: reason.into() }
    }
}

/// One cyclic task (a group's control cycle, the supervisor, trace recording...).
pub trait CyclicTask: Send {
    /// Name for statistics and alarms.
    fn name(&self) -> &str;

    /// One cycle. `now` is the actual start time, `cycle` the release number since the
    /// class started (skipped releases leave gaps). Must not block.
    fn cycle(&mut self, now: Instant, cycle: u64) -> Result<(), TaskError>;

    /// The class degraded: bring outputs to a safe state (stop motion). Called on the
    /// class thread; no `cycle` follows until [`CyclicTask::resume`].
    fn degrade(&mut self) {}

    /// The operator resumed the class after a degradation.
    fn resume(&mut self) {}
}

/// Scheduler errors.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SchedulerError {
    /// The period must be positive.
    #[error("task class {class}: the period must be positive")]
    ZeroPeriod {
        /// Class name.
        class: String,
    },
    /// Two classes share a name.
    #[error("task class {class} is defined twice")]
    DuplicateClass {
        /// Class name.
        class: String,
    },
    /// No such class.
    #[error("no task class named {class}")]
    UnknownClass {
        /// Class name.
        class: String,
    },
    /// The OS refused to start a thread.
    #[error("cannot start the thread of task class {class}: {reason}")]
    Spawn {
        /// Class name.
        class: String,
        /// OS error.
        reason: String,
    },
    /// The class thread did not pick a request up in time (a task is blocked).
    #[error("task class {class} did not respond within {waited:?} (a task is blocked in its cycle)")]
    NotResponding {
        /// Class name.
        class: String,
        /// How long we waited.
        waited: Duration,
    },
}

/// A task class before it starts: a period and its tasks.
pub struct TaskClass {
    name: String,
    period: Duration,
    overrun_limit: u32,
    spin: Duration,
    tasks: Vec<Box<dyn CyclicTask>>,
}

impl std::fmt::Debug for TaskClass {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TaskClass")
            .field("name", &self.name)
            .field("period", &self.period)
            .field("overrun_limit", &self.overrun_limit)
            .field("spin", &self.spin)
            .field("tasks", &self.tasks.iter().map(|t| t.name().to_string()).collect::<Vec<_>>())
            .finish()
    }
}

/// Default spin before each release.
pub const DEFAULT_SPIN: Duration = Duration::from_micros(30);

impl TaskClass {
    /// A class with no tasks yet; overrun limit 3, spin [`DEFAULT_SPIN`].
    pub fn new(name: impl Into<String>, period: Duration) -> Self {
        TaskClass {
            name: name.into(),
            period,
            overrun_limit: crate::config::DEFAULT_OVERRUN_LIMIT,
            spin: DEFAULT_SPIN,
            tasks: Vec::new(),
        }
    }

    /// Consecutive overruns before the class degrades (at least 1).
    pub fn with_overrun_limit(mut self, n: u32) -> Self {
        self.overrun_limit = n.max(1);
        self
    }

    /// How long before each release the thread stops sleeping and spins (zero: no spin).
    pub fn with_spin(mut self, spin: Duration) -> Self {
        self.spin = spin;
        self
    }

    /// Adds a task (tasks run in the order added).
    pub fn with_task(mut self, task: Box<dyn CyclicTask>) -> Self {
        self.tasks.push(task);
        self
    }

    /// Adds a task.
    pub fn add(&mut self, task: Box<dyn CyclicTask>) {
        self.tasks.push(task);
    }

    /// Class name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Period.
    pub fn period(&self) -> Duration {
        self.period
    }
}

/// Requests from the API to a class thread (bit flags in an atomic).
pub(crate) mod req {
    /// Clear alarms and consecutive-overrun counters.
    pub const RESET_ALARMS: u64 = 1;
    /// Leave the degraded state.
    pub const RESUME: u64 = 2;
    /// Degrade now (operator's request).
    pub const DEGRADE: u64 = 4;
    /// Zero the statistics.
    pub const RESET_STATS: u64 = 8;
}

/// State shared between the API and one class thread.
pub(crate) struct Shared {
    pub name: String,
    pub period: Duration,
    pub stop: AtomicBool,
    pub requests: AtomicU64,
    /// Time of the last cycle start (ns since `epoch`), to detect a stall.
    pub last_start_ns: AtomicU64,
    pub epoch: Instant,
    pub stats: Mutex<ClassStats>,
}

struct ClassHandle {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

/// Running task classes.
pub struct Scheduler {
    classes: Vec<ClassHandle>,
}

impl std::fmt::Debug for Scheduler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scheduler")
            .field("classes", &self.classes.iter().map(|c| &c.shared.name).collect::<Vec<_>>())
            .finish()
    }
}

impl Scheduler {
    /// Starts one thread (`motus-<class>`) per class.
    pub fn start(classes: Vec<TaskClass>, alarms: Arc<dyn AlarmSink>) -> Result<Scheduler, SchedulerError> {
        for (i, c) in classes.iter().enumerate() {
            if c.period.is_zero() {
                return Err(SchedulerError::ZeroPeriod { class: c.name.clone() });
            }
            if classes.iter().take(i).any(|o| o.name == c.name) {
                return Err(SchedulerError::DuplicateClass { class: c.name.clone() });
            }
        }
        let mut sched = Scheduler { classes: Vec::new() };
        for class in classes {
            let epoch = Instant::now();
            let shared = Arc::new(Shared {
                name: class.name.clone(),
                period: class.period,
                stop: AtomicBool::new(false),
                requests: AtomicU64::new(0),
                last_start_ns: AtomicU64::new(0),
                epoch,
                stats: Mutex::new(thread::empty_stats(&class.name, class.period)),
            });
            let name = class.name.clone();
            let s = Arc::clone(&shared);
            let a = Arc::clone(&alarms);
            let handle = std::thread::Builder::new()
                .name(format!("motus-{name}"))
                .spawn(move || {
                    motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Cyclic);
                    thread::run(class, &s, a.as_ref())
                })
                .map_err(|e| SchedulerError::Spawn { class: name, reason: e.to_string() })?;
            sched.classes.push(ClassHandle { shared, thread: Some(handle) });
        }
        Ok(sched)
    }

    /// Statistics of every class, in start order.
    pub fn stats(&self) -> Vec<ClassStats> {
        self.classes.iter().map(|c| snapshot(&c.shared)).collect()
    }

    /// Statistics of one class.
    pub fn class_stats(&self, class: &str) -> Option<ClassStats> {
        self.find(class).ok().map(|c| snapshot(&c.shared))
    }

    fn find(&self, class: &str) -> Result<&ClassHandle, SchedulerError> {
        self.classes
            .iter()
            .find(|c| c.shared.name == class)
            .ok_or_else(|| SchedulerError::UnknownClass { class: class.to_string() })
    }

    fn request(&self, class: Option<&str>, bit: u64) -> Result<(), SchedulerError> {
        let targets: Vec<&ClassHandle> = match class {
            Some(name) => vec![self.find(name)?],
            None => self.classes.iter().collect(),
        };
        for c in &targets {
            c.shared.requests.fetch_or(bit, Ordering::SeqCst);
        }
        for c in targets {
            // The thread picks requests up at least every 50 ms (even degraded or with a
            // long period), and after the current cycle.
            let waited = c.shared.period.min(Duration::from_millis(50)) * 4 + Duration::from_millis(500);
            let deadline = Instant::now() + waited;
            while c.shared.requests.load(Ordering::SeqCst) & bit != 0 {
                let finished = match &c.thread {
                    Some(t) => t.is_finished(),
                    None => true,
                };
                if finished {
                    break;
                }
                if Instant::now() > deadline {
                    return Err(SchedulerError::NotResponding { class: c.shared.name.clone(), waited });
                }
                std::thread::sleep(Duration::from_micros(200));
            }
        }
        Ok(())
    }

    /// Clears the alarms of a class (or of all, `None`) and its consecutive-overrun and
    /// task-error latches. Does not leave the degraded state: see [`Scheduler::resume`].
    pub fn reset_alarms(&self, class: Option<&str>) -> Result<(), SchedulerError> {
        self.request(class, req::RESET_ALARMS)
    }

    /// Leaves the degraded state (calls every task's `resume`), clearing the alarms too.
    /// A running class is unaffected.
    pub fn resume(&self, class: Option<&str>) -> Result<(), SchedulerError> {
        self.request(class, req::RESUME | req::RESET_ALARMS)
    }

    /// Degrades a class now (operator's stop): every task's `degrade` is called.
    pub fn degrade(&self, class: &str) -> Result<(), SchedulerError> {
        self.request(Some(class), req::DEGRADE)
    }

    /// Zeroes the statistics of a class (or of all).
    pub fn reset_stats(&self, class: Option<&str>) -> Result<(), SchedulerError> {
        self.request(class, req::RESET_STATS)
    }

    /// Stops every class (each finishes its current cycle) and joins the threads;
    /// returns the final statistics.
    pub fn stop(mut self) -> Vec<ClassStats> {
        self.shutdown();
        self.stats()
    }

    fn shutdown(&mut self) {
        for c in &self.classes {
            c.shared.stop.store(true, Ordering::SeqCst);
        }
        for c in &mut self.classes {
            if let Some(t) = c.thread.take() {
                if t.join().is_err() {
                    tracing::error!(class = %c.shared.name, "task class thread panicked");
                    if let Ok(mut s) = c.shared.stats.lock() {
                        s.state = ClassState::Stopped;
                    }
                }
            }
        }
    }
}

impl Drop for Scheduler {
    fn drop(&mut self) {
        self.shutdown();
    }
}

fn snapshot(shared: &Shared) -> ClassStats {
    let mut s = match shared.stats.lock() {
        Ok(g) => g.clone(),
        Err(p) => p.into_inner().clone(),
    };
    if s.state == ClassState::Running {
        let last = Duration::from_nanos(shared.last_start_ns.load(Ordering::SeqCst));
        let now = shared.epoch.elapsed();
        if now.saturating_sub(last) > shared.period * 10 + Duration::from_millis(100) {
            s.state = ClassState::Stalled;
        }
    }
    s
}

/// The alarm source name of a class.
pub fn class_source(class: &str) -> String {
    format!("task-class:{class}")
}

/// The alarm source name of a task.
pub fn task_source(task: &str) -> String {
    format!("task:{task}")
}

/// Alarm codes a class raises (for clearing in bulk).
pub const CLASS_ALARMS: [AlarmCode; 2] = [AlarmCode::CycleOverrun, AlarmCode::TaskDegraded];

#[cfg(test)]
mod tests;
