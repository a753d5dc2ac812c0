//! Host -> module messages: the commands D0..D5 (`specs/kv01.md`, "Commands").
//!
//! D0/D2 text is kept exactly as sent (Latin-1, see [`crate::text`]); use
//! [`Command::faulhaber_request`] for its typed Faulhaber form and [`Command::d0`] /
//! [`Command::d2`] to build one from a typed [`faulhaber::Request`].

use serde::{Deserialize, Serialize};

use crate::codec::Payload;
use crate::faulhaber;
use crate::text::from_latin1;
use crate::{Address, EncodeError};

/// Command codes.
pub mod code {
    /// D0: pass-through to the Faulhaber controller.
    pub const D0: u8 = 0xD0;
    /// D1: brake / limit switch (gripper: current limitation).
    pub const D1: u8 = 0xD1;
    /// D2: fast message (Faulhaber text in, resolver reply out).
    pub const D2: u8 = 0xD2;
    /// D3: resolver.
    pub const D3: u8 = 0xD3;
    /// D4: voltages.
    pub const D4: u8 = 0xD4;
    /// D5: gripper open/close.
    pub const D5: u8 = 0xD5;
}

/// The D1 data byte of a host message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(tag = "action", rename_all = "snake_case")]
pub enum D1Action {
    /// 0xB1: release the brake (send "EN" first).
    ReleaseBrake,
    /// 0xB0: engage the brake.
    EngageBrake,
    /// 0xA1: enter restricted mode (drive out of a limit switch at |v| <= 399 rpm).
    EnterRestrictedMode,
    /// 0xA0: leave restricted mode.
    LeaveRestrictedMode,
    /// 0xC1 (gripper): enable the open/close motor's current limitation.
    EnableCurrentLimit,
    /// 0xC0 (gripper): disable the open/close motor's current limitation.
    DisableCurrentLimit,
    /// Any other byte, kept as sent.
    Unknown {
        /// The data byte.
        byte: u8,
    },
}

impl D1Action {
    /// The action for a data byte.
    #[must_use]
    pub const fn from_byte(byte: u8) -> Self {
        match byte {
            0xB1 => Self::ReleaseBrake,
            0xB0 => Self::EngageBrake,
            0xA1 => Self::EnterRestrictedMode,
            0xA0 => Self::LeaveRestrictedMode,
            0xC1 => Self::EnableCurrentLimit,
            0xC0 => Self::DisableCurrentLimit,
            byte => Self::Unknown { byte },
        }
    }

    /// The data byte.
    #[must_use]
    pub const fn byte(self) -> u8 {
        match self {
            Self::ReleaseBrake => 0xB1,
            Self::EngageBrake => 0xB0,
            Self::EnterRestrictedMode => 0xA1,
            Self::LeaveRestrictedMode => 0xA0,
            Self::EnableCurrentLimit => 0xC1,
            Self::DisableCurrentLimit => 0xC0,
            Self::Unknown { byte } => byte,
        }
    }
}

/// A host -> module command. JSON: `{"command": "d0", "text": "EN"}`, `{"command": "d3"}`...
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(tag = "command")]
pub enum Command {
    /// D0: Faulhaber ASCII command without terminator (e.g. "EN", "V320"). Empty text is
    /// answered "UC" by the module.
    #[serde(rename = "d0")]
    Faulhaber {
        /// The command text (Latin-1, exactly as sent).
        text: String,
    },
    /// D1: brake / restricted mode / gripper current limitation.
    #[serde(rename = "d1")]
    BrakeLimit(D1Action),
    /// D2: fast message: the text goes to the controller, the reply is the resolver reading.
    #[serde(rename = "d2")]
    Fast {
        /// The command text (Latin-1, exactly as sent).
        text: String,
    },
    /// D3: read the resolver.
    #[serde(rename = "d3")]
    ReadResolver,
    /// D4: read the supply voltages.
    #[serde(rename = "d4")]
    ReadVoltages,
    /// D5 (gripper): open/close speed and direction.
    #[serde(rename = "d5")]
    Gripper {
        /// Speed, bits 0-4 (0..=31).
        speed: u8,
        /// Bit 5: 1 = opening.
        opening: bool,
    },
    /// Any other command code, or a known code whose data does not have its shape
    /// (e.g. D3 with data), kept as sent.
    #[serde(rename = "other")]
    Other {
        /// The COMMAND byte.
        code: u8,
        /// The DATA bytes.
        data: Vec<u8>,
    },
}

