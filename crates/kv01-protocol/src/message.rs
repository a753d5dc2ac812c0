//! The typed message ([`Message`]), its direction, CRC checking mode, and the one-shot
//! [`decode_message`] / [`encode_message`] the CLI and tests use.
//!
//! **Direction.** The bytes of a frame do not say whether it travels host -> module or
//! module -> host (D0 carries ASCII both ways), so decoding takes a [`Direction`]. The JSON
//! form always names it (`"direction": "to_module"` / `"from_module"`), so `encode` needs
//! no hint. [`Direction::Auto`] guesses from the command and data shape ([`guess_direction`]);
//! pass the real direction whenever it is known.

use serde::{Deserialize, Serialize};

use crate::codec::{encode_short, encode_standard};
use crate::command::{code, Command, Request};
use crate::faulhaber;
use crate::frame::{scan, Envelope, Framed, Rules, Scan};
use crate::reply::{Answer, Reply, ReplyBody};
use crate::status::ResolverReading;
use crate::text::from_latin1;
use crate::{Address, DecodeError, EncodeError, END, MAX_FRAME_LEN, MIN_STANDARD_LEN};

/// Which way a message travels.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Direction {
    /// Host -> communication module (commands D0..D5).
    ToModule,
    /// Communication module -> host (replies and short messages).
    FromModule,
    /// Unknown: guess per frame ([`guess_direction`]). Decoding only.
    #[default]
    Auto,
}

/// How a receiver treats a bad CRC.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CrcMode {
    /// Reject the message ([`DecodeError::Crc`] with expected and received CRC).
    #[default]
    Strict,
    /// Accept it and report the mismatch in [`Decoded::crc_mismatch`] (for arms whose
    /// firmware computes the CRC differently: the source's own examples do not match the
    /// published procedure).
    Lenient,
}

/// A CRC that did not match, accepted in [`CrcMode::Lenient`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct CrcMismatch {
    /// CRC computed by the published procedure (after 0xF0 -> 0xF1).
    pub expected: u8,
    /// CRC byte found in the message.
    pub received: u8,
}

/// A KV-01 message in either direction. JSON: the `direction` tag, the `address`, then the
/// command or reply fields, e.g.
/// `{"direction":"to_module","address":226,"command":"d0","text":"EN"}`.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(tag = "direction")]
pub enum Message {
    /// Host -> module.
    #[serde(rename = "to_module")]
    Request(Request),
    /// Module -> host.
    #[serde(rename = "from_module")]
    Reply(Reply),
}

/// A decoded message and, in lenient mode, the CRC mismatch it was accepted with.
/// JSON: the message's fields plus `"crc_mismatch": {"expected": .., "received": ..}` when
/// set; `encode` accepts it (the extra field is ignored).
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Decoded {
    /// The message.
    #[serde(flatten)]
    pub message: Message,
    /// Set when the CRC was wrong and the frame accepted anyway ([`CrcMode::Lenient`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crc_mismatch: Option<CrcMismatch>,
}

impl Message {
    /// A host -> module message.
    #[must_use]
    pub const fn request(address: Address, command: Command) -> Self {
        Self::Request(Request { address, command })
    }

    /// A module -> host message.
    #[must_use]
    pub const fn reply(address: Address, body: ReplyBody) -> Self {
        Self::Reply(Reply { address, body })
    }

    /// The module address.
    #[must_use]
    pub const fn address(&self) -> Address {
        match self {
            Self::Request(r) => r.address,
            Self::Reply(r) => r.address,
        }
    }

    /// The direction ([`Direction::ToModule`] or [`Direction::FromModule`]).
    #[must_use]
    pub const fn direction(&self) -> Direction {
        match self {
            Self::Request(_) => Direction::ToModule,
            Self::Reply(_) => Direction::FromModule,
        }
    }

    /// Encodes into `buf` without allocating; returns the number of bytes written. A host
    /// message with 0xF0 before END is refused ([`EncodeError::EndInData`]).
    pub fn encode_into(&self, buf: &mut [u8]) -> Result<usize, EncodeError> {
        match self {
            Self::Request(r) => {
                let payload = r.command.payload()?;
                encode_standard(r.address.raw(), r.command.code(), &payload, true, buf)
            }
            Self::Reply(r) => match (&r.body, r.body.code()) {
                (ReplyBody::Short { text }, _) => encode_short(r.address.raw(), text.bytes(), buf),
                (body, Some(code)) => {
                    let payload = body.payload(r.address)?;
                    encode_standard(r.address.raw(), code, &payload, false, buf)
                }
                // Only a short message has no COMMAND byte, matched above.
                (_, None) => Err(EncodeError::LooksShort),
            },
        }
    }

