//! The loop of one task-class thread: absolute releases, skip-not-queue, degrade, requests.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use super::stats::{thread_cpu_time, ClassState, ClassStats, Histogram, Percentiles};
use super::{class_source, req, task_source, Shared, TaskClass, CLASS_ALARMS};
use crate::alarm::{Alarm, AlarmCode, AlarmSeverity, AlarmSink};

/// Longest single sleep: stop and requests are seen at least this often.
const MAX_SLEEP: Duration = Duration::from_millis(50);
/// Statistics are published to readers about this often.
const PUBLISH_EVERY: Duration = Duration::from_millis(20);

/// Statistics of a class that has not run yet.
pub(crate) fn empty_stats(name: &str, period: Duration) -> ClassStats {
    ClassStats {
        name: name.to_string(),
        period,
        state: ClassState::Running,
        cycles: 0,
        missed_cycles: 0,
        overruns: 0,
        consecutive_overruns: 0,
        degradations: 0,
        task_errors: 0,
        lateness: Percentiles::default(),
        execution: Percentiles::default(),
        cpu_time: Duration::ZERO,
        elapsed: Duration::ZERO,
    }
}

/// Thread-local bookkeeping.
struct Local {
    lateness: Histogram,
    exec: Histogram,
    cycles: u64,
    missed: u64,
    overruns: u64,
    consecutive: u32,
    degradations: u64,
    task_errors: u64,
    cpu_base: Duration,
    reset_at: Instant,
    overrun_alarm: bool,
    task_alarm: Vec<bool>,
    state: ClassState,
}

impl Local {
    fn new(tasks: usize) -> Self {
        Local {
            lateness: Histogram::default(),
            exec: Histogram::default(),
            cycles: 0,
            missed: 0,
            overruns: 0,
            consecutive: 0,
            degradations: 0,
            task_errors: 0,
            cpu_base: thread_cpu_time().unwrap_or_default(),
            reset_at: Instant::now(),
            overrun_alarm: false,
            task_alarm: vec![false; tasks],
            state: ClassState::Running,
        }
    }
}

struct Ctx<'a> {
    class: TaskClass,
    shared: &'a Shared,
    alarms: &'a dyn AlarmSink,
    local: Local,
    source: String,
}

impl Ctx<'_> {
    fn publish(&self) {
        let l = &self.local;
        let stats = ClassStats {
            name: self.class.name.clone(),
            period: self.class.period,
            state: l.state.clone(),
            cycles: l.cycles,
            missed_cycles: l.missed,
            overruns: l.overruns,
            consecutive_overruns: l.consecutive,
            degradations: l.degradations,
            task_errors: l.task_errors,
            lateness: l.lateness.percentiles(),
            execution: l.exec.percentiles(),
            cpu_time: thread_cpu_time().unwrap_or_default().saturating_sub(l.cpu_base),
            elapsed: l.reset_at.elapsed(),
        };
        match self.shared.stats.lock() {
            Ok(mut g) => *g = stats,
            Err(p) => *p.into_inner() = stats,
        }
    }

    fn overrun(&mut self, missed: u64, why: &str) {
        let l = &mut self.local;
        l.overruns += 1;
        l.missed += missed;
        l.consecutive = l.consecutive.saturating_add(1);
        if !l.overrun_alarm {
            l.overrun_alarm = true;
            self.alarms.raise(Alarm {
                code: AlarmCode::CycleOverrun,
                severity: AlarmSeverity::Warning,
                source: self.source.clone(),
                message: format!(
                    "task class {} ({:?}): {why}; {missed} release(s) skipped",
                    self.class.name, self.class.period
                ),
            });
        }
        if self.local.consecutive >= self.class.overrun_limit && self.local.state == ClassState::Running {
            let reason = format!("{} consecutive cycle overruns", self.local.consecutive);
            self.degrade(reason);
        }
    }

    fn degrade(&mut self, reason: String) {
        tracing::error!(class = %self.class.name, %reason, "task class degraded: stopping its tasks");
        // The state is published first, then the alarm raised, then the tasks told: whoever
        // sees the alarm or a task's reaction reads the class as degraded.
        let message = format!(
            "task class {} degraded ({reason}): its tasks stopped; reset the alarms and resume",
            self.class.name
        );
        self.local.degradations += 1;
        self.local.state = ClassState::Degraded { reason };
        self.publish();
        self.alarms.raise(Alarm {
            code: AlarmCode::TaskDegraded,
            severity: AlarmSeverity::Error,
            source: self.source.clone(),
            message,
        });
        for t in &mut self.class.tasks {
            t.degrade();
        }
    }

    fn handle_requests(&mut self, release: &mut Instant) {
        let bits = self.shared.requests.load(Ordering::SeqCst);
        if bits == 0 {
            return;
        }
        if bits & req::DEGRADE != 0 && self.local.state == ClassState::Running {
            self.degrade("operator request".to_string());
        }
        if bits & req::RESET_ALARMS != 0 {
            for code in CLASS_ALARMS {
                self.alarms.clear(&self.source, code);
            }
            for (t, latched) in self.class.tasks.iter().zip(self.local.task_alarm.iter_mut()) {
                if *latched {
                    self.alarms.clear(&task_source(t.name()), AlarmCode::TaskError);
                    *latched = false;
                }
            }
            self.local.overrun_alarm = false;
            self.local.consecutive = 0;
        }
        if bits & req::RESUME != 0 && matches!(self.local.state, ClassState::Degraded { .. }) {
            tracing::info!(class = %self.class.name, "task class resumed");
            for t in &mut self.class.tasks {
                t.resume();
            }
            self.local.state = ClassState::Running;
            self.local.consecutive = 0;
            *release = Instant::now() + self.class.period;
        }
        if bits & req::RESET_STATS != 0 {
            let tasks = self.local.task_alarm.clone();
            let state = self.local.state.clone();
            let overrun_alarm = self.local.overrun_alarm;
            self.local = Local::new(0);
            self.local.task_alarm = tasks;
            self.local.state = state;
            self.local.overrun_alarm = overrun_alarm;
        }
        self.publish();
        self.shared.requests.fetch_and(!bits, Ordering::SeqCst);
    }

    fn run_cycle(&mut self, start: Instant, cycle: u64) {
        for (i, t) in self.class.tasks.iter_mut().enumerate() {
            if let Err(e) = t.cycle(start, cycle) {
                self.local.task_errors += 1;
                if let Some(latched) = self.local.task_alarm.get_mut(i) {
                    if !*latched {
                        *latched = true;
                        tracing::warn!(task = t.name(), error = %e, "task cycle failed");
                        self.alarms.raise(Alarm {
                            code: AlarmCode::TaskError,
                            severity: AlarmSeverity::Warning,
                            source: task_source(t.name()),
                            message: format!("task {}: {e}", t.name()),
                        });
                    }
                }
            }
        }
    }
}

