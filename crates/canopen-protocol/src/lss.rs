//! LSS (CiA 305): master → slave requests on 0x7E5, slave → master responses on 0x7E4.
//! Every frame is 8 bytes; byte 0 = command specifier; 32-bit values LE in bytes 1–4;
//! unused bytes are 0.

use serde::{Deserialize, Serialize};

use crate::error::EncodeError;

/// Part of the 128-bit LSS address (object 0x1018 sub 1–4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LssIdentityField {
    /// Vendor-ID (0x1018:01).
    Vendor,
    /// Product code (0x1018:02).
    Product,
    /// Revision number (0x1018:03).
    Revision,
    /// Serial number (0x1018:04).
    Serial,
}

impl LssIdentityField {
    fn from_offset(o: u8) -> Option<Self> {
        Some(match o {
            0 => Self::Vendor,
            1 => Self::Product,
            2 => Self::Revision,
            3 => Self::Serial,
            _ => return None,
        })
    }

    fn offset(self) -> u8 {
        match self {
            Self::Vendor => 0,
            Self::Product => 1,
            Self::Revision => 2,
            Self::Serial => 3,
        }
    }
}

/// Master → slave LSS request (COB-ID 0x7E5).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "service", rename_all = "snake_case")]
pub enum LssRequest {
    /// cs 0x04: switch all slaves to waiting (false) or configuration (true).
    SwitchStateGlobal {
        /// True = configuration state.
        configuration: bool,
    },
    /// cs 0x40–0x43: switch state selective, one address part per frame.
    SwitchStateSelective {
        /// Address part.
        field: LssIdentityField,
        /// Its value.
        value: u32,
    },
    /// cs 0x11: configure node-ID (1–127, or 0xFF = unconfigured).
    ConfigureNodeId {
        /// New node id.
        node_id: u8,
    },
    /// cs 0x13: configure bit timing.
    ConfigureBitTiming {
        /// Table selector (0 = standard table).
        table: u8,
        /// Table index (0 = 1000 kbit/s ... 8 = 10 kbit/s, 9 = auto).
        index: u8,
    },
    /// cs 0x15: activate bit timing after a switch delay.
    ActivateBitTiming {
        /// Switch delay in ms.
        delay_ms: u16,
    },
    /// cs 0x17: store configuration.
    StoreConfiguration,
    /// cs 0x46–0x4B: identify remote slave (selector 0 vendor, 1 product, 2 revision low,
    /// 3 revision high, 4 serial low, 5 serial high).
    IdentifyRemoteSlave {
        /// cs − 0x46 (0..=5).
        selector: u8,
        /// Value or bound.
        value: u32,
    },
    /// cs 0x4C: identify non-configured remote slave.
    IdentifyNonConfigured,
    /// cs 0x51: fastscan.
    Fastscan {
        /// IDNumber (bytes 1–4).
        id_number: u32,
        /// BitCheck (0–31, or 0x80 = reset).
        bit_check: u8,
        /// LSSSub (0 vendor .. 3 serial).
        lss_sub: u8,
        /// LSSNext.
        lss_next: u8,
    },
    /// cs 0x5A–0x5D: inquire an identity part.
    InquireIdentity {
        /// Address part asked for.
        field: LssIdentityField,
    },
    /// cs 0x5E: inquire node-ID.
    InquireNodeId,
}

/// Slave → master LSS response (COB-ID 0x7E4).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "service", rename_all = "snake_case")]
pub enum LssResponse {
    /// cs 0x44: switch state selective matched; slave is in configuration state.
    SwitchStateSelective,
    /// cs 0x11: configure node-ID result (0 ok, 1 out of range, 0xFF manufacturer).
    ConfigureNodeId {
        /// Error code.
        error: u8,
        /// Manufacturer-specific error.
        spec_error: u8,
    },
    /// cs 0x13: configure bit timing result (0 ok, 1 not supported, 0xFF manufacturer).
    ConfigureBitTiming {
        /// Error code.
        error: u8,
        /// Manufacturer-specific error.
        spec_error: u8,
    },
    /// cs 0x17: store configuration result (0 ok, 1 not supported, 2 media error).
    StoreConfiguration {
        /// Error code.
        error: u8,
        /// Manufacturer-specific error.
        spec_error: u8,
    },
    /// cs 0x4F: identify slave (answer to identify remote slave / fastscan).
    IdentifySlave,
    /// cs 0x50: identify non-configured slave.
    IdentifyNonConfiguredSlave,
    /// cs 0x5A–0x5D: identity part.
    InquireIdentity {
        /// Address part.
        field: LssIdentityField,
        /// Its value.
        value: u32,
    },
    /// cs 0x5E: active node id (0xFF if unconfigured).
    InquireNodeId {
        /// Node id.
        node_id: u8,
    },
}

