//! Module -> host messages: standard replies to D0..D5 and the short messages "UC"/"TO"
//! (`specs/kv01.md`).
//!
//! **D1 status byte:** the byte alone cannot tell joint bits from gripper bits, so the decoder
//! uses the address: a D1 reply from 0xE6 is [`ReplyBody::GripperStatus`] (LIMIT, PHASE,
//! BRAKE), from 0xE1..=0xE5 [`ReplyBody::Status`]. The D2/D3 resolver status bits always
//! have the joint meaning (the source says so for the gripper module too).
//!
//! **D2 reply:** the source says the reply to D2 "is the D3 resolver reply" but not which
//! COMMAND byte it carries; both are decoded ([`ReplyBody::FastResolver`] for D2,
//! [`ReplyBody::Resolver`] for D3). A simulator should echo D2.

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::codec::Payload;
use crate::command::code;
use crate::faulhaber;
use crate::status::{GripperLoad, GripperStatus, JointStatus, ResolverReading, Voltages};
use crate::text::from_latin1;
use crate::{Address, EncodeError};

/// The DATA of a D0 reply: an answer made by the module itself, or the controller's.
/// In JSON it is the answer text (a string).
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(from = "String", into = "String")]
pub enum Answer {
    /// "TIMEOUT": the controller did not answer in time (a bus failure behind the module).
    Timeout,
    /// "LSSTOP": a speed command blocked after a limit-switch stop (a device refusal).
    LsStop,
    /// "LIMVAL": a speed outside -399..=399 rpm refused in restricted mode (a device refusal).
    LimVal,
    /// The controller's answer.
    Controller(faulhaber::Reply),
}

impl Answer {
    /// Classifies a D0 reply text (total and exact, like [`faulhaber::Reply::parse`]).
    #[must_use]
    pub fn parse(text: &str) -> Self {
        match text {
            "TIMEOUT" => Self::Timeout,
            "LSSTOP" => Self::LsStop,
            "LIMVAL" => Self::LimVal,
            _ => Self::Controller(faulhaber::Reply::parse(text)),
        }
    }
}

impl fmt::Display for Answer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Timeout => f.write_str("TIMEOUT"),
            Self::LsStop => f.write_str("LSSTOP"),
            Self::LimVal => f.write_str("LIMVAL"),
            Self::Controller(r) => r.fmt(f),
        }
    }
}

impl From<String> for Answer {
    fn from(s: String) -> Self {
        Self::parse(&s)
    }
}

impl From<Answer> for String {
    fn from(a: Answer) -> Self {
        a.to_string()
    }
}

impl From<faulhaber::Reply> for Answer {
    fn from(r: faulhaber::Reply) -> Self {
        Self::Controller(r)
    }
}

/// The two characters of a short message. In JSON a two-letter string.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum ShortCode {
    /// "UC": unknown command (e.g. D0 without data).
    UnknownCommand,
    /// "TO": the module's 700 ms safety time-out has tripped (latched).
    Timeout,
    /// Any other two capital letters, kept raw.
    Other([u8; 2]),
}

impl ShortCode {
    /// The code for two bytes, `None` unless both are ASCII capital letters.
    #[must_use]
    pub const fn from_bytes(bytes: [u8; 2]) -> Option<Self> {
        match bytes {
            [b'U', b'C'] => Some(Self::UnknownCommand),
            [b'T', b'O'] => Some(Self::Timeout),
            [a, b] if a.is_ascii_uppercase() && b.is_ascii_uppercase() => Some(Self::Other(bytes)),
            _ => None,
        }
    }

    /// The two bytes.
    #[must_use]
    pub const fn bytes(self) -> [u8; 2] {
        match self {
            Self::UnknownCommand => *b"UC",
            Self::Timeout => *b"TO",
            Self::Other(b) => b,
        }
    }
}

impl TryFrom<String> for ShortCode {
    type Error = String;
    fn try_from(s: String) -> Result<Self, Self::Error> {
        match *s.as_bytes() {
            [a, b] => Self::from_bytes([a, b]),
            _ => None,
        }
        .ok_or_else(|| format!("short message code must be two capital letters, got {s:?}"))
    }
}

impl From<ShortCode> for String {
    fn from(c: ShortCode) -> Self {
        c.bytes().iter().map(|&b| char::from(b)).collect()
    }
}

