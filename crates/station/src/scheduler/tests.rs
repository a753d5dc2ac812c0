#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::*;
use crate::alarm::{AlarmCode, MemoryAlarms};

#[derive(Default)]
struct Probe {
    cycles: Mutex<Vec<u64>>,
    degraded: AtomicU64,
    resumed: AtomicU64,
    /// Execution time of each cycle in microseconds (busy sleep).
    busy_us: AtomicU64,
    fail: AtomicBool,
}

struct ProbeTask {
    name: String,
    probe: Arc<Probe>,
}

impl CyclicTask for ProbeTask {
    fn name(&self) -> &str {
        &self.name
    }
    fn cycle(&mut self, _now: Instant, cycle: u64) -> Result<(), TaskError> {
        self.probe.cycles.lock().unwrap().push(cycle);
        let busy = self.probe.busy_us.load(Ordering::SeqCst);
        if busy > 0 {
            std::thread::sleep(Duration::from_micros(busy));
        }
        if self.probe.fail.load(Ordering::SeqCst) {
            return Err(TaskError::new("sensor missing"));
        }
        Ok(())
    }
    fn degrade(&mut self) {
        self.probe.degraded.fetch_add(1, Ordering::SeqCst);
    }
    fn resume(&mut self) {
        self.probe.resumed.fetch_add(1, Ordering::SeqCst);
    }
}

fn probe_class(name: &str, period: Duration) -> (TaskClass, Arc<Probe>) {
    let probe = Arc::new(Probe::default());
    let task = ProbeTask { name: format!("{name}-task"), probe: Arc::clone(&probe) };
    (TaskClass::new(name, period).with_task(Box::new(task)), probe)
}

fn wait_for(what: &str, timeout: Duration, mut f: impl FnMut() -> bool) {
    let deadline = Instant::now() + timeout;
    while !f() {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(2));
    }
}

#[test]
fn runs_cycles_at_the_period_and_stops_cleanly() {
    let (class, probe) = probe_class("fast", Duration::from_millis(2));
    let alarms = Arc::new(MemoryAlarms::new());
    let sched = Scheduler::start(vec![class], alarms.clone()).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let stats = sched.stop();
    let cycles = probe.cycles.lock().unwrap().clone();
    // 300 ms / 2 ms = 150 releases; allow for start-up and a loaded 2-core machine.
    assert!((100..=152).contains(&cycles.len()), "{} cycles", cycles.len());
    // Cycle numbers strictly increase (gaps only where releases were skipped).
    assert!(cycles.windows(2).all(|w| w[1] > w[0]));
    let s = &stats[0];
    assert_eq!(s.state, ClassState::Stopped);
    assert_eq!(s.cycles, cycles.len() as u64);
    assert_eq!(s.lateness.count, s.cycles);
    assert!(s.lateness.max < Duration::from_millis(50), "{s:?}");
    assert!(s.elapsed >= Duration::from_millis(250));
}

#[test]
fn consecutive_overruns_degrade_then_reset_and_resume_recover() {
    let (class, probe) = probe_class("ctl", Duration::from_millis(5));
    let class = class.with_overrun_limit(3);
    let alarms = Arc::new(MemoryAlarms::new());
    let sched = Scheduler::start(vec![class], alarms.clone()).unwrap();
    wait_for("first cycles", Duration::from_secs(2), || probe.cycles.lock().unwrap().len() >= 5);
    // Each cycle now takes 12 ms > 5 ms: every cycle overruns and skips >= 2 releases.
    probe.busy_us.store(12_000, Ordering::SeqCst);
    wait_for("degradation", Duration::from_secs(2), || probe.degraded.load(Ordering::SeqCst) == 1);
    let src = class_source("ctl");
    assert!(alarms.is_active(&src, AlarmCode::CycleOverrun));
    assert!(alarms.is_active(&src, AlarmCode::TaskDegraded));
    // One overrun alarm for the whole run of overruns, one degradation alarm.
    assert_eq!(alarms.raised().iter().filter(|a| a.code == AlarmCode::CycleOverrun).count(), 1);
    let s = sched.class_stats("ctl").unwrap();
    assert!(matches!(s.state, ClassState::Degraded { .. }), "{s:?}");
    assert!(s.overruns >= 3 && s.missed_cycles >= 3, "{s:?}");
    assert_eq!(s.degradations, 1);
    // Skipped releases leave gaps in the cycle numbers (never queued).
    let cycles = probe.cycles.lock().unwrap().clone();
    assert!(cycles.windows(2).any(|w| w[1] - w[0] >= 3), "{cycles:?}");
    // Degraded: no more cycles.
    let n = cycles.len();
    std::thread::sleep(Duration::from_millis(50));
    assert_eq!(probe.cycles.lock().unwrap().len(), n);

    // Recover remotely: the cause is gone, reset the alarms and resume.
    probe.busy_us.store(0, Ordering::SeqCst);
    sched.reset_alarms(None).unwrap();
    assert!(alarms.active().is_empty(), "{:?}", alarms.active());
    assert!(matches!(sched.class_stats("ctl").unwrap().state, ClassState::Degraded { .. }));
    sched.resume(Some("ctl")).unwrap();
    assert_eq!(probe.resumed.load(Ordering::SeqCst), 1);
    assert_eq!(sched.class_stats("ctl").unwrap().state, ClassState::Running);
    wait_for("cycles after resume", Duration::from_secs(2), || probe.cycles.lock().unwrap().len() >= n + 10);
    assert_eq!(sched.class_stats("ctl").unwrap().consecutive_overruns, 0);
    drop(sched);
}

