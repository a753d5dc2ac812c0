//! CANopen messages classified by COB-ID (CiA 301 §7.3.3 predefined connection set:
//! function code = COB-ID bits 10..7, node id = bits 6..0), decoded and encoded.

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::emcy::EmcyClass;
use crate::error::{check_len, EncodeError};
use crate::lss::{LssRequest, LssResponse};
use crate::nmt::{NmtCommand, NmtState};
use crate::sdo::{SdoPayload, SdoRequest, SdoResponse};
use motus_can_frame::CanFrame;

/// COB-ID of LSS slave → master frames.
pub const LSS_SLAVE_TO_MASTER: u32 = 0x7E4;
/// COB-ID of LSS master → slave frames.
pub const LSS_MASTER_TO_SLAVE: u32 = 0x7E5;

/// Direction of a PDO as seen from the node that owns the COB-ID.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PdoKind {
    /// Transmit PDO (node → bus): 0x180 / 0x280 / 0x380 / 0x480 + node.
    Tpdo,
    /// Receive PDO (bus → node): 0x200 / 0x300 / 0x400 / 0x500 + node.
    Rpdo,
}

/// A CANopen message. Decoding is total: anything that does not fit a service's layout
/// exactly (extended ids, RTR, wrong length, reserved bits set...) is [`CanOpenMessage::Raw`].
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum CanOpenMessage {
    /// NMT module control (COB-ID 0x000, 2 bytes).
    Nmt {
        /// Command specifier.
        command: NmtCommand,
        /// Addressed node (0 = all nodes).
        node: u8,
    },
    /// SYNC (COB-ID 0x080, 0 or 1 byte).
    Sync {
        /// Optional SYNC counter.
        counter: Option<u8>,
    },
    /// Emergency (COB-ID 0x080 + node, 8 bytes).
    Emcy {
        /// Producing node.
        node: u8,
        /// Emergency error code (see [`EmcyClass::of`]).
        code: u16,
        /// Error register (copy of 0x1001).
        register: u8,
        /// Manufacturer-specific error field (bytes 3–7).
        manufacturer: [u8; 5],
    },
    /// One of the four default PDOs.
    Pdo {
        /// TPDO or RPDO.
        kind: PdoKind,
        /// PDO number 1..=4.
        number: u8,
        /// Node id.
        node: u8,
        /// 0..=8 data bytes.
        data: Vec<u8>,
    },
    /// SDO client → server (COB-ID 0x600 + node).
    SdoRequest {
        /// Server node.
        node: u8,
        /// The request.
        sdo: SdoRequest,
    },
    /// SDO server → client (COB-ID 0x580 + node).
    SdoResponse {
        /// Server node.
        node: u8,
        /// The response.
        sdo: SdoResponse,
    },
    /// Heartbeat or boot-up (COB-ID 0x700 + node, 1 byte).
    Heartbeat {
        /// Producing node.
        node: u8,
        /// Its NMT state (boot-up = 0x00).
        state: NmtState,
    },
    /// LSS master → slave (COB-ID 0x7E5).
    LssRequest {
        /// The request.
        lss: LssRequest,
    },
    /// LSS slave → master (COB-ID 0x7E4).
    LssResponse {
        /// The response.
        lss: LssResponse,
    },
    /// Any other frame, unchanged.
    Raw {
        /// The frame.
        frame: CanFrame,
    },
}

fn check_node(node: u8) -> Result<u32, EncodeError> {
    if (1..=127).contains(&node) {
        Ok(u32::from(node))
    } else {
        Err(EncodeError::InvalidNode(node))
    }
}

/// (function code base, kind, number) for the default PDO COB-IDs.
const PDOS: [(u32, PdoKind, u8); 8] = [
    (0x180, PdoKind::Tpdo, 1),
    (0x200, PdoKind::Rpdo, 1),
    (0x280, PdoKind::Tpdo, 2),
    (0x300, PdoKind::Rpdo, 2),
    (0x380, PdoKind::Tpdo, 3),
    (0x400, PdoKind::Rpdo, 3),
    (0x480, PdoKind::Tpdo, 4),
    (0x500, PdoKind::Rpdo, 4),
];

