//! A frame builder for a bus scheduler: packs several commands and queries for one slave
//! into one frame, validating each as it is added and tracking the encoded size, so the
//! scheduler knows at once whether another command still fits in 256 bytes and how long
//! the request and its answer take on the wire.

use crate::code::CommandCode;
use crate::command::Command;
use crate::error::EncodeError;
use crate::frame::{Frame, MAX_FRAME_LEN, OVERHEAD};
use crate::profile::DeviceProfile;
use crate::revision::Revision;
use crate::value::Regulator;

/// Builds one frame for one slave.
///
/// ```
/// use motus_nfv2_protocol::{CommandCode as C, FrameBuilder, Revision};
/// let mut b = FrameBuilder::new(1, Revision::LATEST);
/// b.set(C::SetDrivesPosition, &[-5000])?
///     .query(C::ReadDrivesPosition)?
///     .query(C::ReadDrivesStatus)?;
/// assert_eq!(b.encoded_len(), 15);
/// let bytes = b.build().encode(Revision::LATEST)?;
/// assert_eq!(bytes.len(), 15);
/// # Ok::<(), motus_nfv2_protocol::EncodeError>(())
/// ```
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameBuilder {
    frame: Frame,
    rev: Revision,
    len: usize,
}

impl FrameBuilder {
    /// An empty frame for the slave at `address`, encoded with `rev`.
    #[must_use]
    pub fn new(address: u8, rev: Revision) -> Self {
        FrameBuilder { frame: Frame::new(address), rev, len: OVERHEAD }
    }

    /// Adds any command, if it is valid in the revision and still fits in the frame.
    /// On error the builder is unchanged.
    ///
    /// # Errors
    /// The command's [`EncodeError`], or [`EncodeError::FrameTooLong`] if it does not fit.
    pub fn push(&mut self, command: Command) -> Result<&mut Self, EncodeError> {
        let len = self.len + command.encoded_len(self.rev)?;
        if len > MAX_FRAME_LEN {
            return Err(EncodeError::FrameTooLong { len });
        }
        self.len = len;
        self.frame.commands.push(command);
        Ok(self)
    }

    /// Adds integer values for `code` (one per drive / channel).
    ///
    /// # Errors
    /// As [`FrameBuilder::push`].
    pub fn set(&mut self, code: CommandCode, values: &[i64]) -> Result<&mut Self, EncodeError> {
        self.push(Command::values(code, values))
    }

    /// Adds regulator settings for a `Set*Regulator` code.
    ///
    /// # Errors
    /// As [`FrameBuilder::push`].
    pub fn set_regulators(
        &mut self,
        code: CommandCode,
        values: &[Regulator],
    ) -> Result<&mut Self, EncodeError> {
        self.push(Command::regulators(code, values))
    }

    /// Adds a query (`k = 0`) for `code`.
    ///
    /// # Errors
    /// [`EncodeError::FrameTooLong`] if two more bytes do not fit.
    pub fn query(&mut self, code: CommandCode) -> Result<&mut Self, EncodeError> {
        self.push(Command::query(code))
    }

    /// Whether `command` would be accepted by [`FrameBuilder::push`].
    #[must_use]
    pub fn fits(&self, command: &Command) -> bool {
        command.encoded_len(self.rev).is_ok_and(|l| self.len + l <= MAX_FRAME_LEN)
    }

    /// Encoded size of the frame built so far, in bytes.
    #[must_use]
    pub fn encoded_len(&self) -> usize {
        self.len
    }

    /// Bytes still free before the 256-byte limit.
    #[must_use]
    pub fn remaining(&self) -> usize {
        MAX_FRAME_LEN - self.len
    }

    /// True if no command has been added.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.frame.commands.is_empty()
    }

    /// Size of the answer `profile`'s device will send, `None` if it will not answer
    /// (see [`DeviceProfile::answer_len`]).
    #[must_use]
    pub fn expected_answer_len(&self, profile: &DeviceProfile) -> Option<usize> {
        profile.answer_len(&self.frame, self.rev)
    }

    /// The revision frames are built for.
    #[must_use]
    pub fn revision(&self) -> Revision {
        self.rev
    }

    /// The frame built so far.
    #[must_use]
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// Encodes the frame into `buf` without allocating; returns its length.
    ///
    /// # Errors
    /// [`EncodeError::BufferTooSmall`] only: every command was validated when added.
    pub fn encode_into(&self, buf: &mut [u8]) -> Result<usize, EncodeError> {
        self.frame.encode_into(buf, self.rev)
    }

    /// The finished frame.
    #[must_use]
    pub fn build(self) -> Frame {
        self.frame
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use CommandCode as C;

    #[test]
    fn rejects_what_does_not_fit_and_stays_unchanged() {
        let mut b = FrameBuilder::new(1, Revision::LATEST);
        // 5 + 25 * 10 = 255 bytes.
        for _ in 0..25 {
            assert!(b.set(C::SetDrivesPosition, &[1, 2]).is_ok());
        }
        assert_eq!(b.remaining(), 1);
        assert!(!b.fits(&Command::query(C::ReadDrivesStatus)));
        assert_eq!(b.query(C::ReadDrivesStatus).err(), Some(EncodeError::FrameTooLong { len: 257 }));
        assert_eq!(b.encoded_len(), 255);
        assert_eq!(b.frame().commands.len(), 25);
        assert_eq!(b.clone().build().encode(Revision::LATEST).map(|v| v.len()), Ok(255));
    }

    #[test]
    fn rejects_invalid_values_and_stays_unchanged() {
        let mut b = FrameBuilder::new(1, Revision::Rev2012);
        assert!(b.set(C::SetDrivesSpeed, &[40_000]).is_err()); // i16 in 2012
        assert!(b.set(C::SetDrivesSpeed, &[-100]).is_ok());
        assert_eq!(b.encoded_len(), 5 + 4);
    }
}
