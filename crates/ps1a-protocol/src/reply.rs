//! The status reply, module -> host: `ADR N=5 LBS HBS BP1 BP2 BP3 CSUM`.

use crate::checksum::sum8;
use crate::error::{DecodeError, EncodeError};
use crate::status::{HighStatus, LowStatus};
use crate::values::U24;
use crate::REPLY_LEN;
use serde::{Deserialize, Serialize};

/// The status reply every command is answered with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "ReplyJson", into = "ReplyJson")]
pub struct StatusReply {
    /// Address of the answering module.
    pub addr: u8,
    /// LBS.
    pub low: LowStatus,
    /// HBS.
    pub high: HighStatus,
    /// Actual position, 24 bit.
    pub position: U24,
}

impl StatusReply {
    /// Writes the 8 reply bytes into `buf`. Allocation-free.
    pub fn encode_into(&self, buf: &mut [u8]) -> Result<usize, EncodeError> {
        let have = buf.len();
        let out: &mut [u8; REPLY_LEN] = buf
            .get_mut(..REPLY_LEN)
            .and_then(|s| s.try_into().ok())
            .ok_or(EncodeError::BufferTooSmall { needed: REPLY_LEN, have })?;
        *out = self.to_bytes();
        Ok(REPLY_LEN)
    }

    /// The 8 reply bytes.
    pub fn to_bytes(&self) -> [u8; REPLY_LEN] {
        let [p1, p2, p3] = self.position.to_le();
        let mut b = [self.addr, 5, self.low.0, self.high.0, p1, p2, p3, 0];
        b[7] = sum8(&b[..7]);
        b
    }

    /// Decodes exactly one reply occupying all of `bytes`.
    pub fn decode(bytes: &[u8]) -> Result<StatusReply, DecodeError> {
        if bytes.len() > REPLY_LEN {
            return Err(DecodeError::TooLong { declared: 5, expected: REPLY_LEN, got: bytes.len() });
        }
        Self::decode_prefix(bytes)
    }

    /// Decodes the reply at the start of `bytes` (extra bytes are ignored).
    pub fn decode_prefix(bytes: &[u8]) -> Result<StatusReply, DecodeError> {
        if let Some(&n) = bytes.get(1) {
            if n != 5 {
                return Err(DecodeError::WrongReplyLength(n));
            }
        }
        let b: [u8; REPLY_LEN] = bytes
            .get(..REPLY_LEN)
            .and_then(|s| s.try_into().ok())
            .ok_or(DecodeError::TooShort { needed: REPLY_LEN, got: bytes.len() })?;
        let [addr, _n, lbs, hbs, p1, p2, p3, received] = b;
        let expected = sum8(&b[..7]);
        if expected != received {
            return Err(DecodeError::Checksum { expected, received });
        }
        Ok(StatusReply {
            addr,
            low: LowStatus(lbs),
            high: HighStatus(hbs),
            position: U24::from_le([p1, p2, p3]),
        })
    }
}

/// JSON form: raw bytes plus the named flags (the names are output only; on input they
/// are checked against the raw bytes when present).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ReplyJson {
    addr: u8,
    lbs: u8,
    hbs: u8,
    position: U24,
    #[serde(default)]
    lbs_flags: Option<Vec<String>>,
    #[serde(default)]
    hbs_flags: Option<Vec<String>>,
    #[serde(default)]
    checksum: Option<u8>,
}

impl From<StatusReply> for ReplyJson {
    fn from(r: StatusReply) -> Self {
        ReplyJson {
            addr: r.addr,
            lbs: r.low.0,
            hbs: r.high.0,
            position: r.position,
            lbs_flags: Some(r.low.names().into_iter().map(str::to_string).collect()),
            hbs_flags: Some(r.high.names().into_iter().map(str::to_string).collect()),
            checksum: r.to_bytes().last().copied(),
        }
    }
}

impl TryFrom<ReplyJson> for StatusReply {
    type Error = String;
    fn try_from(j: ReplyJson) -> Result<Self, Self::Error> {
        let r = StatusReply {
            addr: j.addr,
            low: LowStatus(j.lbs),
            high: HighStatus(j.hbs),
            position: j.position,
        };
        if let Some(flags) = j.lbs_flags {
            let names: Vec<String> = r.low.names().into_iter().map(str::to_string).collect();
            if flags != names {
                return Err(format!("lbs_flags {flags:?} do not match lbs = 0x{:02X} ({names:?})", j.lbs));
            }
        }
        if let Some(flags) = j.hbs_flags {
            let names: Vec<String> = r.high.names().into_iter().map(str::to_string).collect();
            if flags != names {
                return Err(format!("hbs_flags {flags:?} do not match hbs = 0x{:02X} ({names:?})", j.hbs));
            }
        }
        if let (Some(c), Some(&actual)) = (j.checksum, r.to_bytes().last()) {
            if c != actual {
                return Err(format!("checksum {c} does not match the computed checksum {actual}"));
            }
        }
        Ok(r)
    }
}