impl CanOpenMessage {
    /// Decodes a frame. Never fails: unknown or malformed frames become `Raw`, and
    /// `decode(f).encode() == Ok(f)` for every frame `f`.
    pub fn decode(frame: &CanFrame) -> Self {
        match Self::parse(frame) {
            Some(msg) if msg.encode().as_ref() == Ok(frame) => msg,
            _ => Self::Raw { frame: frame.clone() },
        }
    }

    /// Structural parse; may accept frames that would not re-encode identically
    /// (e.g. non-zero reserved bytes), which `decode` then keeps raw.
    fn parse(frame: &CanFrame) -> Option<Self> {
        if frame.is_extended() || frame.is_remote() {
            return None;
        }
        let id = frame.id();
        let d = frame.data();
        let node = u8::try_from(id & 0x7F).ok()?;
        match id {
            0x000 => {
                let [cs, node]: [u8; 2] = d.try_into().ok()?;
                return Some(Self::Nmt { command: NmtCommand::from_raw(cs), node });
            }
            0x080 => {
                return Some(Self::Sync {
                    counter: match d {
                        [] => None,
                        [c] => Some(*c),
                        _ => return None,
                    },
                })
            }
            LSS_MASTER_TO_SLAVE => return LssRequest::decode(d).map(|lss| Self::LssRequest { lss }),
            LSS_SLAVE_TO_MASTER => return LssResponse::decode(d).map(|lss| Self::LssResponse { lss }),
            _ => {}
        }
        if node == 0 {
            return None;
        }
        let base = id & !0x7F;
        if let Some(&(_, kind, number)) = PDOS.iter().find(|(b, _, _)| *b == base) {
            return Some(Self::Pdo { kind, number, node, data: d.to_vec() });
        }
        Some(match base {
            0x080 => {
                let [c0, c1, register, m0, m1, m2, m3, m4]: [u8; 8] = d.try_into().ok()?;
                Self::Emcy {
                    node,
                    code: u16::from_le_bytes([c0, c1]),
                    register,
                    manufacturer: [m0, m1, m2, m3, m4],
                }
            }
            0x580 => Self::SdoResponse { node, sdo: SdoResponse::decode(d)? },
            0x600 => Self::SdoRequest { node, sdo: SdoRequest::decode(d)? },
            0x700 => {
                let [state]: [u8; 1] = d.try_into().ok()?;
                Self::Heartbeat { node, state: NmtState::from_raw(state) }
            }
            _ => return None,
        })
    }

    /// Encodes the message into a standard CAN frame.
    pub fn encode(&self) -> Result<CanFrame, EncodeError> {
        let frame = match self {
            Self::Nmt { command, node } => {
                if *node > 127 {
                    return Err(EncodeError::InvalidNode(*node));
                }
                CanFrame::new(0x000, &[command.raw(), *node])?
            }
            Self::Sync { counter } => match counter {
                Some(c) => CanFrame::new(0x080, &[*c])?,
                None => CanFrame::new(0x080, &[])?,
            },
            Self::Emcy { node, code, register, manufacturer } => {
                let [c0, c1] = code.to_le_bytes();
                let [m0, m1, m2, m3, m4] = *manufacturer;
                CanFrame::new(0x080 + check_node(*node)?, &[c0, c1, *register, m0, m1, m2, m3, m4])?
            }
            Self::Pdo { kind, number, node, data } => {
                let base = PDOS
                    .iter()
                    .find(|(_, k, n)| k == kind && n == number)
                    .map(|(b, _, _)| *b)
                    .ok_or(EncodeError::InvalidPdoNumber(*number))?;
                check_len(data.len(), 0, 8)?;
                CanFrame::new(base + check_node(*node)?, data)?
            }
            Self::SdoRequest { node, sdo } => CanFrame::new(0x600 + check_node(*node)?, &sdo.encode()?)?,
            Self::SdoResponse { node, sdo } => CanFrame::new(0x580 + check_node(*node)?, &sdo.encode()?)?,
            Self::Heartbeat { node, state } => CanFrame::new(0x700 + check_node(*node)?, &[state.raw()])?,
            Self::LssRequest { lss } => CanFrame::new(LSS_MASTER_TO_SLAVE, &lss.encode()?)?,
            Self::LssResponse { lss } => CanFrame::new(LSS_SLAVE_TO_MASTER, &lss.encode())?,
            Self::Raw { frame } => frame.clone(),
        };
        Ok(frame)
    }
}

