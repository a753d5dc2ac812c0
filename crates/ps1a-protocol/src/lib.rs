//! # motus-ps1a-protocol — the PS1A serial protocol, sans IO
//!
//! The PS1A is a DIN-rail module closing the position loop of one servo axis; a host
//! commands up to 16 of them on one RS-232/RS-485 line (spec: `specs/ps1a.md`, source
//! seed 004). This crate turns bytes into typed frames and back; it does no IO and keeps
//! no clock.
//!
//! * [`CommandFrame`] (host -> module): `ADR N KOD P1..PN CHSUM`, commands 0-10
//!   ([`Command`]), typed parameters ([`Parameters`], [`ControlByte`], [`Acceleration`],
//!   [`DdaCycle`], [`BaudRate`], 24-bit [`U24`]/[`I24`] values).
//! * [`StatusReply`] (module -> host): the fixed 8-byte status with [`LowStatus`] and
//!   [`HighStatus`] bits and the 24-bit position.
//! * [`checksum`]: the 8-bit sum, carry ignored.
//! * [`CommandScanner`] / [`ReplyScanner`]: find a frame at the start of received bytes
//!   (for the serial bus master), and [`CommandStream`] / [`ReplyStream`]: the streaming
//!   decoders over them ([`motus_wire::Stream`]) that resynchronise after garbage, for a
//!   module and for a host.
//! * [`units`]: speed and acceleration numbers to units/s and units/s^2 (the mapping the
//!   source lost is chosen and documented there, in one place).
//!
//! Decoding never panics: every index is checked, every value is validated, and every
//! error says what was wrong ([`DecodeError`]).

#![forbid(unsafe_code)]

pub mod checksum;
mod command;
mod error;
pub mod layout;
mod parameters;
mod reply;
mod status;
mod stream;
pub mod units;
mod values;

pub use command::{Command, CommandCode, CommandFrame};
pub use error::{DecodeError, EncodeError};
pub use motus_wire::{Stream, StreamStats};
pub use parameters::{Acceleration, BaudRate, ControlByte, DdaCycle, Parameters};
pub use reply::StatusReply;
pub use status::{HighStatus, LowStatus};
pub use stream::{ChecksumError, CommandScanner, CommandStream, ReplyScanner, ReplyStream, StreamEvent};
pub use values::{I24, U24};

/// Length in bytes of a status reply (`ADR N LBS HBS BP1 BP2 BP3 CSUM`).
pub const REPLY_LEN: usize = 8;
/// Largest command frame: set parameters, 4 header/trailer bytes + 11 parameters.
pub const MAX_COMMAND_LEN: usize = 15;
/// Highest number of modules on one line.
pub const MAX_MODULES_PER_LINE: usize = 16;
