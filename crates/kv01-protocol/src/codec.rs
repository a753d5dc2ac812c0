//! Allocation-free message encoding: a bounded [`Writer`] and the [`Payload`] shapes.

use std::fmt::Write as _;

use crate::crc;
use crate::reply::Answer;
use crate::text::{CharCounter, Latin1Sink};
use crate::{EncodeError, END, MAX_FRAME_LEN, MIN_STANDARD_LEN, SHORT_LEN};

/// Writes bytes into a slice, failing instead of overflowing.
pub(crate) struct Writer<'a> {
    buf: &'a mut [u8],
    pos: usize,
}

impl<'a> Writer<'a> {
    pub(crate) fn new(buf: &'a mut [u8]) -> Self {
        Self { buf, pos: 0 }
    }

    pub(crate) fn position(&self) -> usize {
        self.pos
    }

    pub(crate) fn put(&mut self, byte: u8) -> Result<(), EncodeError> {
        let available = self.buf.len();
        let slot = self
            .buf
            .get_mut(self.pos)
            .ok_or(EncodeError::BufferTooSmall { needed: self.pos + 1, available })?;
        *slot = byte;
        self.pos += 1;
        Ok(())
    }

    pub(crate) fn put_all(&mut self, bytes: &[u8]) -> Result<(), EncodeError> {
        bytes.iter().try_for_each(|&b| self.put(b))
    }

    fn written(&self) -> &[u8] {
        self.buf.get(..self.pos).unwrap_or_default()
    }
}

/// The DATA of a message, borrowed from the typed message.
pub(crate) enum Payload<'a> {
    Empty,
    Byte(u8),
    Bytes3([u8; 3]),
    Bytes6([u8; 6]),
    Bytes(&'a [u8]),
    /// Latin-1 text.
    Text(&'a str),
    /// A D0 answer, formatted on the fly.
    Answer(&'a Answer),
}

impl Payload<'_> {
    fn len(&self) -> usize {
        match self {
            Self::Empty => 0,
            Self::Byte(_) => 1,
            Self::Bytes3(_) => 3,
            Self::Bytes6(_) => 6,
            Self::Bytes(b) => b.len(),
            Self::Text(t) => t.chars().count(),
            Self::Answer(a) => {
                let mut c = CharCounter::default();
                // Counting never fails.
                let _ = write!(c, "{a}");
                c.0
            }
        }
    }

    fn write(&self, w: &mut Writer<'_>) -> Result<(), EncodeError> {
        match self {
            Self::Empty => Ok(()),
            Self::Byte(b) => w.put(*b),
            Self::Bytes3(b) => w.put_all(b),
            Self::Bytes6(b) => w.put_all(b),
            Self::Bytes(b) => w.put_all(b),
            Self::Text(t) => write_text(w, format_args!("{t}")),
            Self::Answer(a) => write_text(w, format_args!("{a}")),
        }
    }
}

fn write_text(w: &mut Writer<'_>, args: std::fmt::Arguments<'_>) -> Result<(), EncodeError> {
    let mut sink = Latin1Sink { out: w, error: None };
    match (sink.write_fmt(args), sink.error) {
        (_, Some(e)) => Err(e),
        (Ok(()), None) => Ok(()),
        // A formatting error without a sink error cannot happen with our Display impls.
        (Err(_), None) => Err(EncodeError::BufferTooSmall { needed: MAX_FRAME_LEN, available: 0 }),
    }
}

/// Writes a standard message; `request` enforces "no 0xF0 before END".
pub(crate) fn encode_standard(
    address: u8,
    code: u8,
    payload: &Payload<'_>,
    request: bool,
    buf: &mut [u8],
) -> Result<usize, EncodeError> {
    let total = payload.len() + MIN_STANDARD_LEN;
    let len_byte = u8::try_from(total).map_err(|_| EncodeError::TooLong { len: total })?;
    let available = buf.len();
    let frame = buf.get_mut(..total).ok_or(EncodeError::BufferTooSmall { needed: total, available })?;
    let mut w = Writer::new(frame);
    w.put(address)?;
    w.put(len_byte)?;
    w.put(code)?;
    payload.write(&mut w)?;
    let crc = crc::compute(w.written());
    w.put(crc)?;
    w.put(END)?;
    let frame = w.written();
    if request {
        if let Some(offset) = frame.iter().take(total - 1).position(|&b| b == END) {
            return Err(EncodeError::EndInData { offset });
        }
    } else if let [_, a, b, END, ..] = frame {
        if a.is_ascii_uppercase() && b.is_ascii_uppercase() {
            return Err(EncodeError::LooksShort);
        }
    }
    Ok(total)
}

/// Writes a short message.
pub(crate) fn encode_short(address: u8, code: [u8; 2], buf: &mut [u8]) -> Result<usize, EncodeError> {
    if !code.iter().all(u8::is_ascii_uppercase) {
        return Err(EncodeError::ShortCode(code));
    }
    let available = buf.len();
    let frame =
        buf.get_mut(..SHORT_LEN).ok_or(EncodeError::BufferTooSmall { needed: SHORT_LEN, available })?;
    let mut w = Writer::new(frame);
    w.put(address)?;
    w.put_all(&code)?;
    w.put(END)?;
    Ok(SHORT_LEN)
}
