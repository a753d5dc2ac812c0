//! Sans-IO codec for the KV-01 arm's communication-module protocol (`specs/kv01.md`) and the
//! Faulhaber ASCII commands carried inside its D0/D2 messages ([`faulhaber`],
//! `specs/faulhaber.md`).
//!
//! - Frames: standard messages (ADDRESS, LENGTH, COMMAND, DATA, CRC, 0xF0) both ways, short
//!   messages (ADDRESS, two letters, 0xF0) from modules. [`crc`] implements the published CRC.
//! - Typed messages: [`Message`] = [`Request`] (host -> module, [`Command`] D0..D5) or
//!   [`Reply`] (module -> host, [`ReplyBody`]).
//! - One-shot: [`decode_message`] / [`encode_message`] / [`Message::encode_into`].
//! - Streaming: [`MessageScanner`] finds a message at the start of received bytes (for the
//!   serial bus master), [`StreamDecoder`] resynchronises after garbage over it and counts
//!   CRC failures.
//! - CRC checking is [`CrcMode::Strict`] by default; [`CrcMode::Lenient`] accepts a bad CRC
//!   and reports it, because the source's own example messages do not carry the CRC its
//!   published procedure gives.
//!
//! ```
//! use motus_kv01_protocol::{decode_message, Address, Command, CrcMode, Direction, Message};
//!
//! let msg = Message::request(Address::joint(2).unwrap(), Command::Faulhaber { text: "EN".into() });
//! let bytes = msg.encode().unwrap();
//! assert_eq!(bytes, [0xE2, 0x07, 0xD0, b'E', b'N', 0xFB, 0xF0]);
//! let back = decode_message(&bytes, Direction::ToModule, CrcMode::Strict).unwrap();
//! assert_eq!(back.message, msg);
//! ```

mod address;
mod codec;
mod command;
pub mod crc;
mod error;
pub mod faulhaber;
mod frame;
mod message;
mod reply;
pub mod status;
pub mod stream;
pub mod text;

pub use address::{Address, InvalidAddress};
pub use command::{code, Command, D1Action, Request};
pub use error::{DecodeError, EncodeError};
pub use message::{
    decode_message, encode_message, guess_direction, CrcMismatch, CrcMode, Decoded, Direction, Message,
};
pub use motus_wire::StreamStats;
pub use reply::{Answer, Reply, ReplyBody, ShortCode};
pub use status::{GripperLoad, GripperStatus, JointStatus, ResolverReading, Voltages};
pub use stream::{CrcFailure, MessageScanner, StreamDecoder, StreamEvent};

/// The END byte of every message.
pub const END: u8 = 0xF0;
/// Length of a short message.
pub const SHORT_LEN: usize = 4;
/// Length of a standard message without data.
pub const MIN_STANDARD_LEN: usize = 5;
/// Largest message (LENGTH is one byte).
pub const MAX_FRAME_LEN: usize = 255;
/// Largest DATA of a standard message.
pub const MAX_DATA_LEN: usize = MAX_FRAME_LEN - MIN_STANDARD_LEN;