/// What a module replies. JSON: `{"command": "d3", "position": 1234, ...}`.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(tag = "command")]
pub enum ReplyBody {
    /// D0: the answer text.
    #[serde(rename = "d0")]
    Faulhaber {
        /// The answer.
        answer: Answer,
    },
    /// D1 from joints 1-5 (0xE1..=0xE5): brake / limit-switch status.
    #[serde(rename = "d1")]
    Status(JointStatus),
    /// D1 from the gripper (0xE6): LIMIT, PHASE, BRAKE.
    #[serde(rename = "d1_gripper")]
    GripperStatus(GripperStatus),
    /// D2: the resolver reading answering a fast message.
    #[serde(rename = "d2")]
    FastResolver(ResolverReading),
    /// D3: the resolver reading.
    #[serde(rename = "d3")]
    Resolver(ResolverReading),
    /// D4: supply voltages.
    #[serde(rename = "d4")]
    Voltages(Voltages),
    /// D5: gripper motor load and status.
    #[serde(rename = "d5")]
    Gripper(GripperLoad),
    /// A short message ("UC", "TO", ...).
    #[serde(rename = "short")]
    Short {
        /// The two characters.
        text: ShortCode,
    },
    /// Any other command code, or a known code whose data does not have its shape (wrong
    /// length, reserved bit set), kept as received.
    #[serde(rename = "other")]
    Other {
        /// The COMMAND byte.
        code: u8,
        /// The DATA bytes.
        data: Vec<u8>,
    },
}

impl ReplyBody {
    /// Decodes COMMAND and DATA of a standard reply from `address` (total).
    #[must_use]
    pub fn from_wire(address: Address, code: u8, data: &[u8]) -> Self {
        let decoded = match (code, data) {
            (code::D0, text) => Some(Self::Faulhaber { answer: Answer::parse(&from_latin1(text)) }),
            (code::D1, [b]) if address.is_gripper() => GripperStatus::from_byte(*b).map(Self::GripperStatus),
            (code::D1, [b]) => JointStatus::from_byte(*b).map(Self::Status),
            (code::D2, [a, b, c]) => ResolverReading::from_bytes([*a, *b, *c]).map(Self::FastResolver),
            (code::D3, [a, b, c]) => ResolverReading::from_bytes([*a, *b, *c]).map(Self::Resolver),
            (code::D4, [a, b, c, d, e, f]) => {
                Some(Self::Voltages(Voltages::from_bytes([*a, *b, *c, *d, *e, *f])))
            }
            (code::D5, [b]) => GripperLoad::from_byte(*b).map(Self::Gripper),
            _ => None,
        };
        decoded.unwrap_or_else(|| Self::Other { code, data: data.to_vec() })
    }

    /// The COMMAND byte (`None` for a short message).
    #[must_use]
    pub fn code(&self) -> Option<u8> {
        Some(match self {
            Self::Faulhaber { .. } => code::D0,
            Self::Status(_) | Self::GripperStatus(_) => code::D1,
            Self::FastResolver(_) => code::D2,
            Self::Resolver(_) => code::D3,
            Self::Voltages(_) => code::D4,
            Self::Gripper(_) => code::D5,
            Self::Short { .. } => return None,
            Self::Other { code, .. } => *code,
        })
    }

    /// The resolver reading of a D2 or D3 reply.
    #[must_use]
    pub fn resolver(&self) -> Option<ResolverReading> {
        match self {
            Self::FastResolver(r) | Self::Resolver(r) => Some(*r),
            _ => None,
        }
    }

    pub(crate) fn payload(&self, address: Address) -> Result<Payload<'_>, EncodeError> {
        Ok(match self {
            Self::Faulhaber { answer } => Payload::Answer(answer),
            Self::Status(s) => {
                if address.is_gripper() {
                    return Err(EncodeError::StatusAddress {
                        what: "joint D1 status",
                        address: address.raw(),
                    });
                }
                Payload::Byte(s.bits())
            }
            Self::GripperStatus(s) => {
                if !address.is_gripper() {
                    return Err(EncodeError::StatusAddress {
                        what: "gripper D1 status",
                        address: address.raw(),
                    });
                }
                Payload::Byte(s.bits())
            }
            Self::FastResolver(r) | Self::Resolver(r) => Payload::Bytes3(r.to_bytes()),
            Self::Voltages(v) => Payload::Bytes6(v.to_bytes()),
            Self::Gripper(l) => Payload::Byte(l.to_byte().ok_or(EncodeError::OutOfRange {
                field: "gripper load",
                value: u32::from(l.load),
                max: u32::from(GripperLoad::MAX_LOAD),
            })?),
            Self::Short { .. } => Payload::Empty,
            Self::Other { data, .. } => Payload::Bytes(data),
        })
    }
}

/// A module -> host message: the replying module's address and what it says.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Reply {
    /// The module replying.
    pub address: Address,
    /// The reply.
    #[serde(flatten)]
    pub body: ReplyBody,
}

impl Reply {
    /// A reply from `address`.
    #[must_use]
    pub const fn new(address: Address, body: ReplyBody) -> Self {
        Self { address, body }
    }
}
