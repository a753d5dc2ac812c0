//! The cell's cyclic `[[task]]`s on the station's [`Scheduler`]: each `trace` task records
//! the juggler drives' latest positions and speeds (raw units, from the monitor's PRes) into
//! the station's [`Recorder`] at its own period, with cycle-time and jitter monitoring and
//! an alarm on overruns (the scheduler's). Motion, supervisor and device work run on their
//! own event-driven threads (the supervisor evaluates every PRes, faster than any class).

use std::sync::{Arc, Mutex};
use std::time::Instant;

use motus_cell::JugglerHandle;
use motus_station::alarm::AlarmSink;
use motus_station::config::{Cell, TaskKind};
use motus_station::scheduler::{CyclicTask, Scheduler, SchedulerError, TaskClass, TaskError};
use motus_station::trace::{Recorder, SignalId, TraceError};

use crate::lock;

/// Why the tasks could not start.
#[derive(Debug, thiserror::Error)]
pub enum TasksError {
    /// A signal could not be registered.
    #[error("trace: {0}")]
    Trace(#[from] TraceError),
    /// A class could not start.
    #[error("{0}")]
    Scheduler(#[from] SchedulerError),
}

/// Samples kept per traced signal (10 s at 1 kHz).
pub const TRACE_CAPACITY: usize = 10_000;

/// Records the juggler's drives every cycle.
struct JugglerTrace {
    name: String,
    juggler: Arc<JugglerHandle>,
    recorder: Arc<Mutex<Recorder>>,
    /// Per node: (position, speed) signals.
    signals: Vec<(u8, SignalId, SignalId)>,
    epoch: Instant,
}

impl CyclicTask for JugglerTrace {
    fn name(&self) -> &str {
        &self.name
    }

    fn cycle(&mut self, now: Instant, _cycle: u64) -> Result<(), TaskError> {
        let t = now.saturating_duration_since(self.epoch);
        let mut rec = lock(&self.recorder);
        let signals = &self.signals;
        let mut result = Ok(());
        self.juggler.for_each_drive(|node, position, speed, _status| {
            if let Some((_, p, s)) = signals.iter().find(|(n, _, _)| *n == node) {
                let r =
                    rec.record(*p, t, f64::from(position)).and_then(|()| rec.record(*s, t, f64::from(speed)));
                if let Err(e) = r {
                    result = Err(TaskError::new(e.to_string()));
                }
            }
        });
        result
    }
}

/// The station's task classes and what they record.
pub struct Tasks {
    /// The running classes.
    pub scheduler: Scheduler,
    /// The traced signals.
    pub recorder: Arc<Mutex<Recorder>>,
}

/// Starts one class per `trace` task of `cell` (named after the task). `None` when there is
/// nothing to trace (no trace task, or no juggler).
///
/// # Errors
/// A signal name is invalid, or a class thread cannot start.
pub fn start(
    cell: &Cell,
    juggler: Option<&Arc<JugglerHandle>>,
    alarms: Arc<dyn AlarmSink>,
) -> Result<Option<Tasks>, TasksError> {
    let Some(juggler) = juggler else { return Ok(None) };
    let recorder = Arc::new(Mutex::new(Recorder::new(TRACE_CAPACITY)));
    let supervised: Vec<&str> = cell
        .groups
        .iter()
        .filter(|g| cell.supervisor.as_ref().is_some_and(|s| s.group.as_deref() == Some(g.name.as_str())))
        .flat_map(|g| g.axes.iter().map(String::as_str))
        .collect();
    let nodes: Vec<(u8, String)> = cell
        .devices
        .iter()
        .filter(|d| cell.axes.iter().any(|a| a.device == d.name && supervised.contains(&a.name.as_str())))
        .filter_map(|d| Some((u8::try_from(d.address?).ok()?, d.name.clone())))
        .collect();
    let epoch = Instant::now();
    let mut classes = Vec::new();
    for task in cell.tasks.iter().filter(|t| t.kind == TaskKind::Trace) {
        let mut signals = Vec::new();
        {
            let mut rec = lock(&recorder);
            for (node, device) in &nodes {
                let p = rec.register(&format!("{}/{device}.position", task.name), "raw")?;
                let s = rec.register(&format!("{}/{device}.speed", task.name), "raw")?;
                signals.push((*node, p, s));
            }
        }
        let trace = JugglerTrace {
            name: task.name.clone(),
            juggler: Arc::clone(juggler),
            recorder: Arc::clone(&recorder),
            signals,
            epoch,
        };
        classes.push(
            TaskClass::new(task.name.clone(), task.period)
                .with_overrun_limit(task.overrun_limit)
                .with_task(Box::new(trace)),
        );
    }
    if classes.is_empty() {
        return Ok(None);
    }
    Ok(Some(Tasks { scheduler: Scheduler::start(classes, alarms)?, recorder }))
}
