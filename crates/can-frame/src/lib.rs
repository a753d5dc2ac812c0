//! The classic CAN frame, shared by every CAN layer of Motus: the transports (`motus-can`)
//! carry it, the CANopen codec (`motus-canopen-protocol`) classifies it.
//!
//! Sans-IO and a leaf of the CAN stack (no Motus dependency), so that the CAN transports
//! do not depend on the CANopen codec that sits above them.
//!
//! * [`CanFrame`]: a classic CAN data or remote frame (standard 11-bit or extended 29-bit
//!   identifier, 0-8 bytes), always valid once built; JSON through serde.
//! * The candump text notation (`601#4064600000000000`, `701#R`, `12345678#00`) through
//!   [`std::str::FromStr`] and [`std::fmt::Display`].
//! * [`FrameError`] (a frame that cannot be built) and [`ParseError`] (candump text that
//!   cannot be parsed).
//!
//! ```
//! use motus_can_frame::CanFrame;
//! let frame: CanFrame = "601#4064600000000000".parse().unwrap();
//! assert_eq!(frame.id(), 0x601);
//! assert_eq!(frame.data(), [0x40, 0x64, 0x60, 0, 0, 0, 0, 0]);
//! assert_eq!(frame.to_string(), "601#4064600000000000");
//! ```
#![forbid(unsafe_code)]

mod error;
mod frame;

pub use error::{FrameError, ParseError};
pub use frame::{CanFrame, MAX_EXTENDED_ID, MAX_STANDARD_ID};
