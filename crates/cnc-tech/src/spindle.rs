//! A simulated frequency inverter driving the spindle's asynchronous motor (specs/cnc.md,
//! "Spindle inverter interface": start, stop, speed (rpm), reverse rotation, simulation
//! flag; info "ready").
//!
//! It is a [`Task`] like the technology above it: the drilling task writes its Cmd and
//! Para and reads its Info. The motor speed follows the set speed along a linear ramp
//! (`ramp_rpm_per_s`); with the `simulation` flag set the ramp is skipped (the speed is
//! reached at once, as the source's simulated device). `ready` means running at the set
//! speed (within `ready_tolerance_rpm`).

use crate::task::{CmdFlag, Task};

/// Commands of the inverter.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SpindleCmd {
    /// Start the motor at the set speed.
    pub start: CmdFlag,
    /// Stop the motor (ramp down to standstill).
    pub stop: CmdFlag,
}

/// Parameters of the inverter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpindlePara {
    /// Set speed, rpm (positive).
    pub speed_rpm: i32,
    /// Reverse rotation.
    pub reverse: bool,
    /// Simulated device: no ramp.
    pub simulation: bool,
    /// Acceleration and deceleration ramp, rpm per second.
    pub ramp_rpm_per_s: f64,
    /// Highest speed the inverter accepts, rpm.
    pub max_rpm: i32,
    /// `ready` within this many rpm of the set speed.
    pub ready_tolerance_rpm: f64,
}

impl Default for SpindlePara {
    fn default() -> Self {
        Self {
            speed_rpm: 3000,
            reverse: false,
            simulation: false,
            ramp_rpm_per_s: 3000.0,
            max_rpm: 6000,
            ready_tolerance_rpm: 1.0,
        }
    }
}

/// Status of the inverter.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SpindleInfo {
    /// Running at the set speed (the source's `ucCmdToReady`).
    pub ready: bool,
    /// The motor is switched on (it may still be ramping).
    pub running: bool,
    /// Actual speed, rpm; negative in reverse.
    pub actual_rpm: f64,
    /// Speed is zero.
    pub standstill: bool,
    /// The last refused request.
    pub error: Option<SpindleError>,
}

/// A refused inverter request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum SpindleError {
    /// The set speed is not in 1..=max_rpm.
    #[error("spindle speed {requested} rpm out of range 1..={max}")]
    SpeedOutOfRange {
        /// The set speed.
        requested: i32,
        /// The highest speed.
        max: i32,
    },
}

/// What the inverter drives: the motor speed.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SpindleOutputs {
    /// Motor speed, rpm; negative in reverse.
    pub rpm: f64,
}

/// The simulated inverter.
#[derive(Debug, Clone, Default)]
pub struct Spindle {
    cmd: SpindleCmd,
    para: SpindlePara,
    info: SpindleInfo,
    target: f64,
}

impl Spindle {
    /// A stopped inverter with these parameters.
    pub fn new(para: SpindlePara) -> Self {
        Self { para, info: SpindleInfo { standstill: true, ..SpindleInfo::default() }, ..Self::default() }
    }

    fn set_speed(&self) -> f64 {
        let s = f64::from(self.para.speed_rpm);
        if self.para.reverse {
            -s
        } else {
            s
        }
    }
}

impl Task for Spindle {
    type Cmd = SpindleCmd;
    type Para = SpindlePara;
    type Info = SpindleInfo;
    type Inputs = ();
    type Outputs = SpindleOutputs;
    type Error = SpindleError;

    fn cmd_mut(&mut self) -> &mut SpindleCmd {
        &mut self.cmd
    }
    fn para(&self) -> &SpindlePara {
        &self.para
    }
    fn para_mut(&mut self) -> &mut SpindlePara {
        &mut self.para
    }
    fn info(&self) -> &SpindleInfo {
        &self.info
    }

    fn read_inputs(&mut self, _inputs: &(), _dt: f64) {}

