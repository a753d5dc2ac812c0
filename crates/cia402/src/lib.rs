//! # motus-cia402 — CiA 402 drives, whatever carries their objects
//!
//! The driver speaks to a drive through [`DriveIo`]: read and write objects, write the
//! controlword, read the statusword. The CANopen master implements it with SDOs and PDOs
//! (crate `motus-canopen`); tests implement it with a model. On top:
//!
//! - [`Drive`]: the power state machine driven from the statusword (enable, disable,
//!   fault reset with a clean 0 -> 1 edge, quick stop), modes of operation with the
//!   display check, profile position with the set-point handshake (controlword bits
//!   4/5/6/8, statusword bits 10/12/13), profile velocity, homing, software limits.
//! - [`Cia402Axis`]: a drive as an axis of the axis model (SI units through a scale).
//! - [`group`]: several drives starting together (synchronous RPDO, then one SYNC) and
//!   the bus cost of that compared with SDO writes.

#![forbid(unsafe_code)]

mod axis;
pub mod canopen_io;
mod drive;
mod error;
pub mod group;
mod io;
mod settings;

pub use axis::Cia402Axis;
pub use canopen_io::{CanopenDrive, MasterSync};
pub use drive::{Drive, MoveKind};
pub use error::DriveError;
pub use io::{DriveIo, IoError};
pub use settings::{DriveSettings, Profile};
