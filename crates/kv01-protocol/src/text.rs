//! Text data (D0/D2 payloads) as Latin-1: every byte is one character (U+0000..=U+00FF) and
//! back, so any byte sequence survives a decode/encode round trip and JSON shows ASCII as is.
//! Writing goes through [`core::fmt::Write`] adaptors so encoding needs no allocation.

use std::fmt;

use crate::codec::Writer;
use crate::EncodeError;

/// The Latin-1 string of `bytes` (one `char` per byte).
#[must_use]
pub fn from_latin1(bytes: &[u8]) -> String {
    bytes.iter().map(|&b| char::from(b)).collect()
}

/// The Latin-1 bytes of `text`, or the first character that does not fit in a byte together
/// with its index in characters.
pub fn to_latin1(text: &str) -> Result<Vec<u8>, (usize, char)> {
    text.chars().enumerate().map(|(i, c)| u8::try_from(c).map_err(|_| (i, c))).collect()
}

/// Counts the characters written through [`fmt::Write`] (= bytes once encoded).
#[derive(Default)]
pub(crate) struct CharCounter(pub(crate) usize);

impl fmt::Write for CharCounter {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        self.0 += s.chars().count();
        Ok(())
    }
}

/// Writes characters as Latin-1 bytes into a [`Writer`], keeping the first error.
pub(crate) struct Latin1Sink<'w, 'a> {
    pub(crate) out: &'w mut Writer<'a>,
    pub(crate) error: Option<EncodeError>,
}

impl fmt::Write for Latin1Sink<'_, '_> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for c in s.chars() {
            let offset = self.out.position();
            let result = u8::try_from(c)
                .map_err(|_| EncodeError::NotLatin1 { ch: c, offset })
                .and_then(|b| self.out.put(b));
            if let Err(e) = result {
                self.error = Some(e);
                return Err(fmt::Error);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_all_bytes() {
        let bytes: Vec<u8> = (0..=255).collect();
        let s = from_latin1(&bytes);
        assert_eq!(to_latin1(&s), Ok(bytes));
        assert_eq!(to_latin1("a\u{2013}"), Err((1, '\u{2013}')));
    }
}
