//! # motus-kv01-sim — a simulated KV-01 six-joint arm
//!
//! A faithful model of the KV-01 arm (`specs/kv01.md`, `specs/faulhaber.md`): six
//! communication modules (0xE1..=0xE6) on one RS-485 line, each with a Faulhaber controller
//! behind it and a joint with its gear, brake, resolver and (joints 1, 2, 3, 5) limit
//! switches; the gripper module also drives the jaws. Modelled: the D0 pass-through and
//! the controller's ASCII subset (EN/DI, V, LA/LR/M, HO, ENPROG/DIPROG, ANSW, queries,
//! error strings), "TIMEOUT" for a silent or slow controller, D1 brake / restricted mode /
//! current limitation, D2 fast messages, D3 resolver readings with the spec's offsets, D4
//! voltages, D5 gripper, the limit-switch stop (LSSTOP, LIMVAL) and the 700 ms safety
//! time-out ("TO", latched until [`Arm::power_cycle`]).
//!
//! Time is injected: an [`Arm`] (or one [`Module`]) advances in fixed steps to the `now` it
//! is given, deterministically (seeded noise), so tests step it on a virtual clock. A
//! [`SimLine`] serves the arm on any [`motus_serial::Link`] (a pty for tests), with
//! optional baud-rate pacing and fault injection, or in-process on a virtual clock
//! ([`SimLine::sim_link`]: a driver and the arm in one test on virtual time).
//!
//! ```
//! use motus_kv01_protocol::{Address, Answer, Command, ReplyBody, Request};
//! use motus_kv01_sim::{Arm, ArmConfig};
//! use std::time::Duration;
//!
//! let mut arm = Arm::new(&ArmConfig::default()).unwrap();
//! let en = Request::new(Address::joint(2).unwrap(), Command::Faulhaber { text: "EN".into() });
//! let reply = arm.handle(&en, Duration::from_millis(10)).unwrap();
//! assert_eq!(reply.body, ReplyBody::Faulhaber { answer: Answer::parse("OK") });
//! assert!(arm.state(2).unwrap().drive_enabled);
//! ```

#![forbid(unsafe_code)]

mod arm;
pub mod config;
mod controller;
mod error;
mod gripper;
mod joint;
mod line;
mod module;
pub mod resolver;
mod supply;

pub use arm::Arm;
pub use config::{
    ArmConfig, CmConfig, ControllerConfig, D2Refusal, GripperConfig, JointConfig, Side, SupplyConfig,
};
pub use error::SimError;
pub use gripper::GripperState;
pub use line::{lock, ArmSimLink, LineError, LineOptions, ServedArm, SharedArm, SimLine};
pub use module::{Module, ModuleFaults, ModuleState, TimedReply};
