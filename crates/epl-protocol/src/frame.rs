//! A whole POWERLINK Ethernet frame: [`EthernetHeader`], node IDs, [`Message`] and
//! [`Padding`], with lossless decode and encode.
//!
//! # Padding rules
//! Each message has a natural length (SoC 36 bytes, SoA 54, PReq/PRes 24 + payload size,
//! IdentResponse 176, StatusResponse 32 + 20 per entry, NMT/unknown ASnd up to the last
//! non-zero data byte, SDO 30 + data). Whatever follows it in the frame is classified as
//! [`Padding`] so that re-encoding gives the same bytes:
//! * nothing follows and the frame is shorter than 60 bytes: [`Padding::Unpadded`] (the short
//!   frames openPOWERLINK sends over veth);
//! * zeros follow up to exactly 60 bytes, or nothing follows a frame of 60 bytes or more:
//!   [`Padding::Auto`] (the default: encode pads with zeros to 60 bytes);
//! * other all-zero tails: [`Padding::Zeros`]; anything else: [`Padding::Raw`].

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::asnd::Asnd;
use crate::error::{DecodeError, EncodeError};
use crate::ethernet::{EthernetHeader, MacAddr, MIN_FRAME_LEN};
use crate::preq::PReq;
use crate::pres::PRes;
use crate::soa::Soa;
use crate::soc::Soc;
use crate::wire::{is_zero, trim_zeros, Rd};

/// What follows the message in the frame (see the module documentation).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Padding {
    /// Pad with zeros to 60 bytes when shorter (the default).
    #[default]
    Auto,
    /// No padding, even when the frame is shorter than 60 bytes.
    Unpadded,
    /// This many zero bytes.
    Zeros {
        /// Number of zero bytes.
        len: usize,
    },
    /// These bytes.
    Raw {
        /// The bytes.
        bytes: Vec<u8>,
    },
}

impl Padding {
    /// True for [`Padding::Auto`].
    pub fn is_auto(&self) -> bool {
        *self == Padding::Auto
    }

    /// Classifies `tail`, the bytes after the message in a frame of `frame_len` bytes.
    pub fn classify(tail: &[u8], frame_len: usize) -> Self {
        if tail.is_empty() {
            if frame_len < MIN_FRAME_LEN {
                Padding::Unpadded
            } else {
                Padding::Auto
            }
        } else if tail.iter().all(|&b| b == 0) {
            if frame_len == MIN_FRAME_LEN {
                Padding::Auto
            } else {
                Padding::Zeros { len: tail.len() }
            }
        } else {
            Padding::Raw { bytes: tail.to_vec() }
        }
    }

    fn apply(&self, out: &mut Vec<u8>) {
        match self {
            Padding::Auto => {
                if out.len() < MIN_FRAME_LEN {
                    out.resize(MIN_FRAME_LEN, 0);
                }
            }
            Padding::Unpadded => {}
            Padding::Zeros { len } => out.resize(out.len() + len, 0),
            Padding::Raw { bytes } => out.extend_from_slice(bytes),
        }
    }
}

/// A POWERLINK message (the part after the node IDs), by message type.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Message {
    /// 0x01 Start of Cycle.
    Soc(Soc),
    /// 0x03 Poll Request.
    #[serde(rename = "preq")]
    PReq(PReq),
    /// 0x04 Poll Response.
    #[serde(rename = "pres")]
    PRes(PRes),
    /// 0x05 Start of Asynchronous phase.
    Soa(Soa),
    /// 0x06 Asynchronous Send.
    Asnd(Asnd),
    /// 0x07 Active Managing Node Indication (not decoded further).
    Amni {
        /// Bytes after the node IDs (trailing zeros dropped).
        #[serde(default)]
        data: Vec<u8>,
    },
    /// 0x0D ASnd Invite (not decoded further).
    Ainv {
        /// Bytes after the node IDs (trailing zeros dropped).
        #[serde(default)]
        data: Vec<u8>,
    },
}

impl Message {
    /// The message type code (low 7 bits of frame byte 14).
    pub fn message_type(&self) -> u8 {
        match self {
            Message::Soc(_) => 0x01,
            Message::PReq(_) => 0x03,
            Message::PRes(_) => 0x04,
            Message::Soa(_) => 0x05,
            Message::Asnd(_) => 0x06,
            Message::Amni { .. } => 0x07,
            Message::Ainv { .. } => 0x0D,
        }
    }

    /// Short name as wireshark prints it (SoC, PReq, PRes, SoA, ASnd, AMNI, AInv).
    pub fn name(&self) -> &'static str {
        match self {
            Message::Soc(_) => "SoC",
            Message::PReq(_) => "PReq",
            Message::PRes(_) => "PRes",
            Message::Soa(_) => "SoA",
            Message::Asnd(_) => "ASnd",
            Message::Amni { .. } => "AMNI",
            Message::Ainv { .. } => "AInv",
        }
    }

    /// The destination MAC this message type uses (`specs/powerlink.md` §1); `None` for PReq,
    /// which goes to the CN's own MAC, and AInv.
    pub fn multicast_mac(&self) -> Option<MacAddr> {
        match self {
            Message::Soc(_) => Some(MacAddr::SOC),
            Message::PRes(_) => Some(MacAddr::PRES),
            Message::Soa(_) => Some(MacAddr::SOA),
            Message::Asnd(_) => Some(MacAddr::ASND),
            Message::Amni { .. } => Some(MacAddr::AMNI),
            Message::PReq(_) | Message::Ainv { .. } => None,
        }
    }
}

