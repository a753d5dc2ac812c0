//! The NFv2 frame: `'#', n, ~n, address, commands..., crc`.
//!
//! | byte | value |
//! |---|---|
//! | 0 | `'#'` (0x23) start byte |
//! | 1 | `n`: index of the last byte (the CRC), so the frame is `n + 1` bytes |
//! | 2 | `!n` (bitwise NOT): start detection is `'#'` plus this pair, not line silence |
//! | 3 | slave address |
//! | 4.. | `code, k, k parameter bytes`, repeated |
//! | n | CRC-8 over bytes 3..n-1 (see [`crate::crc`]) |
//!
//! A frame is at most 256 bytes (`n <= 255`); receivers accept `n > 3` only, so the
//! smallest frame is `'#' 4 !4 address crc` with no command.

use serde::{Deserialize, Serialize};

use crate::code::CommandCode;
use crate::command::Command;
use crate::crc::crc8;
use crate::error::{DecodeError, EncodeError};
use crate::profile::DeviceProfile;
use crate::revision::Revision;

/// The start byte `'#'`.
pub const START: u8 = b'#';
/// Largest frame, in bytes (`n` is one byte).
pub const MAX_FRAME_LEN: usize = 256;
/// Smallest frame: `'#' n ~n address crc`.
pub const MIN_FRAME_LEN: usize = 5;
/// Bytes before the first command: `'#' n ~n address`.
pub const HEADER_LEN: usize = 4;
/// Framing overhead of a frame: header plus CRC byte.
pub const OVERHEAD: usize = HEADER_LEN + 1;

/// A decoded (or to-be-encoded) NFv2 frame.
///
/// JSON: `{"address":1,"commands":[{"kind":"values","code":"set_drives_position","values":[-5000]},{"kind":"query","code":"read_drives_position"}]}`.
/// The CRC and length bytes are not part of it: they are computed by the encoder and
/// checked by the decoder.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Frame {
    /// Byte 3: the slave the frame is for (master to slave) or from (slave's answer).
    /// See [`AddressPlan`](crate::AddressPlan) for what address 0 means.
    pub address: u8,
    /// The commands, queries and answers, in wire order.
    pub commands: Vec<Command>,
}

impl Frame {
    /// An empty frame for `address`.
    #[must_use]
    pub fn new(address: u8) -> Self {
        Frame { address, commands: Vec::new() }
    }

    /// Decodes exactly one frame (all of `bytes`).
    ///
    /// # Errors
    /// Any [`DecodeError`]: framing, CRC, or a command the revision cannot split.
    pub fn decode(bytes: &[u8], rev: Revision) -> Result<Frame, DecodeError> {
        RawFrame::parse(bytes)?.decode(rev)
    }

    /// Encoded size in bytes (header, commands, CRC), validating every command.
    ///
    /// # Errors
    /// As [`Frame::encode_into`], except [`EncodeError::BufferTooSmall`].
    pub fn encoded_len(&self, rev: Revision) -> Result<usize, EncodeError> {
        let mut len = OVERHEAD;
        for command in &self.commands {
            len = len.saturating_add(command.encoded_len(rev)?);
        }
        if len > MAX_FRAME_LEN {
            return Err(EncodeError::FrameTooLong { len });
        }
        Ok(len)
    }

    /// Encodes into `buf` without allocating; returns the frame length.
    ///
    /// # Errors
    /// [`EncodeError`]: a value out of range, a code without width in `rev`, a frame over
    /// 256 bytes, or `buf` too small.
    pub fn encode_into(&self, buf: &mut [u8], rev: Revision) -> Result<usize, EncodeError> {
        let len = self.encoded_len(rev)?;
        let available = buf.len();
        let out = buf.get_mut(..len).ok_or(EncodeError::BufferTooSmall { needed: len, available })?;
        let n = u8::try_from(len - 1).map_err(|_| EncodeError::FrameTooLong { len })?;
        let (header, rest) = out
            .split_first_chunk_mut::<HEADER_LEN>()
            .ok_or(EncodeError::BufferTooSmall { needed: len, available })?;
        *header = [START, n, !n, self.address];
        let mut pos = 0;
        for command in &self.commands {
            pos += command.write(rest.get_mut(pos..).unwrap_or_default(), rev)?;
        }
        let crc = crc8(out.get(3..len - 1).unwrap_or_default());
        if let Some(last) = out.last_mut() {
            *last = crc;
        }
        Ok(len)
    }

    /// Encodes into a new vector.
    ///
    /// # Errors
    /// As [`Frame::encode_into`].
    pub fn encode(&self, rev: Revision) -> Result<Vec<u8>, EncodeError> {
        let mut buf = vec![0; self.encoded_len(rev)?];
        let len = self.encode_into(&mut buf, rev)?;
        buf.truncate(len);
        Ok(buf)
    }

    /// Encoded size of the answer the device described by `profile` sends to this frame,
    /// `None` if it sends none (see [`DeviceProfile::answer_len`]).
    #[must_use]
    pub fn expected_answer_len(&self, rev: Revision, profile: &DeviceProfile) -> Option<usize> {
        profile.answer_len(self, rev)
    }

    /// The codes queried by this frame (commands with `k = 0`), in order.
    pub fn queries(&self) -> impl Iterator<Item = CommandCode> + '_ {
        self.commands.iter().filter(|c| c.is_query()).map(Command::code)
    }

    /// The first command with `code`, if any.
    #[must_use]
    pub fn command(&self, code: CommandCode) -> Option<&Command> {
        self.commands.iter().find(|c| c.code() == code)
    }

    /// The first integer values of `code` in this frame (e.g. an answer's
    /// `read_drives_position`), if any.
    #[must_use]
    pub fn int_values(&self, code: CommandCode) -> Option<&[i64]> {
        self.commands.iter().filter(|c| c.code() == code).find_map(Command::int_values)
    }
}