    /// Encodes into a new vector.
    pub fn encode(&self) -> Result<Vec<u8>, EncodeError> {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let n = self.encode_into(&mut buf)?;
        Ok(buf.get(..n).unwrap_or_default().to_vec())
    }
}

/// Encodes a message (see [`Message::encode_into`]).
pub fn encode_message(msg: &Message) -> Result<Vec<u8>, EncodeError> {
    msg.encode()
}

pub(crate) fn rules(direction: Direction, mode: CrcMode) -> Rules {
    Rules { short: direction != Direction::ToModule, request: direction == Direction::ToModule, mode }
}

/// Builds the typed message of a framed candidate.
pub(crate) fn to_decoded(framed: &Framed<'_>, direction: Direction) -> Decoded {
    let message = match framed.envelope {
        Envelope::Short { address, code } => Message::reply(address, ReplyBody::Short { text: code }),
        Envelope::Standard { address, code, data } => {
            let dir = match direction {
                Direction::Auto => guess_direction(code, data),
                d => d,
            };
            if dir == Direction::ToModule {
                Message::request(address, Command::from_wire(code, data))
            } else {
                Message::reply(address, ReplyBody::from_wire(address, code, data))
            }
        }
    };
    Decoded { message, crc_mismatch: framed.crc_mismatch }
}

/// Decodes exactly one message occupying all of `bytes`.
pub fn decode_message(bytes: &[u8], direction: Direction, mode: CrcMode) -> Result<Decoded, DecodeError> {
    if direction == Direction::ToModule {
        if let Scan::Frame(Framed { len: 4, .. }) = scan(bytes, rules(Direction::FromModule, mode)) {
            if bytes.len() == 4 {
                return Err(DecodeError::ShortToModule);
            }
        }
    }
    match scan(bytes, rules(direction, mode)) {
        Scan::NeedMore { expected: Some(n) } => {
            Err(DecodeError::Length { expected: n, received: bytes.len() })
        }
        Scan::NeedMore { expected: None } => Err(DecodeError::TooShort { received: bytes.len() }),
        Scan::Invalid(e) => Err(e),
        Scan::Frame(f) if f.len != bytes.len() => {
            Err(DecodeError::Length { expected: f.len, received: bytes.len() })
        }
        Scan::Frame(f) => Ok(to_decoded(&f, direction)),
    }
}

/// The [`Direction::Auto`] guess for a standard message (a short message is always
/// module -> host). Where both readings fit, host -> module wins:
///
/// - D0: module -> host if the text is a typed answer (`OK`, a number, an error string,
///   `TIMEOUT`, `LSSTOP`, `LIMVAL`, ...), else host -> module (commands start with a letter).
/// - D1: module -> host if the byte has bits 4-7 clear (status), else host -> module
///   (0xB0/0xB1/0xA0/0xA1/0xC0/0xC1).
/// - D2: host -> module if the text parses as a known Faulhaber command; else module -> host
///   if it is a valid 3-byte resolver packing; else host -> module.
/// - D3, D4: host -> module without data, module -> host with data.
/// - D5: module -> host if bit 6 or 7 is set (only a load >= 16 sets bit 6), else host ->
///   module (ambiguous: a request byte is also a valid load byte).
/// - Other codes: host -> module.
///
/// Before all that: a frame with 0xF0 as LENGTH, COMMAND or in DATA cannot go to a module,
/// so it is module -> host.
#[must_use]
pub fn guess_direction(command: u8, data: &[u8]) -> Direction {
    let from = |b: bool| if b { Direction::FromModule } else { Direction::ToModule };
    if command == END || data.contains(&END) || data.len() + MIN_STANDARD_LEN == usize::from(END) {
        return Direction::FromModule;
    }
    match (command, data) {
        (code::D0, []) => Direction::ToModule,
        (code::D0, text) => {
            from(!matches!(Answer::parse(&from_latin1(text)), Answer::Controller(faulhaber::Reply::Text(_))))
        }
        (code::D1, [b]) => from(b & 0xF0 == 0),
        (code::D2, text) => {
            let command = faulhaber::Request::parse(&from_latin1(text));
            let known = matches!(command, Ok(r) if !matches!(r.command, faulhaber::Command::Unknown(_)));
            let resolver = matches!(text, [a, b, c] if ResolverReading::from_bytes([*a, *b, *c]).is_some());
            from(!known && resolver)
        }
        (code::D3 | code::D4, d) => from(!d.is_empty()),
        (code::D5, [b]) => from(b & 0xC0 != 0),
        _ => Direction::ToModule,
    }
}
