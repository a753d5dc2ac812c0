//! # motus-cnc-tech — technology tasks of the CNC drilling add-on
//!
//! A pure, deterministic library (no clocks, threads or IO: time comes in as `dt` per
//! cycle) implementing `specs/cnc.md`, sections "M-functions", "External parameters",
//! "Drilling technology" and "Task structure":
//!
//! * [`plc_interface`]: the data exchange between the CNC program and the PLC — the
//!   1024-bit [`MFunctions`] array (synchronous / asynchronous) and the four
//!   [`ExternalParameters`] arrays (`EXB`, `EXW`, `EXL`, `EXF`).
//! * [`task`]: the source's task pattern — Cmd / Para / Info and the four steps of one
//!   cycle (read inputs, handle errors, state machine, write outputs) — as the [`Task`]
//!   trait with small helpers ([`CmdFlag`], [`StateTimer`]).
//! * [`spindle`]: a simulated frequency inverter for the spindle's asynchronous motor.
//! * [`machine`]: a simulated machine (gantry X/Y with the virtual-axis coupling, the
//!   drilling unit's Z, the pressure plate and its reference switch, the material
//!   surface) that records every hole it drills.
//! * [`setpoint`]: the set-points the technology sends to the axes (Z move, X/Y coupling).
//! * [`drilling`]: the drilling technology task (M60..M64, EXW60/EXF61/EXF62, working-height
//!   search with the pressure plate).
//! * [`cell`]: [`DrillingCell`], a façade that wires the task, the spindle and the
//!   machine together, takes M-functions and external parameters from a program executor
//!   (`on_m_function`, `set_external`, `cycle`), and can run a list of program [`Step`]s
//!   on its own for tests.
//!
//! Units: mm, mm/min, rpm, seconds.

#![forbid(unsafe_code)]

pub mod cell;
pub mod drilling;
pub mod machine;
pub mod plc_interface;
pub mod setpoint;
pub mod spindle;
pub mod task;

pub use cell::{CellCycle, CellError, DrillingCell, MDisposition, RunConfig, RunReport, StateChange, Step};
pub use drilling::{
    DrillingCmd, DrillingError, DrillingInfo, DrillingInputs, DrillingOutputs, DrillingPara, DrillingTask,
    ErrorRecord, HoleSettings, Job, MSet, Mode, State, Technology,
};
pub use machine::{Hole, Machine, MachineCommand, MachineConfig, MachineEvent, MachineFeedback, Surface};
pub use plc_interface::{
    ExtParamError, ExtParamRef, ExtType, ExtValue, ExternalParameters, MFunctionError, MFunctions, MKind,
};
pub use setpoint::{Coupling, ZCommand};
pub use spindle::{Spindle, SpindleCmd, SpindleError, SpindleInfo, SpindleOutputs, SpindlePara};
pub use task::{CmdFlag, StateTimer, Task};