#[test]
fn task_errors_raise_one_alarm_until_reset() {
    let (class, probe) = probe_class("io", Duration::from_millis(2));
    let alarms = Arc::new(MemoryAlarms::new());
    let sched = Scheduler::start(vec![class], alarms.clone()).unwrap();
    probe.fail.store(true, Ordering::SeqCst);
    wait_for("errors", Duration::from_secs(2), || sched.class_stats("io").unwrap().task_errors >= 5);
    let src = task_source("io-task");
    assert!(alarms.is_active(&src, AlarmCode::TaskError));
    // One task-error alarm for the five errors (a loaded host may add overrun alarms).
    let raised = alarms.raised();
    let task_errors: Vec<_> = raised.iter().filter(|a| a.code == AlarmCode::TaskError).collect();
    assert_eq!(task_errors.len(), 1, "{raised:?}");
    assert_eq!(task_errors[0].message, "task io-task: sensor missing");
    // Errors do not stop the class.
    assert_eq!(sched.class_stats("io").unwrap().state, ClassState::Running);
    probe.fail.store(false, Ordering::SeqCst);
    sched.reset_alarms(Some("io")).unwrap();
    // The task-error alarm is gone (a loaded host may raise a new overrun alarm meanwhile).
    assert!(!alarms.is_active(&src, AlarmCode::TaskError), "{:?}", alarms.active());
}

#[test]
fn operator_degrade_and_resume_one_class_only() {
    let (a, pa) = probe_class("a", Duration::from_millis(2));
    let (b, pb) = probe_class("b", Duration::from_millis(3));
    let alarms = Arc::new(MemoryAlarms::new());
    let sched = Scheduler::start(vec![a, b], alarms.clone()).unwrap();
    sched.degrade("a").unwrap();
    assert_eq!(pa.degraded.load(Ordering::SeqCst), 1);
    assert_eq!(pb.degraded.load(Ordering::SeqCst), 0);
    let nb = pb.cycles.lock().unwrap().len();
    wait_for("b keeps running", Duration::from_secs(2), || pb.cycles.lock().unwrap().len() > nb + 5);
    sched.resume(None).unwrap();
    assert_eq!(pa.resumed.load(Ordering::SeqCst), 1);
    assert_eq!(pb.resumed.load(Ordering::SeqCst), 0, "a running class is not resumed");
    assert_eq!(sched.degrade("zz"), Err(SchedulerError::UnknownClass { class: "zz".into() }));
    let names: Vec<String> = sched.stats().iter().map(|s| s.name.clone()).collect();
    assert_eq!(names, vec!["a", "b"]);
}

#[test]
fn invalid_classes_are_refused() {
    let alarms: Arc<dyn AlarmSink> = Arc::new(MemoryAlarms::new());
    let err = Scheduler::start(vec![TaskClass::new("z", Duration::ZERO)], Arc::clone(&alarms)).unwrap_err();
    assert_eq!(err, SchedulerError::ZeroPeriod { class: "z".into() });
    let err = Scheduler::start(
        vec![TaskClass::new("x", Duration::from_millis(1)), TaskClass::new("x", Duration::from_millis(2))],
        alarms,
    )
    .unwrap_err();
    assert_eq!(err, SchedulerError::DuplicateClass { class: "x".into() });
}

#[test]
fn a_blocked_task_shows_as_stalled_and_requests_time_out() {
    let (class, probe) = probe_class("slow", Duration::from_millis(10));
    let alarms = Arc::new(MemoryAlarms::new());
    let sched = Scheduler::start(vec![class], alarms.clone()).unwrap();
    wait_for("first cycle", Duration::from_secs(2), || !probe.cycles.lock().unwrap().is_empty());
    probe.busy_us.store(1_500_000, Ordering::SeqCst);
    std::thread::sleep(Duration::from_millis(400));
    assert_eq!(sched.class_stats("slow").unwrap().state, ClassState::Stalled);
    let err = sched.reset_alarms(Some("slow")).unwrap_err();
    assert!(matches!(err, SchedulerError::NotResponding { .. }), "{err:?}");
    probe.busy_us.store(0, Ordering::SeqCst);
    // Once the task returns, the pending request is served and the class runs again.
    wait_for("recovery", Duration::from_secs(3), || {
        sched.class_stats("slow").unwrap().state != ClassState::Stalled
            && probe.cycles.lock().unwrap().len() > 3
    });
}
