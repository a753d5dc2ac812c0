//! Sans-IO codec of the socketcand text protocol (raw mode).
//!
//! A message is `<`, space-separated tokens, `>`; messages follow each other in a byte
//! stream without separators. [`StreamParser`] cuts messages out of the stream (it
//! resynchronises after garbage and never holds more than [`MAX_MESSAGE`] bytes of an
//! unfinished message); [`Message::parse`] types one message; [`Message::format`] writes
//! one exactly as python-can expects (see `specs/can-transports.md`).

use crate::CanFrame;
use std::fmt::Write as _;
use std::time::Duration;

/// Longest message text kept while waiting for its closing `>`; longer input is garbage.
pub const MAX_MESSAGE: usize = 1024;

/// One socketcand message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Message {
    /// `< hi >`: the server greets a new client.
    Hi,
    /// `< open CHANNEL >`: the client opens a bus.
    Open(String),
    /// `< rawmode >`: the client asks for raw frames.
    Rawmode,
    /// `< ok >`: the server accepts the last request.
    Ok,
    /// `< echo >`: a keep-alive, answered with `< echo >`.
    Echo,
    /// `< send ID DLC b0 b1 ... >`: the client sends a frame (a DLC > 0 without data bytes
    /// is a remote frame, as python-can writes it).
    Send(CanFrame),
    /// `< frame ID SECS.USECS DATA >`: the server delivers a frame.
    Frame {
        /// The frame (never remote: the format cannot express it).
        frame: CanFrame,
        /// Its time stamp (microsecond resolution on the wire).
        timestamp: Duration,
    },
    /// `< error ... >`: an error frame or error report; the tokens after `error`.
    Error(String),
    /// Anything else, or a known command with bad arguments: the text between `<` and `>`.
    Unknown(String),
}

/// Why a message's text is not a valid message of its kind.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CodecError {
    /// An identifier that is not 1-8 hex digits within range.
    #[error("bad CAN identifier {0:?}")]
    BadId(String),
    /// A DLC that is not a hex digit 0-8.
    #[error("bad DLC {0:?}")]
    BadDlc(String),
    /// A data byte or data field that is not hex.
    #[error("bad data {0:?}")]
    BadData(String),
    /// A time stamp that is not `SECS.USECS`.
    #[error("bad time stamp {0:?}")]
    BadTimestamp(String),
    /// The DLC disagrees with the number of data bytes.
    #[error("DLC {dlc} but {bytes} data bytes")]
    LengthMismatch {
        /// The DLC announced.
        dlc: u8,
        /// The data bytes present.
        bytes: usize,
    },
    /// A required token is missing.
    #[error("missing {0}")]
    Missing(&'static str),
}

fn parse_id(text: &str) -> Result<(u32, bool), CodecError> {
    let bad = || CodecError::BadId(text.to_owned());
    if text.is_empty() || text.len() > 8 || !text.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(bad());
    }
    let id = u32::from_str_radix(text, 16).map_err(|_| bad())?;
    // python-can's rule: exactly 3 digits is a standard id, anything else extended.
    Ok((id, text.len() != 3))
}

fn hex_byte(text: &str) -> Result<u8, CodecError> {
    if text.is_empty() || text.len() > 2 {
        return Err(CodecError::BadData(text.to_owned()));
    }
    u8::from_str_radix(text, 16).map_err(|_| CodecError::BadData(text.to_owned()))
}

fn parse_timestamp(text: &str) -> Result<Duration, CodecError> {
    let bad = || CodecError::BadTimestamp(text.to_owned());
    let (secs, frac) = text.split_once('.').unwrap_or((text, ""));
    if secs.is_empty()
        || !secs.bytes().all(|b| b.is_ascii_digit())
        || !frac.bytes().all(|b| b.is_ascii_digit())
    {
        return Err(bad());
    }
    let secs: u64 = secs.parse().map_err(|_| bad())?;
    // Microseconds (the wire resolution) from the first 6 fractional digits, right-padded.
    let mut micros = 0u32;
    for i in 0..6 {
        let digit = frac.as_bytes().get(i).map_or(0, |d| u32::from(d - b'0'));
        micros = micros * 10 + digit;
    }
    Ok(Duration::new(secs, micros * 1000))
}

fn frame_from(id: &str, data: &[u8]) -> Result<CanFrame, CodecError> {
    let (id_value, extended) = parse_id(id)?;
    CanFrame::with_format(id_value, extended, data).map_err(|_| CodecError::BadId(id.to_owned()))
}

