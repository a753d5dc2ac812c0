//! A cyclic task that samples probes into a shared recorder at its class's cycle.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use super::{Recorder, SignalId};
use crate::scheduler::{CyclicTask, TaskError};

/// Reads one signal's current value (`None`: no value this cycle, nothing recorded).
pub type Probe = Box<dyn FnMut() -> Option<f64> + Send>;

/// Records its probes into a shared [`Recorder`] every cycle, timestamped with the
/// cycle's start relative to `epoch`.
pub struct TraceTask {
    name: String,
    recorder: Arc<Mutex<Recorder>>,
    epoch: Instant,
    probes: Vec<(SignalId, Probe)>,
    values: Vec<Option<f64>>,
}

impl std::fmt::Debug for TraceTask {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TraceTask").field("name", &self.name).field("probes", &self.probes.len()).finish()
    }
}

impl TraceTask {
    /// A task recording into `recorder`; times are measured from `epoch`.
    pub fn new(name: impl Into<String>, recorder: Arc<Mutex<Recorder>>, epoch: Instant) -> Self {
        TraceTask { name: name.into(), recorder, epoch, probes: Vec::new(), values: Vec::new() }
    }

    /// Adds a probe for a registered signal.
    pub fn probe(mut self, signal: SignalId, probe: Probe) -> Self {
        self.probes.push((signal, probe));
        self.values.push(None);
        self
    }
}

impl CyclicTask for TraceTask {
    fn name(&self) -> &str {
        &self.name
    }

    fn cycle(&mut self, now: Instant, _cycle: u64) -> Result<(), TaskError> {
        // Read the probes before taking the lock, so the HMI reader blocks us briefly.
        for ((_, p), v) in self.probes.iter_mut().zip(self.values.iter_mut()) {
            *v = p();
        }
        let t = now.saturating_duration_since(self.epoch);
        let mut rec = self.recorder.lock().map_err(|_| TaskError::new("trace recorder lock poisoned"))?;
        for ((id, _), v) in self.probes.iter().zip(&self.values) {
            if let Some(v) = v {
                rec.record(*id, t, *v).map_err(|e| TaskError::new(e.to_string()))?;
            }
        }
        Ok(())
    }
}
