//! [`DrillingCell`]: the drilling task, the spindle inverter and the simulated machine
//! wired together behind the PLC interface (M-functions, external parameters), so a
//! program executor — or the [`Step`] runner here — can drive the whole technology.
//!
//! Each [`DrillingCell::cycle`] runs, in order: the drilling task (reading the machine
//! feedback, the spindle's Info, the M bits and EXW60/EXF61/EXF62), the spindle task
//! (whose Cmd/Para the drilling task writes, as a higher task does), the machine (virtual
//! X/Y from the caller, coupling, Z, spindle speed), then clears the bits of the
//! acknowledged and aborted M-functions.
//!
//! The handshake with an executor: at a synchronous M-function the executor calls
//! [`DrillingCell::on_m_function`] (which answers [`MDisposition::Wait`]), keeps calling
//! [`DrillingCell::cycle`] with its (unchanged) X/Y, and resumes the program when the M
//! shows up in [`CellCycle::acknowledged`] (its bit is then clear). An M in
//! [`CellCycle::aborted`] means the technology was stopped after an error.

use crate::drilling::{
    DrillingInputs, DrillingOutputs, DrillingPara, DrillingTask, ErrorRecord, Job, State, M_ACTIVATE_CUTTING,
    M_DRILL,
};
use crate::machine::{approach, Hole, Machine, MachineCommand, MachineConfig, MachineFeedback};
use crate::plc_interface::{
    ExtParamError, ExtType, ExtValue, ExternalParameters, MFunctionError, MFunctions, MKind,
};
use crate::spindle::{Spindle, SpindlePara};
use crate::task::Task;

/// What the executor does after setting an M-function.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MDisposition {
    /// Synchronous: pause the program until the M is acknowledged.
    Wait,
    /// Asynchronous: go on.
    Continue,
}

/// One step of a program, as an interpreter would hand it over (for tests and demos).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Step {
    /// `M<n>`.
    M(u16),
    /// `EX<ty><index>=<value>`.
    Ext(ExtType, usize, f64),
    /// `G00 X Y`: straight move at the run's rapid feed.
    Rapid {
        /// X, mm (program coordinates).
        x: f64,
        /// Y, mm.
        y: f64,
    },
    /// `G01 X Y F`: straight move at `feed` mm/min.
    MoveXY {
        /// X, mm (program coordinates).
        x: f64,
        /// Y, mm.
        y: f64,
        /// Feed, mm/min.
        feed: f64,
    },
    /// Wait, s.
    Dwell(f64),
}

/// How [`DrillingCell::run_program`] runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunConfig {
    /// Cycle time, s.
    pub dt: f64,
    /// Feed of [`Step::Rapid`], mm/min.
    pub rapid_feed: f64,
    /// Longest wait for one synchronous M, s.
    pub m_timeout: f64,
}

impl Default for RunConfig {
    fn default() -> Self {
        Self { dt: 0.001, rapid_feed: 10_000.0, m_timeout: 300.0 }
    }
}

/// A change of the technology's state, as seen in its Info.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StateChange {
    /// Cell time, s.
    pub time: f64,
    /// The new state.
    pub state: State,
    /// The job at that time.
    pub job: Option<Job>,
}

/// The result of one cell cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct CellCycle {
    /// M-functions finished this cycle (their bits are cleared: resume the program).
    pub acknowledged: Vec<u16>,
    /// M-functions aborted this cycle by `stop_technology` (bits cleared).
    pub aborted: Vec<u16>,
    /// The technology's outputs.
    pub outputs: DrillingOutputs,
    /// The machine after the cycle.
    pub feedback: MachineFeedback,
    /// The failure, while the technology is in its error state.
    pub error: Option<ErrorRecord>,
}

