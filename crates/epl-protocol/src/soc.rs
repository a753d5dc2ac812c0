//! Start of Cycle (`specs/powerlink.md` §3.2): MN -> all, src 240, dst 255, MAC
//! 01:11:1E:00:00:01, 36 bytes without padding.

use serde::{Deserialize, Serialize};

use crate::error::DecodeError;
use crate::flags::Flags;
use crate::wire::{is_zero, Rd};

/// Length of a SoC counted from the message type byte (frame bytes 14..36).
pub const SOC_LEN: usize = 22;

/// POWERLINK NetTime: seconds and nanoseconds (two little-endian u32).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, PartialOrd, Ord, Serialize, Deserialize)]
pub struct NetTime {
    /// Seconds.
    pub seconds: u32,
    /// Nanoseconds.
    pub nanoseconds: u32,
}

impl NetTime {
    pub(crate) fn decode(rd: &Rd<'_>, off: usize) -> Result<Self, DecodeError> {
        Ok(Self { seconds: rd.u32(off)?, nanoseconds: rd.u32(off + 4)? })
    }

    pub(crate) fn encode_into(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.seconds.to_le_bytes());
        out.extend_from_slice(&self.nanoseconds.to_le_bytes());
    }
}

/// A Start of Cycle message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Soc {
    /// Flags: MC 0x80, PS 0x40, AN 0x08 (shown as EC by [`Flags`]).
    pub flags: Flags,
    /// NetTime (wall clock in openPOWERLINK).
    pub net_time: NetTime,
    /// RelativeTime in microseconds (grows by the cycle time each cycle).
    pub relative_time: u64,
    /// Frame byte 17 (reserved).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub reserved1: u8,
    /// Frame byte 19 (reserved).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub reserved2: u8,
}

impl Soc {
    pub(crate) fn decode(rd: &Rd<'_>) -> Result<(Self, usize), DecodeError> {
        rd.need(SOC_LEN)?;
        let soc = Soc {
            reserved1: rd.u8(3)?,
            flags: Flags::from_bits_retain(rd.u8(4)?),
            reserved2: rd.u8(5)?,
            net_time: NetTime::decode(rd, 6)?,
            relative_time: rd.u64(14)?,
        };
        Ok((soc, SOC_LEN))
    }

    pub(crate) fn encode_into(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&[self.reserved1, self.flags.bits(), self.reserved2]);
        self.net_time.encode_into(out);
        out.extend_from_slice(&self.relative_time.to_le_bytes());
    }
}
