//! Message framing (`specs/kv01.md`, "Standard message" and "Short message"): checks one
//! candidate message at the start of a byte slice. Shared by the one-shot decoder and the
//! streaming decoders; never scans for 0xF0 to find the end (LENGTH delimits a standard
//! message, a short message has a fixed 4-byte form).

use crate::crc;
use crate::{Address, CrcMismatch, CrcMode, DecodeError, ShortCode, END, MIN_STANDARD_LEN, SHORT_LEN};

/// The outer layer of a message that passed every framing check.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Envelope<'a> {
    /// ADDRESS, LENGTH, COMMAND, DATA, CRC, END.
    Standard { address: Address, code: u8, data: &'a [u8] },
    /// ADDRESS, two capital letters, END.
    Short { address: Address, code: ShortCode },
}

/// A candidate that passed every check.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Framed<'a> {
    /// Bytes the message occupies.
    pub(crate) len: usize,
    pub(crate) envelope: Envelope<'a>,
    /// Set in lenient mode when the CRC is wrong.
    pub(crate) crc_mismatch: Option<CrcMismatch>,
}

/// The result of checking the start of a buffer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Scan<'a> {
    /// Consistent so far; the message needs `expected` bytes (if known yet).
    NeedMore { expected: Option<usize> },
    /// Not a message: the first byte is garbage.
    Invalid(DecodeError),
    /// A complete message.
    Frame(Framed<'a>),
}

/// What a candidate must satisfy.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Rules {
    /// Accept the short form (module -> host).
    pub(crate) short: bool,
    /// Host -> module: 0xF0 anywhere before END is an error.
    pub(crate) request: bool,
    pub(crate) mode: CrcMode,
}

/// Checks the candidate message at the start of `buf`.
pub(crate) fn scan(buf: &[u8], rules: Rules) -> Scan<'_> {
    let Some((&first, rest)) = buf.split_first() else {
        return Scan::NeedMore { expected: None };
    };
    let Some(address) = Address::new(first) else {
        return Scan::Invalid(DecodeError::Address(first));
    };
    if rules.short {
        if let Some(&[a, b, END]) = rest.get(..SHORT_LEN - 1) {
            if let Some(code) = ShortCode::from_bytes([a, b]) {
                return Scan::Frame(Framed {
                    len: SHORT_LEN,
                    envelope: Envelope::Short { address, code },
                    crc_mismatch: None,
                });
            }
        }
    }
    let Some(&len_byte) = rest.first() else {
        return Scan::NeedMore { expected: None };
    };
    let len = usize::from(len_byte);
    if len < MIN_STANDARD_LEN {
        return Scan::Invalid(DecodeError::LengthField(len_byte));
    }
    if rules.request {
        // Checked on what is present already, so a bad candidate is dropped at once.
        if let Some(offset) = buf.iter().take(len - 1).position(|&b| b == END) {
            return Scan::Invalid(DecodeError::EndInBody { offset });
        }
    }
    let Some(frame) = buf.get(..len) else {
        return Scan::NeedMore { expected: Some(len) };
    };
    let Some((&end, before_end)) = frame.split_last() else {
        return Scan::NeedMore { expected: None };
    };
    if end != END {
        return Scan::Invalid(DecodeError::End { received: end });
    }
    let Some((&received, body)) = before_end.split_last() else {
        return Scan::NeedMore { expected: None };
    };
    let expected = crc::compute(body);
    let crc_mismatch = (expected != received).then_some(CrcMismatch { expected, received });
    if crc_mismatch.is_some() && rules.mode == CrcMode::Strict {
        return Scan::Invalid(DecodeError::Crc { expected, received });
    }
    match body {
        [_, _, code, data @ ..] => Scan::Frame(Framed {
            len,
            envelope: Envelope::Standard { address, code: *code, data },
            crc_mismatch,
        }),
        _ => Scan::Invalid(DecodeError::LengthField(len_byte)),
    }
}
