//! # motus-nfv2-sim — a simulated 1209A axis controller speaking NFv2
//!
//! A faithful model of the 1209A (specs/nfv2.md: seed 002 and the reference firmware):
//! the NFv2 communication buffer (set-points, queries, one answer frame per request), the
//! operating modes (ERROR, MANUAL from AI0, PWM, CURRENT, SPEED, POSITION, POS_INCREMENT,
//! HOMING), a 20 kHz current loop and 1 kHz speed and position regulators whose PID gains
//! the host sets, a brushed DC motor with its load (L/R, back-EMF, torque constant,
//! inertia, friction) and encoder, position / speed / current limits with their status
//! bits, limit switches entering ERROR, the ENABLE E-stop loop, the power-stage supply
//! flag, supply vitals, analog inputs and digital I/O.
//!
//! Time is injected: a [`Controller`] advances in whole 1 ms regulator cycles to the `now`
//! it is given, deterministically (seeded measurement noise), so tests run it on a
//! virtual clock and read the true trajectory ([`Controller::true_state`]). A [`SimLine`]
//! serves one or more controllers on any [`motus_serial::Link`] (a pty for tests), with
//! the address plan and revision of the codec, reply timing (processing delay, baud
//! pacing, gateway relay) and fault injection (noise, dropped replies); on a
//! [`motus_clock::VirtualClock`] it is served in process, in the host's thread
//! ([`SimLine::into_sim_link`]), so a driver and its simulator run on virtual time.
//!
//! ```
//! use motus_nfv2_protocol::{Command, CommandCode as C, DriveMode, Frame, Revision};
//! use motus_nfv2_sim::{Controller, ControllerConfig};
//! use std::time::Duration;
//!
//! let mut c = Controller::new(1, &ControllerConfig::default()).unwrap();
//! let mode = i64::from(DriveMode::Position.to_raw(Revision::LATEST).unwrap());
//! let mut frame = Frame::new(1);
//! frame.commands.push(Command::values(C::SetDrivesMode, [mode]));
//! frame.commands.push(Command::values(C::SetDrivesPosition, [4000]));
//! frame.commands.push(Command::query(C::ReadDrivesPosition));
//! let answer = c.handle(&frame, Duration::ZERO).unwrap();
//! assert_eq!(answer.int_values(C::ReadDrivesPosition), Some(&[0][..]));
//! c.advance_to(Duration::from_millis(500));
//! assert!((c.true_state().counter - 4000).abs() <= 2);
//! ```

#![forbid(unsafe_code)]

pub mod config;
mod controller;
mod error;
mod inputs;
mod line;
mod motor;
mod regulator;

pub use config::{ControllerConfig, ManualConfig, MotorConfig, COUNTS_PER_S_PER_SPEED_UNIT};
pub use controller::{Controller, TrueState, CURRENT_LOOP_SUBSTEPS, REGULATOR_PERIOD};
pub use error::SimError;
pub use inputs::LimitSwitch;
pub use line::{
    lock, Controllers, LineError, LineOptions, SharedController, SimClock, SimLine, DEFAULT_REPLY_DELAY,
};