/// A refused request or a failed program run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CellError {
    /// The M-function array refused (out of range, or still set).
    #[error(transparent)]
    MFunction(#[from] MFunctionError),
    /// No task here handles this M-function.
    #[error("M{0} is not handled by the drilling cell (M60..M64)")]
    NotHandled(u16),
    /// An external parameter was refused.
    #[error(transparent)]
    External(#[from] ExtParamError),
    /// The technology failed during a program step.
    #[error("step {step}: {}", record.error)]
    Technology {
        /// Index of the step.
        step: usize,
        /// The saved context.
        record: ErrorRecord,
    },
    /// A step did not finish in time.
    #[error("step {step}: not finished after {after_s} s")]
    Timeout {
        /// Index of the step.
        step: usize,
        /// Time waited, s.
        after_s: f64,
    },
    /// The M-function was aborted (stop technology).
    #[error("step {step}: M{m} aborted")]
    Aborted {
        /// Index of the step.
        step: usize,
        /// The M-function.
        m: u16,
    },
}

/// What a program run did.
#[derive(Debug, Clone, PartialEq)]
pub struct RunReport {
    /// Simulated time of the run, s.
    pub elapsed: f64,
    /// Cycles run.
    pub cycles: u64,
    /// Holes drilled during the run.
    pub holes: Vec<Hole>,
    /// State changes during the run.
    pub states: Vec<StateChange>,
    /// For each synchronous M: (number, cycles the program was paused).
    pub waits: Vec<(u16, u64)>,
}

/// The drilling task, the spindle and the simulated machine behind the PLC interface.
#[derive(Debug, Clone)]
pub struct DrillingCell {
    mfunctions: MFunctions,
    ext: ExternalParameters,
    drilling: DrillingTask,
    spindle: Spindle,
    machine: Machine,
    program_xy: [f64; 2],
    time: f64,
    cycles: u64,
    trace: Vec<StateChange>,
}

impl DrillingCell {
    /// A cell at rest. M60..M64 are declared synchronous; EXW60, EXF61 and EXF62 start
    /// with the Para's spindle rpm, drilling speed and depth (the PLC's defaults until
    /// the program writes them; an rpm beyond int16 is stored as 0).
    pub fn new(para: DrillingPara, spindle: SpindlePara, machine: MachineConfig) -> Self {
        let mut mfunctions = MFunctions::new();
        for n in M_DRILL..=M_ACTIVATE_CUTTING {
            // In range by construction; an error cannot happen.
            let _ = mfunctions.set_kind(n, MKind::Synchronous);
        }
        let mut ext = ExternalParameters::new();
        let _ = ext.set_w(60, i16::try_from(para.spindle_rpm).unwrap_or(0));
        let _ = ext.set_f(61, para.drilling_speed as f32);
        let _ = ext.set_f(62, para.drilling_depth as f32);
        let machine = Machine::new(machine);
        Self {
            mfunctions,
            ext,
            drilling: DrillingTask::new(para),
            spindle: Spindle::new(spindle),
            program_xy: [0.0, 0.0],
            time: 0.0,
            cycles: 0,
            trace: vec![StateChange { time: 0.0, state: State::Idle, job: None }],
            machine,
        }
    }

    /// Program side: `M<n>`. Refuses an M the cell does not handle and an M whose bit is
    /// still set.
    pub fn on_m_function(&mut self, n: u16) -> Result<MDisposition, CellError> {
        if !(M_DRILL..=M_ACTIVATE_CUTTING).contains(&n) {
            return Err(CellError::NotHandled(n));
        }
        Ok(match self.mfunctions.set(n)? {
            MKind::Synchronous => MDisposition::Wait,
            MKind::Asynchronous => MDisposition::Continue,
        })
    }

    /// Program side: `EX<ty><index>=<value>`.
    pub fn set_external(&mut self, ty: ExtType, index: usize, value: f64) -> Result<ExtValue, CellError> {
        Ok(self.ext.set(ty, index, value)?)
    }

    /// One cycle of `dt` seconds with the virtual X/Y (program coordinates) at
    /// `program_xy`.
    pub fn cycle(&mut self, dt: f64, program_xy: [f64; 2]) -> CellCycle {
        let dt = crate::task::sanitize_dt(dt);
        self.time += dt;
        self.cycles += 1;
        self.program_xy = program_xy;
        let fb = self.machine.feedback();
        let inputs = DrillingInputs::gather(&fb, self.spindle.info(), &self.mfunctions, &self.ext);
        let out = self.drilling.cycle(&inputs, dt);

        // The drilling task is the spindle's higher task: it writes its Cmd and Para.
        let sp = self.spindle.para_mut();
        sp.speed_rpm = out.spindle_rpm;
        sp.reverse = out.spindle_reverse;
        if out.spindle_stop {
            self.spindle.cmd_mut().stop.request();
        }
        if out.spindle_start {
            self.spindle.cmd_mut().start.request();
        }
        let spindle_out = self.spindle.cycle(&(), dt);

        let feedback = self.machine.step(
            dt,
            &MachineCommand {
                virtual_xy: program_xy,
                coupling: out.coupling,
                z: out.z,
                spindle_rpm: spindle_out.rpm,
                clamp: out.clamp,
            },
        );

        let acknowledged: Vec<u16> = out.acknowledge.iter().collect();
        let aborted: Vec<u16> = out.abort.iter().collect();
        for &m in acknowledged.iter().chain(aborted.iter()) {
            let _ = self.mfunctions.clear(m);
        }

        let info = self.drilling.info();
        if !self.trace.last().is_some_and(|c| c.state == info.state && c.job == info.job) {
            self.trace.push(StateChange { time: self.time, state: info.state, job: info.job });
        }
        CellCycle {
            acknowledged,
            aborted,
            outputs: out,
            feedback,
            error: (info.state == State::Error).then_some(info.last_error).flatten(),
        }
    }

    /// Runs program steps to the end, cycle by cycle, with the synchronous-M handshake.
    pub fn run_program(&mut self, steps: &[Step], cfg: &RunConfig) -> Result<RunReport, CellError> {
        let (t0, c0) = (self.time, self.cycles);
        let (holes0, trace0) = (self.machine.holes().len(), self.trace.len());
        let mut waits = Vec::new();
        let dt = cfg.dt;
        for (i, step) in steps.iter().enumerate() {
            match *step {
                Step::M(n) => {
                    if self.on_m_function(n)? == MDisposition::Wait {
                        waits.push((n, self.wait_for(i, n, cfg)?));
                    }
                }
                Step::Ext(ty, index, value) => {
                    self.set_external(ty, index, value)?;
                }
                Step::Rapid { x, y } => self.move_to(i, [x, y], cfg.rapid_feed, dt)?,
                Step::MoveXY { x, y, feed } => self.move_to(i, [x, y], feed, dt)?,
                Step::Dwell(s) => {
                    let until = self.time + s;
                    while self.time < until && dt > 0.0 {
                        self.cycle(dt, self.program_xy);
                    }
                }
            }
        }
        Ok(RunReport {
            elapsed: self.time - t0,
            cycles: self.cycles - c0,
            holes: self.machine.holes().get(holes0..).unwrap_or_default().to_vec(),
            states: self.trace.get(trace0..).unwrap_or_default().to_vec(),
            waits,
        })
    }

    fn wait_for(&mut self, step: usize, n: u16, cfg: &RunConfig) -> Result<u64, CellError> {
        let start = self.time;
        let mut cycles = 0u64;
        loop {
            let c = self.cycle(cfg.dt, self.program_xy);
            cycles += 1;
            if c.acknowledged.contains(&n) {
                return Ok(cycles);
            }
            if c.aborted.contains(&n) {
                return Err(CellError::Aborted { step, m: n });
            }
            if let Some(record) = c.error {
                return Err(CellError::Technology { step, record });
            }
            let after_s = self.time - start;
            if after_s > cfg.m_timeout || cfg.dt <= 0.0 {
                return Err(CellError::Timeout { step, after_s });
            }
        }
    }

    fn move_to(&mut self, step: usize, target: [f64; 2], feed: f64, dt: f64) -> Result<(), CellError> {
        let start = self.time;
        let [tx, ty] = target;
        let [px, py] = self.program_xy;
        let limit = (tx - px).hypot(ty - py) / feed.max(1e-9) * 60.0 * 1.5 + 1.0;
        while self.program_xy != target {
            let xy = approach(self.program_xy, target, feed.max(0.0) / 60.0 * dt);
            let c = self.cycle(dt, xy);
            if let Some(record) = c.error {
                return Err(CellError::Technology { step, record });
            }
            let after_s = self.time - start;
            if after_s > limit || dt <= 0.0 {
                return Err(CellError::Timeout { step, after_s });
            }
        }
        Ok(())
    }

    /// The drilling task (its Info, Para, state).
    pub fn drilling(&self) -> &DrillingTask {
        &self.drilling
    }
    /// The drilling task, to set Cmd and Para (as an HMI or higher task).
    pub fn drilling_mut(&mut self) -> &mut DrillingTask {
        &mut self.drilling
    }
    /// The spindle inverter.
    pub fn spindle(&self) -> &Spindle {
        &self.spindle
    }
    /// The simulated machine (holes, events, feedback).
    pub fn machine(&self) -> &Machine {
        &self.machine
    }
    /// The simulated machine, e.g. to change the material.
    pub fn machine_mut(&mut self) -> &mut Machine {
        &mut self.machine
    }
    /// The M-function array.
    pub fn mfunctions(&self) -> &MFunctions {
        &self.mfunctions
    }
    /// The external parameters.
    pub fn external(&self) -> &ExternalParameters {
        &self.ext
    }
    /// Every state change of the technology since the cell was made.
    pub fn state_trace(&self) -> &[StateChange] {
        &self.trace
    }
    /// Cell time, s.
    pub fn time(&self) -> f64 {
        self.time
    }
    /// The virtual X/Y of the last cycle (program coordinates).
    pub fn program_xy(&self) -> [f64; 2] {
        self.program_xy
    }
}
