//! Sans-IO codec for **NFv2**, the protocol of the 1209A axis controller (pan-tilt head)
//! and of other modules of the same family (specs/nfv2.md).
//!
//! Bytes in, typed frames out and back: no IO, threads or clocks.
//!
//! - [`Frame`] / [`Command`]: a frame for one slave address with any mix of set-points,
//!   queries (`k = 0`) and answers; unknown commands are skipped by their length and kept
//!   raw ([`Command::Unknown`]).
//! - [`crc`]: CRC-8, polynomial 0xD8 MSB-first, init 0, no reflection, no final XOR, over
//!   bytes 3..n-1 (address to last parameter byte).
//! - [`Revision`]: value widths per (revision, code); [`Revision::LATEST`] by default.
//! - [`FrameScanner`] / [`StreamDecoder`]: find `'#' n !n` frames in a noisy stream (for
//!   the serial bus master, and streaming), resynchronise after a bad CRC, count garbage
//!   and corrupt frames.
//! - [`FrameBuilder`], [`DeviceProfile`], [`wire_time`]: what a bus scheduler needs to pack
//!   commands per slave and budget wire time (57600 bps RS-485: a 2 ms cycle is out of
//!   reach for one query and its answer, 3.1 ms).
//! - [`AddressPlan`]: address 0 is the gateway in the seed and broadcast in some reference
//!   configurations; both are representable.
//!
//! # JSON form
//! [`Frame`] derives serde; `motus decode nfv2 <hex>` prints it and
//! `motus encode nfv2 '<json>'` reads it back, and `encode(decode(x)) == x` for every
//! valid frame `x`:
//!
//! ```
//! use motus_nfv2_protocol::{decode_frame, encode_frame, Revision};
//! // '#', n = 14, !n, address 1, SetDrivesPosition -5000, query ReadDrivesPosition,
//! // query ReadDrivesStatus, CRC.
//! let bytes = [0x23, 0x0E, 0xF1, 0x01, 0x13, 0x04, 0x78, 0xEC, 0xFF, 0xFF, 0x1A, 0x00, 0x1F, 0x00, 0xF0];
//! let frame = decode_frame(&bytes, Revision::LATEST)?;
//! let json = serde_json::to_string(&frame).unwrap_or_default();
//! assert_eq!(json, r#"{"address":1,"commands":[{"kind":"values","code":"set_drives_position","values":[-5000]},{"kind":"query","code":"read_drives_position"},{"kind":"query","code":"read_drives_status"}]}"#);
//! let back: motus_nfv2_protocol::Frame = serde_json::from_str(&json).unwrap_or_default();
//! assert_eq!(encode_frame(&back, Revision::LATEST).ok(), Some(bytes.to_vec()));
//! # Ok::<(), motus_nfv2_protocol::DecodeError>(())
//! ```

#![forbid(unsafe_code)]

pub mod address;
pub mod builder;
pub mod code;
pub mod command;
pub mod crc;
pub mod drive;
pub mod error;
pub mod frame;
pub mod profile;
pub mod reply;
pub mod revision;
pub mod stream;
pub mod value;

pub use address::{AddressPlan, AddressRole};
pub use builder::FrameBuilder;
pub use code::CommandCode;
pub use command::Command;
pub use drive::{DriveMode, DriveStatus, DrivesMisc};
pub use error::{DecodeError, EncodeError};
pub use frame::{Frame, RawFrame, HEADER_LEN, MAX_FRAME_LEN, MIN_FRAME_LEN, OVERHEAD, START};
pub use motus_wire::StreamStats;
pub use profile::{wire_time, DeviceProfile, BITS_PER_BYTE_8N1, RS485_BAUD};
pub use reply::answer;
pub use revision::{ParseRevisionError, Revision};
pub use stream::{FrameScanner, StreamDecoder, StreamEvent};
pub use value::{Regulator, ValueKind};

/// Decodes exactly one frame (all of `bytes`) with `rev`'s value widths.
///
/// # Errors
/// Any [`DecodeError`].
pub fn decode_frame(bytes: &[u8], rev: Revision) -> Result<Frame, DecodeError> {
    Frame::decode(bytes, rev)
}

/// Encodes `frame` with `rev`'s value widths.
///
/// # Errors
/// Any [`EncodeError`] except [`EncodeError::BufferTooSmall`].
pub fn encode_frame(frame: &Frame, rev: Revision) -> Result<Vec<u8>, EncodeError> {
    frame.encode(rev)
}
