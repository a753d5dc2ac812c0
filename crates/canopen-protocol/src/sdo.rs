//! SDO frames (CiA 301 §7.2.4.3): the command byte's specifier in bits 7..5, index
//! (bytes 1–2, LE), sub-index (byte 3), data / size / abort code (bytes 4–7).
//! Block transfers are not decoded (they stay raw frames).

use serde::{Deserialize, Serialize};

use crate::abort::SdoAbortCode;
use crate::error::{check_len, EncodeError};

/// Data part of an initiate download request / initiate upload response (bits n, e, s).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "transfer", rename_all = "snake_case")]
pub enum SdoPayload {
    /// Expedited with size indicated (e = 1, s = 1): 1–4 data bytes.
    Expedited {
        /// The data bytes (1..=4), little-endian value.
        data: Vec<u8>,
    },
    /// Expedited without size indication (e = 1, s = 0): all 4 bytes.
    ExpeditedUnsized {
        /// Bytes 4–7.
        data: [u8; 4],
    },
    /// Segmented (e = 0), with the total size in bytes 4–7 when s = 1.
    Segmented {
        /// Total size in bytes, if indicated.
        size: Option<u32>,
    },
}

impl SdoPayload {
    fn decode(cmd: u8, d: [u8; 4]) -> Self {
        let n = usize::from((cmd >> 2) & 0x3);
        match (cmd & 0x2 != 0, cmd & 0x1 != 0) {
            (true, true) => Self::Expedited { data: d.get(..4 - n).unwrap_or(&[]).to_vec() },
            (true, false) => Self::ExpeditedUnsized { data: d },
            (false, true) => Self::Segmented { size: Some(u32::from_le_bytes(d)) },
            (false, false) => Self::Segmented { size: None },
        }
    }

    /// Returns the low command bits (n, e, s) and bytes 4–7.
    fn encode(&self) -> Result<(u8, [u8; 4]), EncodeError> {
        Ok(match self {
            Self::Expedited { data } => {
                check_len(data.len(), 1, 4)?;
                let mut d = [0u8; 4];
                d.get_mut(..data.len()).unwrap_or(&mut []).copy_from_slice(data);
                (((4 - data.len() as u8) << 2) | 0x3, d)
            }
            Self::ExpeditedUnsized { data } => (0x2, *data),
            Self::Segmented { size: Some(size) } => (0x1, size.to_le_bytes()),
            Self::Segmented { size: None } => (0x0, [0; 4]),
        })
    }

    /// The expedited value as a little-endian unsigned integer, if expedited.
    pub fn value(&self) -> Option<u32> {
        let bytes: &[u8] = match self {
            Self::Expedited { data } => data,
            Self::ExpeditedUnsized { data } => data,
            Self::Segmented { .. } => return None,
        };
        Some(bytes.iter().rev().fold(0u32, |acc, &b| (acc << 8) | u32::from(b)))
    }
}

/// Client → server SDO frame (COB-ID 0x600 + node).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "command", rename_all = "snake_case")]
pub enum SdoRequest {
    /// ccs 1: initiate download (write).
    InitiateDownload {
        /// Object index.
        index: u16,
        /// Sub-index.
        subindex: u8,
        /// Expedited data or segmented size.
        payload: SdoPayload,
    },
    /// ccs 0: download segment.
    DownloadSegment {
        /// Toggle bit t.
        toggle: bool,
        /// c: last segment.
        last: bool,
        /// 0..=7 data bytes.
        data: Vec<u8>,
    },
    /// ccs 2: initiate upload (read).
    InitiateUpload {
        /// Object index.
        index: u16,
        /// Sub-index.
        subindex: u8,
    },
    /// ccs 3: upload segment request.
    UploadSegment {
        /// Toggle bit t.
        toggle: bool,
    },
    /// ccs 4: abort transfer.
    Abort {
        /// Object index.
        index: u16,
        /// Sub-index.
        subindex: u8,
        /// Abort code.
        code: SdoAbortCode,
    },
}

/// Server → client SDO frame (COB-ID 0x580 + node).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "command", rename_all = "snake_case")]
pub enum SdoResponse {
    /// scs 2: initiate upload response (read reply).
    InitiateUpload {
        /// Object index.
        index: u16,
        /// Sub-index.
        subindex: u8,
        /// Expedited data or segmented size.
        payload: SdoPayload,
    },
    /// scs 0: upload segment response.
    UploadSegment {
        /// Toggle bit t.
        toggle: bool,
        /// c: last segment.
        last: bool,
        /// 0..=7 data bytes.
        data: Vec<u8>,
    },
    /// scs 3: initiate download response (write acknowledged).
    InitiateDownload {
        /// Object index.
        index: u16,
        /// Sub-index.
        subindex: u8,
    },
    /// scs 1: download segment response.
    DownloadSegment {
        /// Toggle bit t.
        toggle: bool,
    },
    /// cs 4: abort transfer.
    Abort {
        /// Object index.
        index: u16,
        /// Sub-index.
        subindex: u8,
        /// Abort code.
        code: SdoAbortCode,
    },
}

