//! Sans-IO CANopen wire codec (CiA 301 predefined connection set, CiA 305 LSS).
//!
//! Bytes in, typed messages out and back; no IO, threads or clocks.
//!
//! * [`CanFrame`]: a classic CAN frame, with candump notation (`601#4064600000000000`,
//!   `701#R`) through [`std::str::FromStr`] and [`std::fmt::Display`].
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

/// Defines a total wire code table: named variants, an `Unknown(raw)` fallback,
/// conversions both ways, a description and serde as the raw number.
macro_rules! code_table {
    ($(#[$m:meta])* $name:ident : $ty:ty as $tys:literal { $($(#[$vm:meta])* $var:ident = $val:expr => $desc:expr,)* }) => {
        $(#[$m])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
        #[serde(from = $tys, into = $tys)]
        pub enum $name {
            $($(#[$vm])* $var,)*
            /// A value this table does not name, kept raw.
            Unknown($ty),
        }
        impl $name {
            /// Classifies a raw wire value.
            pub fn from_raw(raw: $ty) -> Self {
                match raw { $($val => Self::$var,)* other => Self::Unknown(other) }
            }
            /// The raw wire value.
            pub fn raw(self) -> $ty {
                match self { $(Self::$var => $val,)* Self::Unknown(raw) => raw }
            }
            /// Human-readable meaning (from the specification's table).
            pub fn description(self) -> &'static str {
                match self { $(Self::$var => $desc,)* Self::Unknown(_) => "unknown" }
            }
        }
        impl From<$ty> for $name {
            fn from(raw: $ty) -> Self { Self::from_raw(raw) }
        }
        impl From<$name> for $ty {
            fn from(code: $name) -> Self { code.raw() }
        }
        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.description())
            }
        }
    };
}
pub(crate) use code_table;

pub mod abort;
pub mod cia402;
pub mod emcy;
pub mod error;
pub mod frame;
pub mod lss;
pub mod message;
pub mod nmt;
pub mod sdo;

pub use abort::SdoAbortCode;
pub use emcy::EmcyClass;
pub use error::{EncodeError, FrameError, ParseError};
pub use frame::CanFrame;
pub use lss::{LssIdentityField, LssRequest, LssResponse};
pub use message::{CanOpenMessage, PdoKind};
pub use nmt::{NmtCommand, NmtState};
pub use sdo::{SdoPayload, SdoRequest, SdoResponse};
