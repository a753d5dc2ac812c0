//! Waiting for an axis to reach a condition, with progress callbacks, on a clock.

use crate::{Axis, AxisError, AxisState};
use motus_clock::Clock;
use std::time::Duration;

/// How a wait ended.
#[derive(Debug, Clone, PartialEq)]
pub enum WaitOutcome {
    /// The condition held; the last state read.
    Done(AxisState),
}

/// Polls `axis` every `period` of `clock` until `done(state)` is true, a fault appears, or
/// `timeout` elapses on `clock`. `progress` sees every state read (for progress bars). A fault
/// stops the wait with [`AxisError::DeviceFault`]. The CLI waits on the system clock; tests
/// wait on a [`motus_clock::VirtualClock`].
pub fn wait_until(
    clock: &dyn Clock,
    axis: &mut dyn Axis,
    what: &str,
    timeout: Duration,
    period: Duration,
    mut done: impl FnMut(&AxisState) -> bool,
    mut progress: impl FnMut(&AxisState),
) -> Result<WaitOutcome, AxisError> {
    let start = clock.now();
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
        if clock.elapsed(start) >= timeout {
            return Err(AxisError::WaitTimeout {
                axis: axis.name().to_string(),
                what: what.to_string(),
                timeout,
            });
        }
        clock.sleep(period);
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::panic)]
    use super::*;
    use crate::{AxisCommand, AxisFlags, Capabilities, Fault, FaultKind, Scale};
    use motus_clock::{SharedClock, VirtualClock};
    use std::time::Instant;

    /// An axis moving at 1 unit per ms of the clock from 0 to `target`; faulted from
    /// `fault_at` on.
    struct Ramp {
        clock: SharedClock,
        start: Instant,
        target: i64,
        fault_at: Option<i64>,
        reads: u32,
    }

    impl Axis for Ramp {
        fn name(&self) -> &str {
            "ramp"
        }
        fn capabilities(&self) -> Capabilities {
            Capabilities::POSITIONING
        }
        fn scale(&self) -> &Scale {
            &Scale::HUNDREDTH_MM
        }
        fn read_state(&mut self) -> Result<AxisState, AxisError> {
            self.reads += 1;
            let ms = i64::try_from(self.clock.elapsed(self.start).as_millis()).unwrap();
            let position_raw = ms.min(self.target);
            let faults = match self.fault_at {
                Some(at) if position_raw >= at => {
                    vec![Fault { kind: FaultKind::FollowingError, reason: "following error".into() }]
                }
                _ => Vec::new(),
            };
            Ok(AxisState {
                position: 0.0,
                position_raw,
                velocity: None,
                current: None,
                following_error: None,
                flags: AxisFlags { moving: position_raw < self.target, ..AxisFlags::default() },
                faults,
            })
        }
        fn execute(&mut self, _: &AxisCommand) -> Result<(), AxisError> {
            Ok(())
        }
    }

    fn ramp(clock: &VirtualClock, target: i64, fault_at: Option<i64>) -> Ramp {
        Ramp { clock: clock.shared(), start: clock.now(), target, fault_at, reads: 0 }
    }

    const PERIOD: Duration = Duration::from_millis(20);

    /// Waits every [`PERIOD`] for the axis to stand still, without progress.
    fn wait_for_standstill(
        clock: &VirtualClock,
        axis: &mut Ramp,
        what: &str,
        timeout: Duration,
    ) -> Result<WaitOutcome, AxisError> {
        wait_until(clock, axis, what, timeout, PERIOD, |s| !s.flags.moving, |_| {})
    }

    #[test]
    fn ends_at_the_first_poll_after_the_motion_ends() {
        let clock = VirtualClock::new();
        let mut axis = ramp(&clock, 95, None);
        let mut seen = Vec::new();
        let t0 = clock.now();
        let out = wait_until(
            &clock,
            &mut axis,
            "move",
            Duration::from_secs(1),
            PERIOD,
            |s| !s.flags.moving,
            |s| seen.push(s.position_raw),
        )
        .unwrap();
        let WaitOutcome::Done(state) = out;
        assert_eq!(state.position_raw, 95);
        assert_eq!(seen, vec![0, 20, 40, 60, 80, 95]);
        assert_eq!(clock.elapsed(t0), Duration::from_millis(100));
    }

    #[test]
    fn times_out_on_the_clock_naming_what_it_waited_for() {
        let clock = VirtualClock::new();
        let mut axis = ramp(&clock, 10_000, None);
        let t0 = clock.now();
        let err = wait_for_standstill(&clock, &mut axis, "home", Duration::from_millis(150)).unwrap_err();
        assert!(matches!(&err, AxisError::WaitTimeout { what, .. } if what == "home"), "{err}");
        assert_eq!(clock.elapsed(t0), Duration::from_millis(160), "the first poll at or past 150 ms");
        assert_eq!(axis.reads, 9);
    }

    #[test]
    fn a_fault_ends_the_wait_with_the_devices_reason() {
        let clock = VirtualClock::new();
        let mut axis = ramp(&clock, 1000, Some(50));
        let err = wait_for_standstill(&clock, &mut axis, "move", Duration::from_secs(1)).unwrap_err();
        match err {
            AxisError::DeviceFault { axis, reason } => {
                assert_eq!((axis.as_str(), reason.as_str()), ("ramp", "following error"));
            }
            other => panic!("{other}"),
        }
        assert_eq!(axis.reads, 4, "faulted at the read at 60 ms");
    }
}