/// Whole periods in `d` (rounded down).
fn periods_in(d: Duration, period: Duration) -> u64 {
    u64::try_from(d.as_nanos() / period.as_nanos().max(1)).unwrap_or(u64::MAX)
}

fn period_times(period: Duration, n: u64) -> Duration {
    period.saturating_mul(u32::try_from(n).unwrap_or(u32::MAX))
}

/// The class thread's body.
pub(crate) fn run(class: TaskClass, shared: &Shared, alarms: &dyn AlarmSink) {
    #[cfg(target_os = "linux")]
    if let Err(e) = nix::sys::prctl::set_timerslack(1) {
        tracing::debug!(error = %e, "cannot reduce the timer slack");
    }
    let period = class.period;
    let spin = class.spin.min(period);
    let publish_every = periods_in(PUBLISH_EVERY, period).max(1);
    let tasks = class.tasks.len();
    let mut ctx = Ctx { source: class_source(&class.name), class, shared, alarms, local: Local::new(tasks) };
    ctx.publish();
    let mut release = Instant::now() + period;
    let mut cycle: u64 = 0;
    let mut since_publish: u64 = 0;
    while !shared.stop.load(Ordering::Relaxed) {
        if shared.requests.load(Ordering::Relaxed) != 0 {
            ctx.handle_requests(&mut release);
        }
        let now = Instant::now();
        if matches!(ctx.local.state, ClassState::Degraded { .. }) {
            // Suspended: keep the release grid moving with time, wait for resume.
            if now > release {
                let n = periods_in(now - release, period) + 1;
                release += period_times(period, n);
                cycle += n;
            }
            std::thread::sleep(period.min(MAX_SLEEP));
            continue;
        }
        if now < release {
            let left = release - now;
            if left > spin {
                std::thread::sleep((left - spin).min(MAX_SLEEP));
                continue;
            }
            while Instant::now() < release {
                std::hint::spin_loop();
            }
        }
        let mut start = Instant::now();
        // Woke a whole period (or more) late: those releases are skipped.
        if start >= release + period {
            let missed = periods_in(start - release, period);
            release += period_times(period, missed);
            cycle += missed;
            ctx.overrun(missed, "the thread woke up after the next release");
            if !matches!(ctx.local.state, ClassState::Running) {
                continue;
            }
            start = Instant::now();
        }
        shared.last_start_ns.store(
            u64::try_from(start.duration_since(shared.epoch).as_nanos()).unwrap_or(u64::MAX),
            Ordering::Relaxed,
        );
        ctx.run_cycle(start, cycle);
        let end = Instant::now();
        ctx.local.lateness.record(start.saturating_duration_since(release));
        ctx.local.exec.record(end - start);
        ctx.local.cycles += 1;
        let next = release + period;
        if end > next {
            let missed = periods_in(end - next, period) + 1;
            release = next + period_times(period, missed);
            cycle += 1 + missed;
            ctx.overrun(missed, &format!("a cycle took {:?}", end - start));
        } else {
            release = next;
            cycle += 1;
            ctx.local.consecutive = 0;
        }
        since_publish += 1;
        if since_publish >= publish_every {
            since_publish = 0;
            ctx.publish();
        }
    }
    ctx.local.state = ClassState::Stopped;
    ctx.publish();
}
