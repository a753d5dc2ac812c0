//! The task pattern of the source's controller (specs/cnc.md, "Task structure").
//!
//! Every technology or axis task owns one structure with three parts:
//!
//! * **Cmd** — commands, usually booleans. A higher task (or the HMI) may only *set*
//!   them ([`CmdFlag::request`]); the task itself resets them when it takes them
//!   ([`CmdFlag::take`]).
//! * **Para** — parameters, written by higher tasks, read by the task.
//! * **Info** — status; written only by the task, read by everybody else.
//!
//! Tasks form a hierarchy: a higher task writes the Cmd/Para of the lower ones and reads
//! their Info; an HMI holds no logic of the tasks below it.
//!
//! One cycle ([`Task::cycle`]) runs four steps in a fixed order:
//!
//! 1. [`Task::read_inputs`] — read and condition the inputs (sensors, feedback, M bits);
//! 2. [`Task::detect_error`] / [`Task::enter_error`] — handle errors: save the context
//!    (state, time, values) and send the state machine to its error state;
//! 3. [`Task::step`] — the state machine: an idle state waiting for a request, a sequence
//!    of states per job, back to idle (a state may also report an error, handled as in 2);
//! 4. [`Task::write_outputs`] — write the outputs (set-points, commands of lower tasks,
//!    acknowledgements).
//!
//! Time is never read from a clock: each cycle gets its `dt` in seconds.

/// A command bit of a task's Cmd part: set by a higher task, reset by the task itself.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CmdFlag(bool);

impl CmdFlag {
    /// Higher task / HMI: request the command (sets the bit to 1).
    pub fn request(&mut self) {
        self.0 = true;
    }

    /// Whether the command is requested and not yet taken.
    pub fn is_requested(&self) -> bool {
        self.0
    }

    /// The owning task: takes the request, resetting the bit. Only the task that owns the
    /// Cmd structure calls this.
    pub fn take(&mut self) -> bool {
        std::mem::take(&mut self.0)
    }
}

/// Time spent in the current state of a state machine (for time-outs).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StateTimer {
    elapsed: f64,
}

impl StateTimer {
    /// Starts again from zero (on a state change).
    pub fn restart(&mut self) {
        self.elapsed = 0.0;
    }

    /// Adds one cycle's time.
    pub fn advance(&mut self, dt: f64) {
        self.elapsed += dt;
    }

    /// Seconds since the last restart.
    pub fn elapsed(&self) -> f64 {
        self.elapsed
    }
}

/// A cycle time made safe: negative, NaN or infinite `dt` counts as 0.
pub fn sanitize_dt(dt: f64) -> f64 {
    if dt.is_finite() && dt > 0.0 {
        dt
    } else {
        0.0
    }
}

/// A cyclic task with Cmd / Para / Info and the four steps of one cycle.
pub trait Task {
    /// Commands (set by higher tasks, reset by this task).
    type Cmd;
    /// Parameters (written by higher tasks).
    type Para;
    /// Status (written only by this task).
    type Info;
    /// What the task reads each cycle (sensors, feedback, M bits...).
    type Inputs;
    /// What the task writes each cycle (set-points, lower tasks' commands...).
    type Outputs;
    /// What can go wrong in a job.
    type Error;

    /// The Cmd part, for a higher task to set commands.
    fn cmd_mut(&mut self) -> &mut Self::Cmd;
    /// The Para part.
    fn para(&self) -> &Self::Para;
    /// The Para part, for a higher task to write parameters.
    fn para_mut(&mut self) -> &mut Self::Para;
    /// The Info part (read-only for everybody but the task).
    fn info(&self) -> &Self::Info;

    /// Step 1: read and condition the inputs; `dt` is the cycle time in seconds.
    fn read_inputs(&mut self, inputs: &Self::Inputs, dt: f64);
    /// Step 2a: look for errors in the inputs and the current state (time-outs, limits).
    fn detect_error(&mut self) -> Option<Self::Error>;
    /// Step 2b: save the context and send the state machine to its error state.
    fn enter_error(&mut self, error: Self::Error);
    /// Step 3: one step of the state machine.
    fn step(&mut self, dt: f64) -> Result<(), Self::Error>;
    /// Step 4: the outputs of this cycle.
    fn write_outputs(&mut self) -> Self::Outputs;

    /// One cycle: the four steps in order. `dt` that is negative or not finite counts as 0.
    fn cycle(&mut self, inputs: &Self::Inputs, dt: f64) -> Self::Outputs {
        let dt = sanitize_dt(dt);
        self.read_inputs(inputs, dt);
        if let Some(error) = self.detect_error() {
            self.enter_error(error);
        }
        if let Err(error) = self.step(dt) {
            self.enter_error(error);
        }
        self.write_outputs()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    /// A toy task: counts requests, errors when the input exceeds a limit.
    #[derive(Default)]
    struct Counter {
        cmd: CmdFlag,
        limit: u32,
        count: u32,
        input: u32,
        errors: Vec<String>,
        order: Vec<&'static str>,
    }

    impl Task for Counter {
        type Cmd = CmdFlag;
        type Para = u32;
        type Info = u32;
        type Inputs = u32;
        type Outputs = u32;
        type Error = String;
        fn cmd_mut(&mut self) -> &mut CmdFlag {
            &mut self.cmd
        }
        fn para(&self) -> &u32 {
            &self.limit
        }
        fn para_mut(&mut self) -> &mut u32 {
            &mut self.limit
        }
        fn info(&self) -> &u32 {
            &self.count
        }
        fn read_inputs(&mut self, inputs: &u32, _dt: f64) {
            self.order.push("read");
            self.input = *inputs;
        }
        fn detect_error(&mut self) -> Option<String> {
            self.order.push("detect");
            (self.input > self.limit).then(|| format!("input {} > {}", self.input, self.limit))
        }
        fn enter_error(&mut self, error: String) {
            self.order.push("error");
            self.errors.push(error);
        }
        fn step(&mut self, _dt: f64) -> Result<(), String> {
            self.order.push("step");
            if self.cmd.take() {
                self.count += 1;
            }
            Ok(())
        }
        fn write_outputs(&mut self) -> u32 {
            self.order.push("write");
            self.count
        }
    }

    #[test]
    fn four_steps_in_order_and_cmd_reset_by_task() {
        let mut t = Counter { limit: 10, ..Counter::default() };
        t.cmd_mut().request();
        assert!(t.cmd.is_requested());
        assert_eq!(t.cycle(&1, 0.01), 1);
        assert!(!t.cmd.is_requested(), "the task resets its command");
        assert_eq!(t.order, vec!["read", "detect", "step", "write"]);
        t.order.clear();
        assert_eq!(t.cycle(&11, 0.01), 1);
        assert_eq!(t.order, vec!["read", "detect", "error", "step", "write"]);
        assert_eq!(t.errors, vec!["input 11 > 10".to_string()]);
        assert_eq!(*t.info(), 1);
        *t.para_mut() = 20;
        assert_eq!(*t.para(), 20);
    }

    #[test]
    fn timer_and_dt() {
        let mut s = StateTimer::default();
        s.advance(0.5);
        s.advance(0.25);
        assert_eq!(s.elapsed(), 0.75);
        s.restart();
        assert_eq!(s.elapsed(), 0.0);
        assert_eq!(sanitize_dt(-1.0), 0.0);
        assert_eq!(sanitize_dt(f64::NAN), 0.0);
        assert_eq!(sanitize_dt(0.002), 0.002);
    }
}
