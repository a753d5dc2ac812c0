//! Sans-IO CANopen wire codec (CiA 301 predefined connection set, CiA 305 LSS).
//!
//! Bytes in, typed messages out and back; no IO, threads or clocks.
//!
//! * [`CanFrame`]: the classic CAN frame with its candump notation, defined below CANopen
//!   in `motus-can-frame` and re-exported here because this codec's API takes and builds it.
//! * [`CanOpenMessage`]: a frame classified by COB-ID and decoded. Decoding is total and
//!   lossless: a frame that does not fit its service's layout exactly is kept as
//!   [`CanOpenMessage::Raw`], so `encode(decode(x)) == x` for every valid frame.
//!
//! ```
//! use motus_canopen_protocol::{CanFrame, CanOpenMessage};
//! let frame: CanFrame = "583#43646000E8030000".parse().unwrap();
//! let msg = CanOpenMessage::decode(&frame);
//! assert_eq!(msg.to_string(), "SDO upload response 0x6064:00 = 1000 (node 3)");
//! assert_eq!(msg.encode().unwrap(), frame);
//! ```
#![forbid(unsafe_code)]

pub mod abort;
pub mod emcy;
pub mod error;
pub mod lss;
pub mod message;
pub mod nmt;
pub mod sdo;

pub use abort::SdoAbortCode;
pub use emcy::EmcyClass;
pub use error::EncodeError;
pub use lss::{LssIdentityField, LssRequest, LssResponse};
pub use message::{CanOpenMessage, PdoKind};
pub use nmt::{NmtCommand, NmtState};
pub use sdo::{SdoPayload, SdoRequest, SdoResponse};

// The CAN frame this codec classifies and builds, and its errors: they live below CANopen,
// in `motus-can-frame`, shared with the CAN transports.
pub use motus_can_frame::{CanFrame, FrameError, ParseError};