fn parse_send<'a>(mut tokens: impl Iterator<Item = &'a str>) -> Result<CanFrame, CodecError> {
    let id = tokens.next().ok_or(CodecError::Missing("identifier"))?;
    let dlc_text = tokens.next().ok_or(CodecError::Missing("DLC"))?;
    let dlc = match u8::from_str_radix(dlc_text, 16) {
        Ok(d) if d <= 8 && dlc_text.len() <= 2 => d,
        _ => return Err(CodecError::BadDlc(dlc_text.to_owned())),
    };
    let mut data = [0u8; 8];
    let mut len = 0usize;
    for token in tokens {
        let slot = data.get_mut(len).ok_or(CodecError::LengthMismatch { dlc, bytes: len + 1 })?;
        *slot = hex_byte(token)?;
        len += 1;
    }
    if len == 0 && dlc > 0 {
        let (id_value, extended) = parse_id(id)?;
        return CanFrame::remote(id_value, extended, dlc).map_err(|_| CodecError::BadId(id.to_owned()));
    }
    if len != usize::from(dlc) {
        return Err(CodecError::LengthMismatch { dlc, bytes: len });
    }
    frame_from(id, data.get(..len).unwrap_or(&[]))
}

fn parse_frame<'a>(mut tokens: impl Iterator<Item = &'a str>) -> Result<Message, CodecError> {
    let id = tokens.next().ok_or(CodecError::Missing("identifier"))?;
    let timestamp = parse_timestamp(tokens.next().ok_or(CodecError::Missing("time stamp"))?)?;
    let hex = tokens.next().unwrap_or("");
    if tokens.next().is_some() || hex.len() & 1 == 1 || hex.len() > 16 {
        return Err(CodecError::BadData(hex.to_owned()));
    }
    let mut data = [0u8; 8];
    for (slot, pair) in data.iter_mut().zip(hex.as_bytes().chunks(2)) {
        let text = std::str::from_utf8(pair).map_err(|_| CodecError::BadData(hex.to_owned()))?;
        *slot = hex_byte(text)?;
    }
    let frame = frame_from(id, data.get(..hex.len() / 2).unwrap_or(&[]))?;
    Ok(Message::Frame { frame, timestamp })
}

impl Message {
    /// Types the text between `<` and `>` (surrounding spaces allowed).
    ///
    /// Unknown commands give `Ok(Message::Unknown)`; a known command with bad arguments
    /// gives the error.
    pub fn parse(text: &str) -> Result<Message, CodecError> {
        let mut tokens = text.split_ascii_whitespace();
        let Some(command) = tokens.next() else {
            return Ok(Message::Unknown(text.trim().to_owned()));
        };
        let rest_empty = |mut t: std::str::SplitAsciiWhitespace<'_>| t.next().is_none();
        Ok(match command {
            "hi" if rest_empty(tokens.clone()) => Message::Hi,
            "ok" if rest_empty(tokens.clone()) => Message::Ok,
            "rawmode" if rest_empty(tokens.clone()) => Message::Rawmode,
            "echo" if rest_empty(tokens.clone()) => Message::Echo,
            "open" => {
                let channel = tokens.next().ok_or(CodecError::Missing("channel"))?;
                Message::Open(channel.to_owned())
            }
            "send" => Message::Send(parse_send(tokens)?),
            "frame" => parse_frame(tokens)?,
            "error" => Message::Error(tokens.collect::<Vec<_>>().join(" ")),
            _ => Message::Unknown(text.trim().to_owned()),
        })
    }

    /// Like [`Message::parse`], but a malformed message becomes [`Message::Unknown`].
    pub fn parse_lenient(text: &str) -> Message {
        Message::parse(text).unwrap_or_else(|_| Message::Unknown(text.trim().to_owned()))
    }

