//! Waiting for an axis to reach a condition, with progress callbacks.

use crate::{Axis, AxisError, AxisState};
use std::time::{Duration, Instant};

/// How a wait ended.
#[derive(Debug, Clone, PartialEq)]
pub enum WaitOutcome {
    /// The condition held; the last state read.
    Done(AxisState),
}

/// Polls `axis` every `period` until `done(state)` is true, a fault appears, or `timeout`
/// elapses. `progress` sees every state read (for progress bars). A fault stops the wait
/// with [`AxisError::DeviceFault`].
pub fn wait_until(
    axis: &mut dyn Axis,
    what: &str,
    timeout: Duration,
    period: Duration,
    mut done: impl FnMut(&AxisState) -> bool,
    mut progress: impl FnMut(&AxisState),
) -> Result<WaitOutcome, AxisError> {
    let start = Instant::now();
    loop {
        let state = axis.read_state()?;
        progress(&state);
        if let Some(fault) = state.faults.first() {
            return Err(AxisError::DeviceFault {
                axis: axis.name().to_string(),
                reason: fault.reason.clone(),
            });
        }
        if done(&state) {
            return Ok(WaitOutcome::Done(state));
        }
        if start.elapsed() >= timeout {
            return Err(AxisError::WaitTimeout {
                axis: axis.name().to_string(),
                what: what.to_string(),
                timeout,
            });
        }
        std::thread::sleep(period);
    }
}