fn u32_at(d: &[u8; 8]) -> u32 {
    let [_, a, b, c, e, ..] = *d;
    u32::from_le_bytes([a, b, c, e])
}

fn with_u32(cs: u8, v: u32) -> [u8; 8] {
    let [a, b, c, d] = v.to_le_bytes();
    [cs, a, b, c, d, 0, 0, 0]
}

fn with_bytes(cs: u8, b1: u8, b2: u8) -> [u8; 8] {
    [cs, b1, b2, 0, 0, 0, 0, 0]
}

impl LssRequest {
    /// Decodes an 8-byte request; `None` for unknown command specifiers or short frames.
    pub fn decode(d: &[u8]) -> Option<Self> {
        let d: &[u8; 8] = d.try_into().ok()?;
        let [cs, b1, b2, _, _, b5, b6, b7] = *d;
        Some(match cs {
            0x04 => Self::SwitchStateGlobal {
                configuration: match b1 {
                    0 => false,
                    1 => true,
                    _ => return None,
                },
            },
            0x40..=0x43 => Self::SwitchStateSelective {
                field: LssIdentityField::from_offset(cs - 0x40)?,
                value: u32_at(d),
            },
            0x11 => Self::ConfigureNodeId { node_id: b1 },
            0x13 => Self::ConfigureBitTiming { table: b1, index: b2 },
            0x15 => Self::ActivateBitTiming { delay_ms: u16::from_le_bytes([b1, b2]) },
            0x17 => Self::StoreConfiguration,
            0x46..=0x4B => Self::IdentifyRemoteSlave { selector: cs - 0x46, value: u32_at(d) },
            0x4C => Self::IdentifyNonConfigured,
            0x51 => Self::Fastscan { id_number: u32_at(d), bit_check: b5, lss_sub: b6, lss_next: b7 },
            0x5A..=0x5D => Self::InquireIdentity { field: LssIdentityField::from_offset(cs - 0x5A)? },
            0x5E => Self::InquireNodeId,
            _ => return None,
        })
    }

    /// Encodes the 8-byte frame body.
    pub fn encode(&self) -> Result<[u8; 8], EncodeError> {
        Ok(match self {
            Self::SwitchStateGlobal { configuration } => with_bytes(0x04, u8::from(*configuration), 0),
            Self::SwitchStateSelective { field, value } => with_u32(0x40 + field.offset(), *value),
            Self::ConfigureNodeId { node_id } => with_bytes(0x11, *node_id, 0),
            Self::ConfigureBitTiming { table, index } => with_bytes(0x13, *table, *index),
            Self::ActivateBitTiming { delay_ms } => {
                let [a, b] = delay_ms.to_le_bytes();
                with_bytes(0x15, a, b)
            }
            Self::StoreConfiguration => with_bytes(0x17, 0, 0),
            Self::IdentifyRemoteSlave { selector, value } => {
                if *selector > 5 {
                    return Err(EncodeError::InvalidField { field: "selector", value: u32::from(*selector) });
                }
                with_u32(0x46 + selector, *value)
            }
            Self::IdentifyNonConfigured => with_bytes(0x4C, 0, 0),
            Self::Fastscan { id_number, bit_check, lss_sub, lss_next } => {
                let mut out = with_u32(0x51, *id_number);
                out[5] = *bit_check;
                out[6] = *lss_sub;
                out[7] = *lss_next;
                out
            }
            Self::InquireIdentity { field } => with_bytes(0x5A + field.offset(), 0, 0),
            Self::InquireNodeId => with_bytes(0x5E, 0, 0),
        })
    }
}

