//! The M-function bit array (specs/cnc.md, "M-functions").

use std::fmt;

/// Number of M-functions (bits) in the array.
pub const M_FUNCTION_COUNT: usize = 1024;

const WORDS: usize = M_FUNCTION_COUNT / 64;

/// Whether an M-function pauses the program.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MKind {
    /// The program pauses until the PLC clears the bit (the acknowledgement).
    Synchronous,
    /// The program goes on; the same M may be called again only after it was cleared.
    Asynchronous,
}

impl fmt::Display for MKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Synchronous => "synchronous",
            Self::Asynchronous => "asynchronous",
        })
    }
}

/// A misuse of the M-function array.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum MFunctionError {
    /// The number is not in 0..1024.
    #[error("M{number} is out of range (0..{M_FUNCTION_COUNT})")]
    OutOfRange {
        /// The number asked for.
        number: u16,
    },
    /// The program called an M whose bit the PLC has not cleared yet.
    #[error("M{number} ({kind}) called again before the PLC cleared it")]
    StillSet {
        /// The M-function number.
        number: u16,
        /// Its kind.
        kind: MKind,
    },
}

/// The 1024-bit M-function array with the kind (synchronous or asynchronous) of each bit.
///
/// Every M is asynchronous until [`MFunctions::set_kind`] says otherwise.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MFunctions {
    bits: [u64; WORDS],
    sync: [u64; WORDS],
}

impl Default for MFunctions {
    fn default() -> Self {
        Self::new()
    }
}

fn locate(number: u16) -> Result<(usize, u64), MFunctionError> {
    let n = usize::from(number);
    if n >= M_FUNCTION_COUNT {
        return Err(MFunctionError::OutOfRange { number });
    }
    Ok((n / 64, 1u64 << (n % 64)))
}

impl MFunctions {
    /// All bits clear, every M asynchronous.
    pub fn new() -> Self {
        Self { bits: [0; WORDS], sync: [0; WORDS] }
    }

    /// Declares the kind of M-function `number` (configuration, done once).
    pub fn set_kind(&mut self, number: u16, kind: MKind) -> Result<(), MFunctionError> {
        let (word, mask) = locate(number)?;
        let w = self.sync.get_mut(word).ok_or(MFunctionError::OutOfRange { number })?;
        match kind {
            MKind::Synchronous => *w |= mask,
            MKind::Asynchronous => *w &= !mask,
        }
        Ok(())
    }

    /// The kind of M-function `number`.
    pub fn kind(&self, number: u16) -> Result<MKind, MFunctionError> {
        let (word, mask) = locate(number)?;
        let w = self.sync.get(word).ok_or(MFunctionError::OutOfRange { number })?;
        Ok(if w & mask != 0 { MKind::Synchronous } else { MKind::Asynchronous })
    }

    /// Program side: `M<number>` sets the bit. Returns the kind, so the caller knows
    /// whether to pause (synchronous) or go on. Calling an M whose bit is still set is
    /// refused with [`MFunctionError::StillSet`] (for a synchronous M this means the
    /// caller did not wait for the acknowledgement).
    pub fn set(&mut self, number: u16) -> Result<MKind, MFunctionError> {
        let kind = self.kind(number)?;
        let (word, mask) = locate(number)?;
        let w = self.bits.get_mut(word).ok_or(MFunctionError::OutOfRange { number })?;
        if *w & mask != 0 {
            return Err(MFunctionError::StillSet { number, kind });
        }
        *w |= mask;
        Ok(kind)
    }

    /// Whether bit `number` is set (false for a number out of range).
    pub fn is_set(&self, number: u16) -> bool {
        locate(number)
            .ok()
            .and_then(|(word, mask)| self.bits.get(word).map(|w| w & mask != 0))
            .unwrap_or(false)
    }

    /// PLC side: clears bit `number` (the acknowledgement). Returns whether it was set.
    pub fn clear(&mut self, number: u16) -> Result<bool, MFunctionError> {
        let (word, mask) = locate(number)?;
        let w = self.bits.get_mut(word).ok_or(MFunctionError::OutOfRange { number })?;
        let was = *w & mask != 0;
        *w &= !mask;
        Ok(was)
    }

    /// The numbers of every set bit, ascending.
    pub fn pending(&self) -> impl Iterator<Item = u16> + '_ {
        (0..M_FUNCTION_COUNT as u16).filter(|&n| self.is_set(n))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn set_clear_and_pending() {
        let mut m = MFunctions::new();
        assert_eq!(m.set(40).unwrap(), MKind::Asynchronous);
        assert!(m.is_set(40));
        assert!(!m.is_set(41));
        m.set(1023).unwrap();
        m.set(0).unwrap();
        assert_eq!(m.pending().collect::<Vec<_>>(), vec![0, 40, 1023]);
        assert!(m.clear(40).unwrap());
        assert!(!m.clear(40).unwrap());
        assert!(!m.is_set(40));
        assert_eq!(m.pending().collect::<Vec<_>>(), vec![0, 1023]);
    }

    #[test]
    fn async_m_rejected_until_cleared() {
        // specs/cnc.md: "the same M may be called again only after it was cleared"
        let mut m = MFunctions::new();
        m.set(41).unwrap();
        assert_eq!(m.set(41), Err(MFunctionError::StillSet { number: 41, kind: MKind::Asynchronous }));
        m.clear(41).unwrap();
        assert_eq!(m.set(41), Ok(MKind::Asynchronous));
    }

    #[test]
    fn kinds_and_range() {
        let mut m = MFunctions::new();
        m.set_kind(60, MKind::Synchronous).unwrap();
        assert_eq!(m.kind(60).unwrap(), MKind::Synchronous);
        assert_eq!(m.kind(61).unwrap(), MKind::Asynchronous);
        assert_eq!(m.set(60).unwrap(), MKind::Synchronous);
        assert_eq!(m.set(60), Err(MFunctionError::StillSet { number: 60, kind: MKind::Synchronous }));
        m.set_kind(60, MKind::Asynchronous).unwrap();
        assert_eq!(m.kind(60).unwrap(), MKind::Asynchronous);
        assert_eq!(m.set(1024), Err(MFunctionError::OutOfRange { number: 1024 }));
        assert_eq!(m.clear(5000), Err(MFunctionError::OutOfRange { number: 5000 }));
        assert!(!m.is_set(1024));
        // Bits 63 and 64 sit in different words.
        m.set(63).unwrap();
        assert!(!m.is_set(64));
        assert!(m.is_set(63));
    }
}
