//! [`ProgramRun`]: one CNC system stepped cycle by cycle.
//!
//! Each [`ProgramRun::step`]: the interpreter decodes ahead into the block buffer (up to
//! [`ProgramRun::DECODE_PER_STEP`] items per cycle, until the buffer is full or a decoder
//! synchronisation point blocks it), the executor produces the cycle's set-point, the
//! executor's events go to the technology (M-functions, external parameters), and the
//! technology's acknowledgements release a path waiting at a synchronous M-function.
//! A technology error stops the path (decelerating within the limits) and ends the run
//! with the error: on doubt about motion, stop.

use motus_cnc_planner::{AxisLimits, Config, Event, ExecState, Executor, PathItem, Setpoint};
use motus_gcode::{GcodeError, Interpreter, InterpreterConfig};
use serde::Serialize;
use thiserror::Error;

use crate::adapter;
use crate::technology::{Technology, TechnologyError};
use crate::AXES;

/// Limits of X, Y, Z and the planner tolerances.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits3 {
    /// Velocity (mm/s) and acceleration (mm/s²) of X, Y, Z.
    pub axes: [AxisLimits; AXES],
    /// Corner blending tolerance (mm).
    pub path_tolerance: f64,
    /// Arc chord tolerance (mm).
    pub chord_tolerance: f64,
}

impl Default for Limits3 {
    /// A gantry cutting machine: X, Y 200 mm/s, 2000 mm/s²; Z 50 mm/s, 500 mm/s².
    fn default() -> Self {
        let xy = AxisLimits { velocity: 200.0, acceleration: 2000.0 };
        Self {
            axes: [xy, xy, AxisLimits { velocity: 50.0, acceleration: 500.0 }],
            path_tolerance: 0.05,
            chord_tolerance: 0.01,
        }
    }
}

/// Why a run failed.
#[derive(Debug, Error)]
pub enum RunError {
    /// The program is invalid (line and column inside).
    #[error("{0}")]
    Program(#[from] GcodeError),
    /// The planner refused an item or the configuration.
    #[error("line {line}: {message}")]
    Planner {
        /// Program line.
        line: u32,
        /// What.
        message: String,
    },
    /// The technology failed (the path was stopped).
    #[error("line {line}: {source}")]
    Technology {
        /// Program line.
        line: u32,
        /// What.
        source: TechnologyError,
    },
    /// The run did not end in the allowed time.
    #[error("program not finished after {0} s")]
    Timeout(f64),
}

/// State of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RunStatus {
    /// Moving or dwelling.
    Running,
    /// At a synchronous M-function, waiting for the technology.
    WaitingTechnology,
    /// Feed hold (at rest or decelerating).
    Held,
    /// Single-block stop.
    BlockStop,
    /// Stopped by the operator or an error.
    Stopped,
    /// Program finished.
    Done,
}

/// Figures of a run, measured on the executed set-points.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct RunReport {
    /// Program time (s).
    pub duration: f64,
    /// Items pushed into the block buffer.
    pub items: u64,
    /// Planned pieces (lines after arc splitting, blends).
    pub segments: u64,
    /// Peak |velocity| per axis (mm/s), from the set-points.
    pub peak_velocity: [f64; AXES],
    /// Peak |acceleration| per axis (mm/s²), from successive set-point velocities.
    pub peak_acceleration: [f64; AXES],
    /// Current program line.
    pub line: u32,
    /// Lines in the program.
    pub lines: u32,
    /// M-functions executed.
    pub m_functions: u64,
}

impl RunReport {
    /// Progress 0..=1 by program line.
    pub fn progress(&self) -> f64 {
        if self.lines == 0 {
            1.0
        } else {
            f64::from(self.line.min(self.lines)) / f64::from(self.lines)
        }
    }
}

/// One program on one CNC system (see the module documentation).
pub struct ProgramRun<'a> {
    interp: Interpreter<'a>,
    adapter: adapter::Adapter,
    exec: Executor<AXES>,
    pending: Option<(u32, PathItem<AXES>)>,
    decoded_all: bool,
    report: RunReport,
    last_velocity: Option<[f64; AXES]>,
    waiting: Option<u16>,
    failed: bool,
    stopped: bool,
}

impl<'a> ProgramRun<'a> {
    /// Items decoded per cycle at most (bounds the decoder's share of a cycle).
    pub const DECODE_PER_STEP: usize = 256;

    /// Prepares `src`, starting at `start` (machine mm).
    pub fn new(
        src: &'a str,
        config: InterpreterConfig,
        limits: Limits3,
        start: [f64; AXES],
    ) -> Result<Self, RunError> {
        let mut cfg = Config::new(limits.axes);
        cfg.path_tolerance = limits.path_tolerance;
        cfg.chord_tolerance = limits.chord_tolerance;
        cfg.buffer_capacity = 20_000;
        let exec =
            Executor::new(cfg, start).map_err(|e| RunError::Planner { line: 0, message: e.to_string() })?;
        Ok(Self {
            interp: Interpreter::with_config(src, config),
            adapter: adapter::Adapter::default(),
            exec,
            pending: None,
            decoded_all: false,
            report: RunReport {
                lines: u32::try_from(src.lines().count()).unwrap_or(u32::MAX),
                ..Default::default()
            },
            last_velocity: None,
            waiting: None,
            failed: false,
            stopped: false,
        })
    }

    /// The executor (state, coupling, planner).
    pub fn executor(&self) -> &Executor<AXES> {
        &self.exec
    }

    /// Figures so far.
    pub fn report(&self) -> &RunReport {
        &self.report
    }

    /// Feed hold.
    pub fn feed_hold(&mut self) {
        self.exec.feed_hold();
    }