/// One POWERLINK frame.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct EplFrame {
    /// Ethernet header.
    pub ethernet: EthernetHeader,
    /// Destination node ID (frame byte 15).
    pub dst_node: u8,
    /// Source node ID (frame byte 16).
    pub src_node: u8,
    /// The message.
    pub message: Message,
    /// What follows the message (default [`Padding::Auto`]).
    #[serde(default, skip_serializing_if = "Padding::is_auto")]
    pub padding: Padding,
    /// Bit 7 of the message type byte (reserved), kept raw (0 or 1).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub message_type_bit7: u8,
}

impl EplFrame {
    /// A frame with [`Padding::Auto`]; the destination MAC is the message's multicast address
    /// (`dst_mac` is used for PReq and AInv, and ignored otherwise).
    pub fn new(src_mac: MacAddr, dst_mac: MacAddr, dst_node: u8, src_node: u8, message: Message) -> Self {
        let dst = message.multicast_mac().unwrap_or(dst_mac);
        Self {
            ethernet: EthernetHeader::new(dst, src_mac),
            dst_node,
            src_node,
            message,
            padding: Padding::Auto,
            message_type_bit7: 0,
        }
    }

    /// Decodes one Ethernet frame (without FCS).
    pub fn decode(frame: &[u8]) -> Result<Self, DecodeError> {
        let (ethernet, start) = EthernetHeader::decode(frame)?;
        let epl = frame.get(start..).unwrap_or(&[]);
        let rd = Rd::new(epl, start, "POWERLINK header");
        rd.need(3)?;
        let mtyp_byte = rd.u8(0)?;
        let dst_node = rd.u8(1)?;
        let src_node = rd.u8(2)?;
        let mtyp = mtyp_byte & 0x7F;
        let (message, consumed) = match mtyp {
            0x01 => Soc::decode(&Rd::new(epl, start, "SoC")).map(|(m, n)| (Message::Soc(m), n))?,
            0x03 => PReq::decode(&Rd::new(epl, start, "PReq")).map(|(m, n)| (Message::PReq(m), n))?,
            0x04 => PRes::decode(&Rd::new(epl, start, "PRes")).map(|(m, n)| (Message::PRes(m), n))?,
            0x05 => Soa::decode(&Rd::new(epl, start, "SoA")).map(|(m, n)| (Message::Soa(m), n))?,
            0x06 => Asnd::decode(&Rd::new(epl, start, "ASnd")).map(|(m, n)| (Message::Asnd(m), n))?,
            0x07 | 0x0D => {
                let data = trim_zeros(rd.rest(3)).to_vec();
                let n = 3 + data.len();
                (if mtyp == 0x07 { Message::Amni { data } } else { Message::Ainv { data } }, n)
            }
            other => return Err(DecodeError::UnknownMessageType(other)),
        };
        let tail = epl.get(consumed..).unwrap_or(&[]);
        Ok(Self {
            ethernet,
            dst_node,
            src_node,
            message,
            padding: Padding::classify(tail, frame.len()),
            message_type_bit7: mtyp_byte >> 7,
        })
    }

    /// Encodes the frame (without FCS).
    pub fn encode(&self) -> Result<Vec<u8>, EncodeError> {
        let mut out = Vec::with_capacity(MIN_FRAME_LEN);
        self.encode_into(&mut out)?;
        Ok(out)
    }

    /// Appends the encoded frame to `out` (reuse a buffer to avoid allocation).
    pub fn encode_into(&self, out: &mut Vec<u8>) -> Result<(), EncodeError> {
        crate::wire::check_max("message_type_bit7", self.message_type_bit7.into(), 1)?;
        let start = out.len();
        self.ethernet.encode_into(out);
        out.extend_from_slice(&[
            self.message.message_type() | self.message_type_bit7 << 7,
            self.dst_node,
            self.src_node,
        ]);
        match &self.message {
            Message::Soc(m) => m.encode_into(out),
            Message::PReq(m) => m.encode_into(out)?,
            Message::PRes(m) => m.encode_into(out)?,
            Message::Soa(m) => m.encode_into(out),
            Message::Asnd(m) => m.encode_into(out)?,
            Message::Amni { data } | Message::Ainv { data } => out.extend_from_slice(data),
        }
        let mut frame = out.split_off(start);
        self.padding.apply(&mut frame);
        out.append(&mut frame);
        Ok(())
    }
}

impl fmt::Display for EplFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}->{} {}", self.src_node, self.dst_node, self.message.name())?;
        match &self.message {
            Message::PRes(p) => write!(
                f,
                " [{}] RD={} {}",
                p.payload.len(),
                u8::from(p.flags.contains(crate::Flags::RD)),
                p.nmt_state
            ),
            Message::PReq(p) => {
                write!(f, " [{}] RD={}", p.payload.len(), u8::from(p.flags.contains(crate::Flags::RD)))
            }
            Message::Soa(s) => write!(f, " {} tgt={} {}", s.requested_service, s.target, s.nmt_state),
            Message::Asnd(Asnd::NmtCommand(c)) => write!(f, " {}", c.command),
            Message::Asnd(a) => write!(f, " service {:#04x}", a.service_id()),
            _ => Ok(()),
        }
    }
}