    fn detect_error(&mut self) -> Option<SpindleError> {
        let bad = self.para.speed_rpm < 1 || self.para.speed_rpm > self.para.max_rpm;
        if bad && (self.info.running || self.cmd.start.is_requested()) {
            return Some(SpindleError::SpeedOutOfRange {
                requested: self.para.speed_rpm,
                max: self.para.max_rpm,
            });
        }
        None
    }

    fn enter_error(&mut self, error: SpindleError) {
        tracing::warn!(%error, "spindle inverter refuses; stopping");
        self.info.error = Some(error);
        self.info.running = false;
        self.cmd.start.take();
        self.target = 0.0;
    }

    fn step(&mut self, dt: f64) -> Result<(), SpindleError> {
        if self.cmd.stop.take() {
            self.info.running = false;
            self.cmd.start.take();
        }
        if self.cmd.start.take() {
            self.info.running = true;
            self.info.error = None;
        }
        self.target = if self.info.running { self.set_speed() } else { 0.0 };
        let actual = self.info.actual_rpm;
        self.info.actual_rpm = if self.para.simulation {
            self.target
        } else {
            let max_step = self.para.ramp_rpm_per_s.max(0.0) * dt;
            actual + (self.target - actual).clamp(-max_step, max_step)
        };
        Ok(())
    }

    fn write_outputs(&mut self) -> SpindleOutputs {
        let actual = self.info.actual_rpm;
        self.info.standstill = actual == 0.0;
        self.info.ready = self.info.running
            && self.target != 0.0
            && (actual - self.target).abs() <= self.para.ready_tolerance_rpm;
        SpindleOutputs { rpm: actual }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    fn run(s: &mut Spindle, seconds: f64, dt: f64) {
        let n = (seconds / dt).round() as usize;
        for _ in 0..n {
            s.cycle(&(), dt);
        }
    }

    #[test]
    fn ramps_up_ready_at_speed_and_down() {
        // ramp 3000 rpm/s: 3600 rpm needs 1.2 s.
        let mut s = Spindle::new(SpindlePara::default());
        s.para_mut().speed_rpm = 3600;
        s.cmd_mut().start.request();
        run(&mut s, 0.6, 0.01);
        assert!((s.info().actual_rpm - 1800.0).abs() < 1e-6);
        assert!(s.info().running && !s.info().ready);
        run(&mut s, 0.6, 0.01);
        assert!((s.info().actual_rpm - 3600.0).abs() < 1e-6);
        assert!(s.info().ready);
        // New set speed: ramp down to 1800, not ready meanwhile.
        s.para_mut().speed_rpm = 1800;
        run(&mut s, 0.3, 0.01);
        assert!(!s.info().ready);
        run(&mut s, 0.3, 0.01);
        assert!(s.info().ready);
        assert!((s.info().actual_rpm - 1800.0).abs() < 1e-6);
        s.cmd_mut().stop.request();
        run(&mut s, 0.59, 0.01);
        assert!(!s.info().ready && !s.info().standstill);
        run(&mut s, 0.02, 0.01);
        assert!(s.info().standstill);
        assert_eq!(s.info().actual_rpm, 0.0);
    }

    #[test]
    fn reverse_and_simulation() {
        let mut s = Spindle::new(SpindlePara {
            simulation: true,
            reverse: true,
            speed_rpm: 1000,
            ..SpindlePara::default()
        });
        s.cmd_mut().start.request();
        let out = s.cycle(&(), 0.001);
        assert_eq!(out.rpm, -1000.0);
        assert!(s.info().ready);
    }

    #[test]
    fn speed_out_of_range_refused() {
        let mut s = Spindle::new(SpindlePara { speed_rpm: 9000, ..SpindlePara::default() });
        s.cmd_mut().start.request();
        run(&mut s, 0.1, 0.01);
        assert_eq!(s.info().error, Some(SpindleError::SpeedOutOfRange { requested: 9000, max: 6000 }));
        assert!(!s.info().running);
        assert_eq!(s.info().actual_rpm, 0.0);
    }
}