fn hex(data: &[u8]) -> String {
    data.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ")
}

fn payload(f: &mut fmt::Formatter<'_>, p: &SdoPayload) -> fmt::Result {
    match (p, p.value()) {
        (SdoPayload::Segmented { size: Some(s) }, _) => write!(f, " (segmented, {s} bytes)"),
        (SdoPayload::Segmented { size: None }, _) => write!(f, " (segmented)"),
        (_, Some(v)) => write!(f, " = {v}"),
        (_, None) => Ok(()),
    }
}

impl fmt::Display for CanOpenMessage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Nmt { command, node: 0 } => write!(f, "NMT {command} (all nodes)"),
            Self::Nmt { command, node } => write!(f, "NMT {command} (node {node})"),
            Self::Sync { counter: None } => write!(f, "SYNC"),
            Self::Sync { counter: Some(c) } => write!(f, "SYNC counter {c}"),
            Self::Emcy { node, code, register, manufacturer } => write!(
                f,
                "EMCY 0x{code:04X} ({}) register 0x{register:02X} data {} (node {node})",
                EmcyClass::of(*code).description(),
                hex(manufacturer)
            ),
            Self::Pdo { kind, number, node, data } => {
                let k = match kind {
                    PdoKind::Tpdo => "TPDO",
                    PdoKind::Rpdo => "RPDO",
                };
                write!(f, "{k}{number} [{}] (node {node})", hex(data))
            }
            Self::SdoRequest { node, sdo } => {
                match sdo {
                    SdoRequest::InitiateDownload { index, subindex, payload: p } => {
                        write!(f, "SDO download request 0x{index:04X}:{subindex:02X}")?;
                        payload(f, p)?;
                    }
                    SdoRequest::DownloadSegment { toggle, last, data } => write!(
                        f,
                        "SDO download segment t={} [{}]{}",
                        u8::from(*toggle),
                        hex(data),
                        if *last { " last" } else { "" }
                    )?,
                    SdoRequest::InitiateUpload { index, subindex } => {
                        write!(f, "SDO upload request 0x{index:04X}:{subindex:02X}")?
                    }
                    SdoRequest::UploadSegment { toggle } => {
                        write!(f, "SDO upload segment request t={}", u8::from(*toggle))?
                    }
                    SdoRequest::Abort { index, subindex, code } => write!(
                        f,
                        "SDO abort 0x{index:04X}:{subindex:02X} 0x{:08X} {}",
                        code.raw(),
                        code.description()
                    )?,
                }
                write!(f, " (node {node})")
            }
            Self::SdoResponse { node, sdo } => {
                match sdo {
                    SdoResponse::InitiateUpload { index, subindex, payload: p } => {
                        write!(f, "SDO upload response 0x{index:04X}:{subindex:02X}")?;
                        payload(f, p)?;
                    }
                    SdoResponse::UploadSegment { toggle, last, data } => write!(
                        f,
                        "SDO upload segment t={} [{}]{}",
                        u8::from(*toggle),
                        hex(data),
                        if *last { " last" } else { "" }
                    )?,
                    SdoResponse::InitiateDownload { index, subindex } => {
                        write!(f, "SDO download response 0x{index:04X}:{subindex:02X} ok")?
                    }
                    SdoResponse::DownloadSegment { toggle } => {
                        write!(f, "SDO download segment response t={}", u8::from(*toggle))?
                    }
                    SdoResponse::Abort { index, subindex, code } => write!(
                        f,
                        "SDO abort 0x{index:04X}:{subindex:02X} 0x{:08X} {}",
                        code.raw(),
                        code.description()
                    )?,
                }
                write!(f, " (node {node})")
            }
            Self::Heartbeat { node, state: NmtState::BootUp } => write!(f, "boot-up (node {node})"),
            Self::Heartbeat { node, state } => match state {
                NmtState::Unknown(raw) => write!(f, "heartbeat state 0x{raw:02X} (node {node})"),
                _ => write!(f, "heartbeat {state} (node {node})"),
            },
            Self::LssRequest { lss } => write!(f, "LSS request: {lss}"),
            Self::LssResponse { lss } => write!(f, "LSS response: {lss}"),
            Self::Raw { frame } => write!(f, "raw {frame}"),
        }
    }
}