/// Splits an 8-byte SDO frame into command byte, index, sub-index and bytes 4–7.
fn split(d: &[u8]) -> Option<(u8, u16, u8, [u8; 4])> {
    let d: &[u8; 8] = d.try_into().ok()?;
    let [cmd, i0, i1, sub, a, b, c, e] = *d;
    Some((cmd, u16::from_le_bytes([i0, i1]), sub, [a, b, c, e]))
}

fn join(cmd: u8, index: u16, subindex: u8, tail: [u8; 4]) -> [u8; 8] {
    let [i0, i1] = index.to_le_bytes();
    let [a, b, c, d] = tail;
    [cmd, i0, i1, subindex, a, b, c, d]
}

/// Decodes a segment body: t = bit 4, n = bits 3..1, c = bit 0; data in bytes 1..8-n.
fn segment(d: &[u8]) -> Option<(bool, bool, Vec<u8>)> {
    let (&cmd, rest) = d.split_first()?;
    let n = usize::from((cmd >> 1) & 0x7);
    let data = rest.get(..7usize.checked_sub(n)?)?.to_vec();
    Some((cmd & 0x10 != 0, cmd & 0x01 != 0, data))
}

fn encode_segment(base: u8, toggle: bool, last: bool, data: &[u8]) -> Result<[u8; 8], EncodeError> {
    check_len(data.len(), 0, 7)?;
    let mut out = [0u8; 8];
    let n = 7 - data.len() as u8;
    out[0] = base | (u8::from(toggle) << 4) | (n << 1) | u8::from(last);
    out.get_mut(1..=data.len()).unwrap_or(&mut []).copy_from_slice(data);
    Ok(out)
}

fn toggle_byte(base: u8, toggle: bool) -> [u8; 8] {
    [base | (u8::from(toggle) << 4), 0, 0, 0, 0, 0, 0, 0]
}

impl SdoRequest {
    /// Decodes an 8-byte client → server frame body; `None` for block transfers or short frames.
    pub fn decode(d: &[u8]) -> Option<Self> {
        let (cmd, index, subindex, tail) = split(d)?;
        Some(match cmd >> 5 {
            0 => {
                let (toggle, last, data) = segment(d)?;
                Self::DownloadSegment { toggle, last, data }
            }
            1 => Self::InitiateDownload { index, subindex, payload: SdoPayload::decode(cmd, tail) },
            2 => Self::InitiateUpload { index, subindex },
            3 => Self::UploadSegment { toggle: cmd & 0x10 != 0 },
            4 => Self::Abort { index, subindex, code: SdoAbortCode::from_raw(u32::from_le_bytes(tail)) },
            _ => return None,
        })
    }

    /// Encodes the 8-byte frame body.
    pub fn encode(&self) -> Result<[u8; 8], EncodeError> {
        Ok(match self {
            Self::InitiateDownload { index, subindex, payload } => {
                let (bits, tail) = payload.encode()?;
                join(0x20 | bits, *index, *subindex, tail)
            }
            Self::DownloadSegment { toggle, last, data } => encode_segment(0x00, *toggle, *last, data)?,
            Self::InitiateUpload { index, subindex } => join(0x40, *index, *subindex, [0; 4]),
            Self::UploadSegment { toggle } => toggle_byte(0x60, *toggle),
            Self::Abort { index, subindex, code } => join(0x80, *index, *subindex, code.raw().to_le_bytes()),
        })
    }
}

impl SdoResponse {
    /// Decodes an 8-byte server → client frame body; `None` for block transfers or short frames.
    pub fn decode(d: &[u8]) -> Option<Self> {
        let (cmd, index, subindex, tail) = split(d)?;
        Some(match cmd >> 5 {
            0 => {
                let (toggle, last, data) = segment(d)?;
                Self::UploadSegment { toggle, last, data }
            }
            1 => Self::DownloadSegment { toggle: cmd & 0x10 != 0 },
            2 => Self::InitiateUpload { index, subindex, payload: SdoPayload::decode(cmd, tail) },
            3 => Self::InitiateDownload { index, subindex },
            4 => Self::Abort { index, subindex, code: SdoAbortCode::from_raw(u32::from_le_bytes(tail)) },
            _ => return None,
        })
    }

    /// Encodes the 8-byte frame body.
    pub fn encode(&self) -> Result<[u8; 8], EncodeError> {
        Ok(match self {
            Self::InitiateUpload { index, subindex, payload } => {
                let (bits, tail) = payload.encode()?;
                join(0x40 | bits, *index, *subindex, tail)
            }
            Self::UploadSegment { toggle, last, data } => encode_segment(0x00, *toggle, *last, data)?,
            Self::InitiateDownload { index, subindex } => join(0x60, *index, *subindex, [0; 4]),
            Self::DownloadSegment { toggle } => toggle_byte(0x20, *toggle),
            Self::Abort { index, subindex, code } => join(0x80, *index, *subindex, code.raw().to_le_bytes()),
        })
    }
}
