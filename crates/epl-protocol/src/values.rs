//! Process-value extraction (sans-IO): a [`ValueMap`] names, per node, values at PRes
//! payload byte offsets (little-endian i8/i16/i32/u8/u16/u32/f32) and extracts them from a
//! PRes payload. Deserialisable from TOML for `--map` files:
//!
//! ```toml
//! [[node]]
//! node = 1
//! label = "X axis"
//! values = [
//!   { name = "position", offset = 16, type = "i32" },
//!   { name = "speed", offset = 20, type = "i32" },
//! ]
//! ```
//!
//! Offsets count from the first payload byte (frame byte 24), as the juggler's "position at
//! PRes payload offset 16" does (`specs/powerlink.md`, "From the seed").

use std::collections::BTreeSet;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::frame::{EplFrame, Message};

/// The type of a mapped value (all little-endian).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ValueType {
    /// Signed 8 bit.
    I8,
    /// Signed 16 bit.
    I16,
    /// Signed 32 bit.
    I32,
    /// Unsigned 8 bit.
    U8,
    /// Unsigned 16 bit.
    U16,
    /// Unsigned 32 bit.
    U32,
    /// IEEE 754 single.
    F32,
}

impl ValueType {
    /// Size in bytes.
    pub fn width(self) -> usize {
        match self {
            ValueType::I8 | ValueType::U8 => 1,
            ValueType::I16 | ValueType::U16 => 2,
            ValueType::I32 | ValueType::U32 | ValueType::F32 => 4,
        }
    }
}

/// An extracted value. JSON: the plain number.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Value {
    /// i8.
    I8(i8),
    /// i16.
    I16(i16),
    /// i32.
    I32(i32),
    /// u8.
    U8(u8),
    /// u16.
    U16(u16),
    /// u32.
    U32(u32),
    /// f32.
    F32(f32),
}

impl Value {
    /// The value as f64 (exact for every type).
    pub fn as_f64(self) -> f64 {
        match self {
            Value::I8(v) => v.into(),
            Value::I16(v) => v.into(),
            Value::I32(v) => v.into(),
            Value::U8(v) => v.into(),
            Value::U16(v) => v.into(),
            Value::U32(v) => v.into(),
            Value::F32(v) => v.into(),
        }
    }
}

/// One mapped value of a node.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ValueSpec {
    /// Name (unique within the node).
    pub name: String,
    /// Byte offset in the PRes payload.
    pub offset: usize,
    /// Type.
    #[serde(rename = "type")]
    pub ty: ValueType,
}

impl ValueSpec {
    /// Reads this value from `payload`.
    pub fn read(&self, node: u8, payload: &[u8]) -> Result<Value, ExtractError> {
        let w = self.ty.width();
        let bytes =
            self.offset.checked_add(w).and_then(|end| payload.get(self.offset..end)).ok_or_else(|| {
                ExtractError::OutOfRange {
                    node,
                    name: self.name.clone(),
                    offset: self.offset,
                    width: w,
                    payload_len: payload.len(),
                }
            })?;
        let mut b = [0u8; 4];
        for (d, s) in b.iter_mut().zip(bytes) {
            *d = *s;
        }
        let [b0, b1, b2, b3] = b;
        Ok(match self.ty {
            ValueType::I8 => Value::I8(i8::from_le_bytes([b0])),
            ValueType::U8 => Value::U8(b0),
            ValueType::I16 => Value::I16(i16::from_le_bytes([b0, b1])),
            ValueType::U16 => Value::U16(u16::from_le_bytes([b0, b1])),
            ValueType::I32 => Value::I32(i32::from_le_bytes(b)),
            ValueType::U32 => Value::U32(u32::from_le_bytes([b0, b1, b2, b3])),
            ValueType::F32 => Value::F32(f32::from_le_bytes(b)),
        })
    }
}

/// The values of one node.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodeValues {
    /// Node ID (source of the PRes).
    pub node: u8,
    /// Optional human label ("X axis").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
    /// The values.
    pub values: Vec<ValueSpec>,
}

/// Per-node value maps.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ValueMap {
    /// The nodes (TOML `[[node]]`).
    #[serde(rename = "node", default)]
    pub nodes: Vec<NodeValues>,
}

/// An extracted, named value.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sample<'a> {
    /// Value name from the map.
    pub name: &'a str,
    /// The value.
    pub value: Value,
}

/// Why a value map is not usable.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ValueMapError {
    /// TOML syntax or schema error.
    #[error("value map: {0}")]
    Toml(String),
    /// A node appears twice.
    #[error("value map: node {0} appears more than once")]
    DuplicateNode(u8),
    /// A value name appears twice for one node.
    #[error("value map: node {node} has two values named {name:?}")]
    DuplicateName {
        /// Node.
        node: u8,
        /// Name.
        name: String,
    },
}

/// Why values could not be extracted.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ExtractError {
    /// A value lies (partly) beyond the payload.
    #[error("node {node} value {name:?}: bytes {offset}..{} beyond the {payload_len}-byte PRes payload", offset + width)]
    OutOfRange {
        /// Node.
        node: u8,
        /// Value name.
        name: String,
        /// Offset in the payload.
        offset: usize,
        /// Value width.
        width: usize,
        /// Payload length.
        payload_len: usize,
    },
    /// The map has no entry for this node.
    #[error("node {0} is not in the value map")]
    NodeNotMapped(u8),
}

impl ValueMap {
    /// Parses and checks a TOML map.
    pub fn from_toml(text: &str) -> Result<Self, ValueMapError> {
        let map: ValueMap = toml::from_str(text).map_err(|e| ValueMapError::Toml(e.to_string()))?;
        map.validate()?;
        Ok(map)
    }

    /// Checks for duplicate nodes and names.
    pub fn validate(&self) -> Result<(), ValueMapError> {
        let mut nodes = BTreeSet::new();
        for n in &self.nodes {
            if !nodes.insert(n.node) {
                return Err(ValueMapError::DuplicateNode(n.node));
            }
            let mut names = BTreeSet::new();
            for v in &n.values {
                if !names.insert(v.name.as_str()) {
                    return Err(ValueMapError::DuplicateName { node: n.node, name: v.name.clone() });
                }
            }
        }
        Ok(())
    }

    /// The values mapped for `node`.
    pub fn node(&self, node: u8) -> Option<&NodeValues> {
        self.nodes.iter().find(|n| n.node == node)
    }

    /// Extracts every value of `node` from a PRes payload into `out` (cleared first).
    pub fn extract_into<'a>(
        &'a self,
        node: u8,
        payload: &[u8],
        out: &mut Vec<Sample<'a>>,
    ) -> Result<(), ExtractError> {
        out.clear();
        let n = self.node(node).ok_or(ExtractError::NodeNotMapped(node))?;
        for v in &n.values {
            out.push(Sample { name: &v.name, value: v.read(node, payload)? });
        }
        Ok(())
    }

    /// Extracts every value of `node` from a PRes payload.
    pub fn extract(&self, node: u8, payload: &[u8]) -> Result<Vec<Sample<'_>>, ExtractError> {
        let mut out = Vec::new();
        self.extract_into(node, payload, &mut out)?;
        Ok(out)
    }

    /// Extracts the values carried by `frame`: `Ok(None)` unless it is a PRes of a mapped node.
    pub fn extract_frame(&self, frame: &EplFrame) -> Result<Option<Vec<Sample<'_>>>, ExtractError> {
        match &frame.message {
            Message::PRes(p) if self.node(frame.src_node).is_some() => {
                self.extract(frame.src_node, &p.payload).map(Some)
            }
            _ => Ok(None),
        }
    }
}