    /// Appends the wire form of this message to `out`.
    ///
    /// `Frame` with a remote frame is written with no data (the format has no RTR flag);
    /// callers are expected not to send those to python-can.
    pub fn format_into(&self, out: &mut String) {
        match self {
            Message::Hi => out.push_str("< hi >"),
            Message::Ok => out.push_str("< ok >"),
            Message::Rawmode => out.push_str("< rawmode >"),
            Message::Echo => out.push_str("< echo >"),
            Message::Open(channel) => {
                let _ = write!(out, "< open {channel} >");
            }
            Message::Send(frame) => {
                out.push_str("< send ");
                push_id(out, frame);
                out.push(' ');
                push_hex(out, frame.dlc(), HEX_UPPER, false);
                out.push(' ');
                for b in frame.data() {
                    push_hex(out, *b, HEX_LOWER, false);
                    out.push(' ');
                }
                if frame.data().is_empty() {
                    // `< send 080 0  >`: the space after the DLC, then the one before `>`.
                    out.push(' ');
                }
                out.push('>');
            }
            Message::Frame { frame, timestamp } => {
                out.push_str("< frame ");
                push_id(out, frame);
                let _ = write!(out, " {}.{:06} ", timestamp.as_secs(), timestamp.subsec_micros());
                for b in frame.data() {
                    push_hex(out, *b, HEX_UPPER, true);
                }
                // Always a space before `>`: an empty frame ends with two spaces.
                out.push_str(" >");
            }
            Message::Error(text) => {
                let _ = write!(out, "< error {text} >");
            }
            Message::Unknown(text) => {
                let _ = write!(out, "< {text} >");
            }
        }
    }

    /// The wire form of this message.
    pub fn format(&self) -> String {
        let mut out = String::with_capacity(48);
        self.format_into(&mut out);
        out
    }
}

const HEX_UPPER: &[u8; 16] = b"0123456789ABCDEF";
const HEX_LOWER: &[u8; 16] = b"0123456789abcdef";

/// Appends `b` in hexadecimal: two digits with `pad`, else without a leading zero (what
/// `{:02X}` and `{:x}` write, without going through `core::fmt` for every byte).
fn push_hex(out: &mut String, b: u8, digits: &[u8; 16], pad: bool) {
    let digit = |nibble: u8| char::from(digits.get(usize::from(nibble & 0xF)).copied().unwrap_or(b'0'));
    if pad || b > 0xF {
        out.push(digit(b >> 4));
    }
    out.push(digit(b));
}

fn push_id(out: &mut String, frame: &CanFrame) {
    let _ = if frame.is_extended() {
        write!(out, "{:08X}", frame.id())
    } else {
        write!(out, "{:03X}", frame.id())
    };
}

/// Cuts `< ... >` messages out of a byte stream.
#[derive(Debug, Default)]
pub struct StreamParser {
    buf: Vec<u8>,
    garbage: u64,
}

impl StreamParser {
    /// An empty parser.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
        self.trim();
    }

    /// Bytes discarded so far because they were outside any message (or too long).
    pub fn garbage_bytes(&self) -> u64 {
        self.garbage
    }

    /// Bytes held while waiting for the rest of a message (at most [`MAX_MESSAGE`]).
    pub fn buffered(&self) -> usize {
        self.buf.len()
    }

    /// Drops what cannot start a message and bounds the buffer.
    fn trim(&mut self) {
        let keep_from = match self.buf.iter().position(|&b| b == b'>') {
            // A complete message (or a stray `>`) is waiting: next_text handles it.
            Some(_) => return,
            None => self.buf.iter().rposition(|&b| b == b'<').unwrap_or(self.buf.len()),
        };
        let keep_from = if self.buf.len() - keep_from > MAX_MESSAGE { self.buf.len() } else { keep_from };
        self.garbage += keep_from as u64;
        self.buf.drain(..keep_from);
    }

    /// The text of the next complete message, if any.
    pub fn next_text(&mut self) -> Option<String> {
        self.take_next(str::to_owned)
    }

    /// Takes the next complete message out of the buffer and hands its text (between `<`
    /// and `>`, borrowed when it is valid UTF-8) to `read`; what is not a message is
    /// counted as garbage.
    fn take_next<T>(&mut self, mut read: impl FnMut(&str) -> T) -> Option<T> {
        loop {
            let close = self.buf.iter().position(|&b| b == b'>')?;
            let head = self.buf.get(..close).unwrap_or(&[]);
            let open = head.iter().rposition(|&b| b == b'<');
            let consumed_garbage = open.unwrap_or(close + 1);
            self.garbage += consumed_garbage as u64;
            let taken = match open.and_then(|o| head.get(o + 1..)) {
                Some(t) if t.len() <= MAX_MESSAGE => Some(read(&String::from_utf8_lossy(t))),
                Some(_) => {
                    self.garbage += (close + 1 - consumed_garbage) as u64;
                    None
                }
                None => None,
            };
            self.buf.drain(..=close);
            self.trim();
            if taken.is_some() {
                return taken;
            }
        }
    }
}

impl Iterator for StreamParser {
    type Item = Message;

    /// The next complete message, typed leniently (malformed -> [`Message::Unknown`]),
    /// parsed in place (no copy of its text).
    fn next(&mut self) -> Option<Message> {
        self.take_next(Message::parse_lenient)
    }
}
