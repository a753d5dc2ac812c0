//! # motus-mouse-protocol — the omni robot's optical-mouse odometry sensor
//!
//! Sans-IO codecs (bytes in, typed packets out and back; no IO, threads or clocks) for the
//! sensor described in `specs/omni-robot.md` (seed 000):
//!
//! * [`converter`]: the 7-byte packet of the ATmega PS/2 -> RS-232 converter
//!   (`'a'`, device type, X1, X2, Y1, Y2, `'x'`; 9600 bit/s 8N1), with
//!   [`ConverterStream`], a resynchronising streaming decoder.
//! * [`microsoft`]: the plain Microsoft 2-button serial mouse (3-byte packets) and
//!   [`MicrosoftStream`].
//! * [`mouse_systems`]: the Mouse Systems 3-button serial mouse (5-byte packets) and
//!   [`MouseSystemsStream`].
//! * [`calibration`]: counts per metre (10 cm = 850 counts) and conversions to metres and
//!   robot wheel increments.
//!
//! Every decoder is total: it never panics on any input and skips garbage. The three
//! streams are [`motus_wire::Stream`]s over a [`PacketScanner`].

#![forbid(unsafe_code)]

pub mod calibration;
pub mod converter;
pub mod error;
pub mod microsoft;
pub mod mouse_systems;
mod scan;

pub use calibration::Calibration;
pub use converter::{ConverterPacket, ConverterStream, DeviceType, PACKET_LEN};
pub use error::PacketError;
pub use microsoft::{MicrosoftPacket, MicrosoftStream};
pub use motus_wire::{Stream, StreamStats};
pub use mouse_systems::{MouseSystemsPacket, MouseSystemsStream};
pub use scan::{Packet, PacketScanner};

/// Relative motion and buttons of one serial-mouse packet, in one convention for both
/// protocols: `dx` positive to the right, `dy` positive **up** (away from the user), as
/// the Mouse Systems protocol sends it; the Microsoft protocol's `dy` (positive down) is
/// negated.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct MouseReport {
    /// Motion to the right, counts.
    pub dx: i16,
    /// Motion up (away from the user), counts.
    pub dy: i16,
    /// Left button pressed.
    pub left: bool,
    /// Middle button pressed (always false for a Microsoft 2-button mouse).
    pub middle: bool,
    /// Right button pressed.
    pub right: bool,
}
