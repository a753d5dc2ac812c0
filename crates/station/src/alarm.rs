//! The alarm seam: the runtime raises and clears alarms through an [`AlarmSink`]; the
//! station connects it to its alarm store (history, acknowledgement, HMI).

use std::sync::Mutex;

/// How serious an alarm is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum AlarmSeverity {
    /// Information.
    Info,
    /// Needs attention; operation goes on.
    Warning,
    /// A function stopped (a task degraded, a device's axes faulted).
    Error,
}

/// What raised an alarm: one code per condition, so the store can clear it precisely.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AlarmCode {
    /// A task class missed its deadline (a cycle ran longer than the period).
    CycleOverrun,
    /// A task class degraded after consecutive overruns (its tasks stopped motion).
    TaskDegraded,
    /// A task's cycle returned an error.
    TaskError,
    /// A device is disconnected; its axes are faulted and stopped.
    DeviceDisconnected,
    /// A connected device latched a condition that only the operator can clear (a KV-01
    /// module's safety time-out needs a power cycle); the message says what to do.
    DeviceLatched,
}

impl AlarmCode {
    /// A stable short name (`cycle_overrun`...).
    pub fn as_str(self) -> &'static str {
        match self {
            AlarmCode::CycleOverrun => "cycle_overrun",
            AlarmCode::TaskDegraded => "task_degraded",
            AlarmCode::TaskError => "task_error",
            AlarmCode::DeviceDisconnected => "device_disconnected",
            AlarmCode::DeviceLatched => "device_latched",
        }
    }
}

/// One raised alarm.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Alarm {
    /// The condition.
    pub code: AlarmCode,
    /// Severity.
    pub severity: AlarmSeverity,
    /// What raised it: `task-class:1ms`, `task:omni`, `device:wheels`...
    pub source: String,
    /// A sentence for the operator.
    pub message: String,
}

/// Where the runtime sends alarms. Called from real-time threads: implementations must
/// return quickly (queue the alarm, never block on IO).
pub trait AlarmSink: Send + Sync {
    /// An alarm condition became true.
    fn raise(&self, alarm: Alarm);
    /// The condition `code` of `source` is gone.
    fn clear(&self, source: &str, code: AlarmCode);
}

/// Drops every alarm (for tools and benchmarks).
#[derive(Debug, Default, Clone, Copy)]
pub struct NullAlarms;

impl AlarmSink for NullAlarms {
    fn raise(&self, _alarm: Alarm) {}
    fn clear(&self, _source: &str, _code: AlarmCode) {}
}

/// Keeps alarms in memory: the raised ones in order and the currently active set.
#[derive(Debug, Default)]
pub struct MemoryAlarms {
    inner: Mutex<MemoryInner>,
}

#[derive(Debug, Default)]
struct MemoryInner {
    raised: Vec<Alarm>,
    active: Vec<(String, AlarmCode)>,
}

impl MemoryAlarms {
    /// An empty store.
    pub fn new() -> Self {
        Self::default()
    }

    /// Every alarm raised so far, in order.
    pub fn raised(&self) -> Vec<Alarm> {
        self.inner.lock().map(|g| g.raised.clone()).unwrap_or_default()
    }

    /// The (source, code) pairs raised and not cleared.
    pub fn active(&self) -> Vec<(String, AlarmCode)> {
        self.inner.lock().map(|g| g.active.clone()).unwrap_or_default()
    }

    /// Whether `code` of `source` is active.
    pub fn is_active(&self, source: &str, code: AlarmCode) -> bool {
        self.active().iter().any(|(s, c)| s == source && *c == code)
    }
}

impl AlarmSink for MemoryAlarms {
    fn raise(&self, alarm: Alarm) {
        if let Ok(mut g) = self.inner.lock() {
            let key = (alarm.source.clone(), alarm.code);
            if !g.active.contains(&key) {
                g.active.push(key);
            }
            g.raised.push(alarm);
        }
    }

    fn clear(&self, source: &str, code: AlarmCode) {
        if let Ok(mut g) = self.inner.lock() {
            g.active.retain(|(s, c)| !(s == source && *c == code));
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn memory_alarms_track_active_set() {
        let m = MemoryAlarms::new();
        let a = Alarm {
            code: AlarmCode::CycleOverrun,
            severity: AlarmSeverity::Warning,
            source: "task-class:1ms".into(),
            message: "late".into(),
        };
        m.raise(a.clone());
        m.raise(a);
        assert_eq!(m.raised().len(), 2);
        assert_eq!(m.active().len(), 1);
        assert!(m.is_active("task-class:1ms", AlarmCode::CycleOverrun));
        m.clear("task-class:1ms", AlarmCode::CycleOverrun);
        assert!(m.active().is_empty());
        assert_eq!(AlarmCode::DeviceDisconnected.as_str(), "device_disconnected");
    }
}