    /// Resume after a feed hold or a single-block stop.
    pub fn resume(&mut self) -> Result<(), RunError> {
        self.exec
            .cycle_start()
            .map_err(|e| RunError::Planner { line: self.report.line, message: e.to_string() })
    }

    /// Stop: decelerate within the limits, then flush the program.
    pub fn stop(&mut self) {
        self.stopped = true;
        self.exec.stop();
        self.decoded_all = true;
        self.pending = None;
    }

    /// Feed override in percent (0..=200).
    pub fn set_override(&mut self, percent: f64) -> Result<(), RunError> {
        self.exec
            .set_override(percent / 100.0)
            .map_err(|e| RunError::Planner { line: self.report.line, message: e.to_string() })
    }

    /// Single-block mode.
    pub fn set_single_block(&mut self, on: bool) {
        self.exec.set_single_block(on);
    }

    fn decode(&mut self) -> Result<(), RunError> {
        let mut n = 0;
        while n < Self::DECODE_PER_STEP && !self.decoded_all && !self.exec.decoder_blocked() {
            let next = match self.pending.take() {
                Some(p) => Some(p),
                None => match self.interp.next() {
                    None => {
                        self.decoded_all = true;
                        self.exec.finish();
                        None
                    }
                    Some(Err(e)) => return Err(e.into()),
                    Some(Ok(call)) => self.adapter.item(&call).map(|i| (call.line, i)),
                },
            };
            let Some((line, item)) = next else { continue };
            match self.exec.push(line, item) {
                Ok(()) => {
                    self.report.items += 1;
                    n += 1;
                }
                Err(motus_cnc_planner::PushError::Full { .. })
                | Err(motus_cnc_planner::PushError::AwaitingDecoderSync { .. }) => {
                    self.pending = Some((line, item));
                    break;
                }
                Err(e) => return Err(RunError::Planner { line, message: e.to_string() }),
            }
        }
        Ok(())
    }

    /// One cycle of `dt` seconds: returns the set-point and the run status.
    pub fn step(
        &mut self,
        dt: f64,
        tech: &mut dyn Technology,
    ) -> Result<(Setpoint<AXES>, RunStatus), RunError> {
        if let Err(e) = self.decode() {
            // An invalid line ahead: stop the path before it, within the limits.
            self.exec.stop();
            self.failed = true;
            return Err(e);
        }
        let sp = self.exec.tick(dt);
        self.measure(&sp, dt);
        while let Some(ev) = self.exec.poll_event() {
            let r = match ev {
                Event::MFunction { number, sync, line } => {
                    self.report.m_functions += 1;
                    match tech.m_function(number, sync) {
                        Ok(true) => {
                            self.waiting = Some(number);
                            Ok(())
                        }
                        Ok(false) => {
                            if sync {
                                self.exec.acknowledge(number);
                            }
                            Ok(())
                        }
                        Err(e) => Err((line, e)),
                    }
                }
                Event::ExternalParameter { array, index, value, line } => {
                    tech.external(array, index, value).map_err(|e| (line, e))
                }
                _ => Ok(()),
            };
            if let Err((line, source)) = r {
                self.exec.stop();
                self.failed = true;
                return Err(RunError::Technology { line, source });
            }
        }
        let [x, y, _] = sp.path_positions;
        match tech.cycle(dt, [x, y]) {
            Ok(acks) => {
                for m in acks {
                    self.exec.acknowledge(m);
                    if self.waiting == Some(m) {
                        self.waiting = None;
                    }
                }
            }
            Err(source) => {
                self.exec.stop();
                self.failed = true;
                return Err(RunError::Technology { line: sp.line, source });
            }
        }
        self.report.segments = self.exec.planner().segments();
        let status = match sp.state {
            ExecState::WaitingAck(_) => RunStatus::WaitingTechnology,
            ExecState::Holding | ExecState::Held => RunStatus::Held,
            ExecState::BlockStop => RunStatus::BlockStop,
            ExecState::Stopping => RunStatus::Stopped,
            ExecState::Idle if self.failed || self.stopped => RunStatus::Stopped,
            ExecState::Idle
                if self.decoded_all && self.pending.is_none() && !self.exec.planner().has_pending() =>
            {
                RunStatus::Done
            }
            _ => RunStatus::Running,
        };
        Ok((sp, status))
    }

    fn measure(&mut self, sp: &Setpoint<AXES>, dt: f64) {
        self.report.duration = sp.time;
        self.report.line = self.report.line.max(sp.line);
        for (peak, v) in self.report.peak_velocity.iter_mut().zip(sp.velocities) {
            *peak = peak.max(v.abs());
        }
        if let Some(prev) = self.last_velocity {
            if dt > 0.0 {
                for ((peak, v), p) in self.report.peak_acceleration.iter_mut().zip(sp.velocities).zip(prev) {
                    *peak = peak.max((v - p).abs() / dt);
                }
            }
        }
        self.last_velocity = Some(sp.velocities);
    }

    /// Steps until the program is done (or `max_time` of program time), calling `on_step`
    /// after every cycle.
    pub fn run_to_end(
        &mut self,
        dt: f64,
        tech: &mut dyn Technology,
        max_time: f64,
        mut on_step: impl FnMut(&Setpoint<AXES>, RunStatus, &RunReport),
    ) -> Result<RunReport, RunError> {
        loop {
            let (sp, status) = self.step(dt, tech)?;
            on_step(&sp, status, &self.report);
            if status == RunStatus::Done {
                return Ok(self.report.clone());
            }
            if sp.time > max_time {
                self.exec.stop();
                return Err(RunError::Timeout(max_time));
            }
        }
    }
}
