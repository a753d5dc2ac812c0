//! Bounds-checked little-endian reads and writes shared by the message modules.

use crate::error::{DecodeError, EncodeError};

/// A view of the EPL part of a frame (from the message type byte on). `base` is the frame
/// offset of that byte, so errors report frame lengths.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Rd<'a> {
    pub(crate) buf: &'a [u8],
    pub(crate) base: usize,
    pub(crate) what: &'static str,
}

impl<'a> Rd<'a> {
    pub(crate) fn new(buf: &'a [u8], base: usize, what: &'static str) -> Self {
        Self { buf, base, what }
    }

    /// Fails unless `len` bytes (counted from the message type byte) are present.
    pub(crate) fn need(&self, len: usize) -> Result<(), DecodeError> {
        if self.buf.len() < len {
            Err(DecodeError::TooShort {
                what: self.what,
                needed: self.base + len,
                got: self.base + self.buf.len(),
            })
        } else {
            Ok(())
        }
    }

    pub(crate) fn bytes(&self, off: usize, len: usize) -> Result<&'a [u8], DecodeError> {
        self.need(off + len)?;
        self.buf.get(off..off + len).ok_or(DecodeError::TooShort {
            what: self.what,
            needed: self.base + off + len,
            got: self.base + self.buf.len(),
        })
    }

    pub(crate) fn array<const N: usize>(&self, off: usize) -> Result<[u8; N], DecodeError> {
        let s = self.bytes(off, N)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }

    pub(crate) fn u8(&self, off: usize) -> Result<u8, DecodeError> {
        Ok(u8::from_le_bytes(self.array::<1>(off)?))
    }

    pub(crate) fn u16(&self, off: usize) -> Result<u16, DecodeError> {
        Ok(u16::from_le_bytes(self.array::<2>(off)?))
    }

    pub(crate) fn u32(&self, off: usize) -> Result<u32, DecodeError> {
        Ok(u32::from_le_bytes(self.array::<4>(off)?))
    }

    pub(crate) fn u64(&self, off: usize) -> Result<u64, DecodeError> {
        Ok(u64::from_le_bytes(self.array::<8>(off)?))
    }

    /// Bytes from `off` to the end (empty when `off` is past the end).
    pub(crate) fn rest(&self, off: usize) -> &'a [u8] {
        self.buf.get(off..).unwrap_or(&[])
    }
}

/// `s` without its trailing zero bytes.
pub(crate) fn trim_zeros(s: &[u8]) -> &[u8] {
    let end = s.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
    s.get(..end).unwrap_or(s)
}

/// Checks that `value` fits in `max`.
pub(crate) fn check_max(field: &'static str, value: u64, max: u64) -> Result<(), EncodeError> {
    if value > max {
        Err(EncodeError::FieldOutOfRange { field, value, max })
    } else {
        Ok(())
    }
}

/// Appends `data` padded with zeros to `room` bytes after checking it fits.
pub(crate) fn put_padded(
    out: &mut Vec<u8>,
    field: &'static str,
    data: &[u8],
    room: usize,
) -> Result<(), EncodeError> {
    if data.len() > room {
        return Err(EncodeError::TooLong { field, got: data.len(), max: room });
    }
    out.extend_from_slice(data);
    out.resize(out.len() + room - data.len(), 0);
    Ok(())
}

/// serde helper: skip zero numbers.
pub(crate) fn is_zero<T: Default + PartialEq>(v: &T) -> bool {
    *v == T::default()
}
