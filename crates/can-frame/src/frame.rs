//! Classic CAN frame and its candump text notation (`601#4064600000000000`, `701#R`,
//! `12345678#00`: 3 hex digits = standard 11-bit id, 8 = extended 29-bit id).

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::error::{FrameError, ParseError};

/// Largest standard (CAN 2.0A, 11-bit) identifier.
pub const MAX_STANDARD_ID: u32 = 0x7FF;
/// Largest extended (CAN 2.0B, 29-bit) identifier.
pub const MAX_EXTENDED_ID: u32 = 0x1FFF_FFFF;

/// A classic CAN data or remote frame (0–8 bytes). Always valid once built.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "CanFrameRepr", into = "CanFrameRepr")]
pub struct CanFrame {
    id: u32,
    extended: bool,
    rtr: bool,
    len: u8,
    data: [u8; 8],
}

/// JSON form of a [`CanFrame`].
#[derive(Serialize, Deserialize)]
struct CanFrameRepr {
    id: u32,
    #[serde(default)]
    extended: bool,
    #[serde(default)]
    rtr: bool,
    #[serde(default)]
    data: Vec<u8>,
    /// Requested length of a remote frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    dlc: Option<u8>,
}

impl TryFrom<CanFrameRepr> for CanFrame {
    type Error = FrameError;
    fn try_from(r: CanFrameRepr) -> Result<Self, FrameError> {
        if r.rtr {
            Self::remote(r.id, r.extended, r.dlc.unwrap_or(0))
        } else {
            Self::with_format(r.id, r.extended, &r.data)
        }
    }
}

impl From<CanFrame> for CanFrameRepr {
    fn from(f: CanFrame) -> Self {
        CanFrameRepr {
            id: f.id,
            extended: f.extended,
            rtr: f.rtr,
            data: f.data().to_vec(),
            dlc: f.rtr.then_some(f.len),
        }
    }
}

fn check_id(id: u32, extended: bool) -> Result<(), FrameError> {
    let max = if extended { MAX_EXTENDED_ID } else { MAX_STANDARD_ID };
    if id > max {
        return Err(FrameError::IdOutOfRange { id, extended });
    }
    Ok(())
}

impl CanFrame {
    /// A standard (11-bit id) data frame, as CANopen uses.
    pub fn new(id: u32, data: &[u8]) -> Result<Self, FrameError> {
        Self::with_format(id, false, data)
    }

    /// A data frame with a standard or extended identifier.
    pub fn with_format(id: u32, extended: bool, data: &[u8]) -> Result<Self, FrameError> {
        check_id(id, extended)?;
        let mut buf = [0u8; 8];
        let dst = buf.get_mut(..data.len()).ok_or(FrameError::TooLong { len: data.len() })?;
        dst.copy_from_slice(data);
        Ok(Self { id, extended, rtr: false, len: data.len() as u8, data: buf })
    }

    /// A remote (RTR) frame requesting `dlc` bytes.
    pub fn remote(id: u32, extended: bool, dlc: u8) -> Result<Self, FrameError> {
        check_id(id, extended)?;
        if dlc > 8 {
            return Err(FrameError::TooLong { len: usize::from(dlc) });
        }
        Ok(Self { id, extended, rtr: true, len: dlc, data: [0; 8] })
    }

    /// The identifier (11 or 29 bits).
    pub fn id(&self) -> u32 {
        self.id
    }

    /// Whether the identifier is extended (29-bit).
    pub fn is_extended(&self) -> bool {
        self.extended
    }

    /// Whether this is a remote (RTR) frame.
    pub fn is_remote(&self) -> bool {
        self.rtr
    }

    /// The data length code (for a remote frame: the requested length).
    pub fn dlc(&self) -> u8 {
        self.len
    }

    /// The data bytes (empty for a remote frame).
    pub fn data(&self) -> &[u8] {
        if self.rtr {
            &[]
        } else {
            self.data.get(..usize::from(self.len)).unwrap_or(&[])
        }
    }
}

impl fmt::Display for CanFrame {
    /// candump notation: `601#4064600000000000`, `701#R`, `12345678#00`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.extended {
            write!(f, "{:08X}#", self.id)?;
        } else {
            write!(f, "{:03X}#", self.id)?;
        }
        if self.rtr {
            f.write_str("R")?;
            if self.len > 0 {
                write!(f, "{}", self.len)?;
            }
            return Ok(());
        }
        for b in self.data() {
            write!(f, "{b:02X}")?;
        }
        Ok(())
    }
}

impl FromStr for CanFrame {
    type Err = ParseError;

    fn from_str(s: &str) -> Result<Self, ParseError> {
        let s = s.trim();
        let (id_text, data_text) = s.split_once('#').ok_or(ParseError::MissingSeparator)?;
        if data_text.starts_with('#') {
            return Err(ParseError::CanFd);
        }
        let extended = match id_text.len() {
            3 => false,
            8 => true,
            _ => return Err(ParseError::BadId(id_text.to_owned())),
        };
        if !id_text.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(ParseError::BadId(id_text.to_owned()));
        }
        let id = u32::from_str_radix(id_text, 16).map_err(|_| ParseError::BadId(id_text.to_owned()))?;
        let bad = || ParseError::BadData(data_text.to_owned());
        if let Some(rest) = data_text.strip_prefix('R').or_else(|| data_text.strip_prefix('r')) {
            let dlc = match rest.as_bytes() {
                [] => 0,
                [d @ b'0'..=b'8'] => d - b'0',
                _ => return Err(bad()),
            };
            return Ok(Self::remote(id, extended, dlc)?);
        }
        let mut data = [0u8; 8];
        let mut len = 0usize;
        let mut digits = data_text.bytes().filter(|&b| b != b'.');
        while let Some(hi) = digits.next() {
            let lo = digits.next().ok_or_else(bad)?;
            let byte = hex_val(hi).ok_or_else(bad)? << 4 | hex_val(lo).ok_or_else(bad)?;
            let slot = data.get_mut(len).ok_or(FrameError::TooLong { len: len + 1 })?;
            *slot = byte;
            len += 1;
        }
        Ok(Self::with_format(id, extended, data.get(..len).unwrap_or(&[]))?)
    }
}

fn hex_val(b: u8) -> Option<u8> {
    char::from(b).to_digit(16).and_then(|d| u8::try_from(d).ok())
}