/// A frame whose framing and CRC have been checked, before its commands are split
/// (which needs the [`Revision`] of the device at [`RawFrame::address`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RawFrame<'a> {
    /// Byte 3.
    pub address: u8,
    /// Bytes 4..n-1: the commands.
    pub body: &'a [u8],
}

impl<'a> RawFrame<'a> {
    /// Checks start byte, `n` / `!n`, `n > 3`, exact length and CRC of one frame.
    ///
    /// # Errors
    /// [`DecodeError::BadStart`], [`DecodeError::Length`], [`DecodeError::TooShort`],
    /// [`DecodeError::Truncated`], [`DecodeError::TrailingBytes`] or [`DecodeError::Crc`].
    pub fn parse(bytes: &'a [u8]) -> Result<Self, DecodeError> {
        let received = bytes.len();
        let Some((&start, rest)) = bytes.split_first() else {
            return Err(DecodeError::Truncated { expected: MIN_FRAME_LEN, received });
        };
        if start != START {
            return Err(DecodeError::BadStart { found: start });
        }
        let Some(&[n, complement]) = rest.first_chunk::<2>() else {
            return Err(DecodeError::Truncated { expected: MIN_FRAME_LEN, received });
        };
        if complement != !n {
            return Err(DecodeError::Length { n, complement });
        }
        if n <= 3 {
            return Err(DecodeError::TooShort { n });
        }
        let expected = usize::from(n) + 1;
        if received < expected {
            return Err(DecodeError::Truncated { expected, received });
        }
        if received > expected {
            return Err(DecodeError::TrailingBytes { expected, received });
        }
        // n >= 4 and len == n + 1, so bytes 3..n and byte n exist.
        let covered = bytes.get(3..usize::from(n)).unwrap_or_default();
        let crc_byte = bytes.last().copied().unwrap_or_default();
        let computed = crc8(covered);
        if computed != crc_byte {
            return Err(DecodeError::Crc { expected: computed, received: crc_byte });
        }
        let Some((&address, body)) = covered.split_first() else {
            return Err(DecodeError::Truncated { expected, received });
        };
        Ok(RawFrame { address, body })
    }

    /// Splits the body into commands using `rev`'s width table.
    ///
    /// # Errors
    /// [`DecodeError::MissingLength`], [`DecodeError::CommandOverrun`] or
    /// [`DecodeError::TruncatedValue`].
    pub fn decode(self, rev: Revision) -> Result<Frame, DecodeError> {
        let mut commands = Vec::new();
        let mut rest = self.body;
        let mut offset = HEADER_LEN;
        while let Some((&code, tail)) = rest.split_first() {
            let Some((&len, tail)) = tail.split_first() else {
                return Err(DecodeError::MissingLength { offset, code });
            };
            let Some((params, tail)) = tail.split_at_checked(usize::from(len)) else {
                let available = tail.len();
                return Err(DecodeError::CommandOverrun { offset, code, len, available });
            };
            commands.push(Command::decode(code, params, rev)?);
            offset += 2 + params.len();
            rest = tail;
        }
        Ok(Frame { address: self.address, commands })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smallest_frame_has_no_command() {
        // Vector from the independent Python script (see tests/vectors.rs): '#', n = 4,
        // !4 = 0xFB, address 5, CRC-8([0x05]) = 0x08.
        let bytes = [0x23, 0x04, 0xFB, 0x05, 0x08];
        assert_eq!(Frame::decode(&bytes, Revision::LATEST), Ok(Frame::new(5)));
        assert_eq!(Frame::new(5).encode(Revision::LATEST), Ok(bytes.to_vec()));
    }

    #[test]
    fn framing_errors() {
        let rev = Revision::LATEST;
        assert_eq!(Frame::decode(&[], rev), Err(DecodeError::Truncated { expected: 5, received: 0 }));
        assert_eq!(Frame::decode(&[0x24, 4, 0xFB], rev), Err(DecodeError::BadStart { found: 0x24 }));
        assert_eq!(
            Frame::decode(&[0x23, 4, 0xFA, 5, 8], rev),
            Err(DecodeError::Length { n: 4, complement: 0xFA })
        );
        assert_eq!(Frame::decode(&[0x23, 3, 0xFC, 5], rev), Err(DecodeError::TooShort { n: 3 }));
        assert_eq!(
            Frame::decode(&[0x23, 4, 0xFB, 5], rev),
            Err(DecodeError::Truncated { expected: 5, received: 4 })
        );
        assert_eq!(
            Frame::decode(&[0x23, 4, 0xFB, 5, 8, 0], rev),
            Err(DecodeError::TrailingBytes { expected: 5, received: 6 })
        );
        assert_eq!(
            Frame::decode(&[0x23, 4, 0xFB, 5, 9], rev),
            Err(DecodeError::Crc { expected: 8, received: 9 })
        );
    }

    #[test]
    fn encode_into_reports_small_buffers() {
        let mut buf = [0u8; 4];
        assert_eq!(
            Frame::new(1).encode_into(&mut buf, Revision::LATEST),
            Err(EncodeError::BufferTooSmall { needed: 5, available: 4 })
        );
    }

    #[test]
    fn too_long_frame() {
        let mut frame = Frame::new(1);
        for _ in 0..26 {
            frame.commands.push(Command::values(CommandCode::SetDrivesPosition, [0, 0]));
        }
        // 5 + 26 * 10 = 265 bytes.
        assert_eq!(frame.encoded_len(Revision::LATEST), Err(EncodeError::FrameTooLong { len: 265 }));
    }
}