impl LssResponse {
    /// Decodes an 8-byte response; `None` for unknown command specifiers or short frames.
    pub fn decode(d: &[u8]) -> Option<Self> {
        let d: &[u8; 8] = d.try_into().ok()?;
        let [cs, b1, b2, ..] = *d;
        Some(match cs {
            0x44 => Self::SwitchStateSelective,
            0x11 => Self::ConfigureNodeId { error: b1, spec_error: b2 },
            0x13 => Self::ConfigureBitTiming { error: b1, spec_error: b2 },
            0x17 => Self::StoreConfiguration { error: b1, spec_error: b2 },
            0x4F => Self::IdentifySlave,
            0x50 => Self::IdentifyNonConfiguredSlave,
            0x5A..=0x5D => {
                Self::InquireIdentity { field: LssIdentityField::from_offset(cs - 0x5A)?, value: u32_at(d) }
            }
            0x5E => Self::InquireNodeId { node_id: b1 },
            _ => return None,
        })
    }

    /// Encodes the 8-byte frame body.
    pub fn encode(&self) -> [u8; 8] {
        match self {
            Self::SwitchStateSelective => with_bytes(0x44, 0, 0),
            Self::ConfigureNodeId { error, spec_error } => with_bytes(0x11, *error, *spec_error),
            Self::ConfigureBitTiming { error, spec_error } => with_bytes(0x13, *error, *spec_error),
            Self::StoreConfiguration { error, spec_error } => with_bytes(0x17, *error, *spec_error),
            Self::IdentifySlave => with_bytes(0x4F, 0, 0),
            Self::IdentifyNonConfiguredSlave => with_bytes(0x50, 0, 0),
            Self::InquireIdentity { field, value } => with_u32(0x5A + field.offset(), *value),
            Self::InquireNodeId { node_id } => with_bytes(0x5E, *node_id, 0),
        }
    }
}

impl std::fmt::Display for LssIdentityField {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Vendor => "vendor-ID",
            Self::Product => "product code",
            Self::Revision => "revision",
            Self::Serial => "serial number",
        })
    }
}

impl std::fmt::Display for LssRequest {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::SwitchStateGlobal { configuration: true } => {
                write!(f, "switch state global: configuration")
            }
            Self::SwitchStateGlobal { configuration: false } => write!(f, "switch state global: waiting"),
            Self::SwitchStateSelective { field, value } => {
                write!(f, "switch state selective {field} 0x{value:08X}")
            }
            Self::ConfigureNodeId { node_id } => write!(f, "configure node-ID {node_id}"),
            Self::ConfigureBitTiming { table, index } => {
                write!(f, "configure bit timing table {table} index {index}")
            }
            Self::ActivateBitTiming { delay_ms } => {
                write!(f, "activate bit timing after {delay_ms} ms")
            }
            Self::StoreConfiguration => write!(f, "store configuration"),
            Self::IdentifyRemoteSlave { selector, value } => {
                write!(f, "identify remote slave selector {selector} 0x{value:08X}")
            }
            Self::IdentifyNonConfigured => write!(f, "identify non-configured remote slave"),
            Self::Fastscan { id_number, bit_check, lss_sub, lss_next } => {
                write!(f, "fastscan id 0x{id_number:08X} bit check {bit_check} sub {lss_sub} next {lss_next}")
            }
            Self::InquireIdentity { field } => write!(f, "inquire {field}"),
            Self::InquireNodeId => write!(f, "inquire node-ID"),
        }
    }
}

impl std::fmt::Display for LssResponse {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::SwitchStateSelective => write!(f, "switch state selective: matched"),
            Self::ConfigureNodeId { error, spec_error } => {
                write!(f, "configure node-ID error {error} (spec {spec_error})")
            }
            Self::ConfigureBitTiming { error, spec_error } => {
                write!(f, "configure bit timing error {error} (spec {spec_error})")
            }
            Self::StoreConfiguration { error, spec_error } => {
                write!(f, "store configuration error {error} (spec {spec_error})")
            }
            Self::IdentifySlave => write!(f, "identify slave"),
            Self::IdentifyNonConfiguredSlave => write!(f, "identify non-configured slave"),
            Self::InquireIdentity { field, value } => write!(f, "{field} = 0x{value:08X}"),
            Self::InquireNodeId { node_id } => write!(f, "node-ID = {node_id}"),
        }
    }
}