impl Command {
    /// Largest D5 speed.
    pub const MAX_GRIPPER_SPEED: u8 = 31;

    /// A D0 command carrying a typed Faulhaber request (canonical text).
    #[must_use]
    pub fn d0(request: &faulhaber::Request) -> Self {
        Self::Faulhaber { text: request.to_string() }
    }

    /// A D2 (fast) command carrying a typed Faulhaber request (canonical text).
    #[must_use]
    pub fn d2(request: &faulhaber::Request) -> Self {
        Self::Fast { text: request.to_string() }
    }

    /// The COMMAND byte.
    #[must_use]
    pub fn code(&self) -> u8 {
        match self {
            Self::Faulhaber { .. } => code::D0,
            Self::BrakeLimit(_) => code::D1,
            Self::Fast { .. } => code::D2,
            Self::ReadResolver => code::D3,
            Self::ReadVoltages => code::D4,
            Self::Gripper { .. } => code::D5,
            Self::Other { code, .. } => *code,
        }
    }

    /// The D0/D2 text parsed as a Faulhaber request (`None` for the other commands).
    #[must_use]
    pub fn faulhaber_request(&self) -> Option<Result<faulhaber::Request, faulhaber::RequestError>> {
        match self {
            Self::Faulhaber { text } | Self::Fast { text } => Some(faulhaber::Request::parse(text)),
            _ => None,
        }
    }

    /// Decodes COMMAND and DATA (total: shapes that do not fit give [`Command::Other`]).
    #[must_use]
    pub fn from_wire(code: u8, data: &[u8]) -> Self {
        match (code, data) {
            (code::D0, text) => Self::Faulhaber { text: from_latin1(text) },
            (code::D1, [b]) => Self::BrakeLimit(D1Action::from_byte(*b)),
            (code::D2, text) => Self::Fast { text: from_latin1(text) },
            (code::D3, []) => Self::ReadResolver,
            (code::D4, []) => Self::ReadVoltages,
            (code::D5, [b]) if b & 0xC0 == 0 => Self::Gripper { speed: b & 0x1F, opening: b & 0x20 != 0 },
            (code, data) => Self::Other { code, data: data.to_vec() },
        }
    }

    pub(crate) fn payload(&self) -> Result<Payload<'_>, EncodeError> {
        Ok(match self {
            Self::Faulhaber { text } | Self::Fast { text } => Payload::Text(text),
            Self::BrakeLimit(a) => Payload::Byte(a.byte()),
            Self::ReadResolver | Self::ReadVoltages => Payload::Empty,
            Self::Gripper { speed, opening } => {
                if *speed > Self::MAX_GRIPPER_SPEED {
                    return Err(EncodeError::OutOfRange {
                        field: "gripper speed",
                        value: u32::from(*speed),
                        max: u32::from(Self::MAX_GRIPPER_SPEED),
                    });
                }
                Payload::Byte(speed | u8::from(*opening) << 5)
            }
            Self::Other { data, .. } => Payload::Bytes(data),
        })
    }
}

/// A host -> module message: the module address and the command.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Request {
    /// The module addressed.
    pub address: Address,
    /// The command.
    #[serde(flatten)]
    pub command: Command,
}

impl Request {
    /// A request to `address`.
    #[must_use]
    pub const fn new(address: Address, command: Command) -> Self {
        Self { address, command }
    }
}
