//! CiA 306 EDS (electronic data sheet) loading: the INI file's object sections
//! (`[1018]`, `[1018sub1]`), names, data types, access, default values and PDO mapping
//! flags, as an [`ObjectDictionary`] with typed decode/encode of values.

use std::collections::BTreeMap;
use std::fmt;

/// EDS parsing errors (the file is the culprit, with its line).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum EdsError {
    /// A line that is neither a section, a key=value, a comment nor blank.
    #[error("EDS line {line}: cannot parse {text:?}")]
    Syntax {
        /// 1-based line number.
        line: usize,
        /// The line.
        text: String,
    },
    /// A numeric field that is not a number.
    #[error("EDS section [{section}]: bad {key} {value:?}")]
    BadField {
        /// Section name.
        section: String,
        /// Key.
        key: &'static str,
        /// Value.
        value: String,
    },
    /// The file could not be read.
    #[error("cannot read EDS {path}: {reason}")]
    Io {
        /// Path.
        path: String,
        /// OS error.
        reason: String,
    },
}

/// Value could not be converted from or to the object's type.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ValueError {
    /// Raw bytes of the wrong length for the type.
    #[error("{data_type}: {len} bytes, want {want}")]
    Length {
        /// Type.
        data_type: DataType,
        /// Length received.
        len: usize,
        /// Length wanted.
        want: usize,
    },
    /// Text that does not parse as the type.
    #[error("{data_type}: cannot parse {text:?}")]
    Parse {
        /// Type.
        data_type: DataType,
        /// Text.
        text: String,
    },
}

/// CiA 301 basic data types (table 44), by their object index.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DataType {
    /// 0x0001.
    Boolean,
    /// 0x0002.
    Integer8,
    /// 0x0003.
    Integer16,
    /// 0x0004.
    Integer32,
    /// 0x0005.
    Unsigned8,
    /// 0x0006.
    Unsigned16,
    /// 0x0007.
    Unsigned32,
    /// 0x0008.
    Real32,
    /// 0x0009.
    VisibleString,
    /// 0x000A.
    OctetString,
    /// 0x000B.
    UnicodeString,
    /// 0x000F.
    Domain,
    /// 0x0010.
    Integer24,
    /// 0x0011.
    Real64,
    /// 0x0015.
    Integer64,
    /// 0x0016.
    Unsigned24,
    /// 0x001B.
    Unsigned64,
    /// Any other code (kept raw; values stay bytes).
    Unknown(u16),
}

/// A typed object value.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// BOOLEAN.
    Bool(bool),
    /// INTEGERn.
    Int(i64),
    /// UNSIGNEDn.
    Uint(u64),
    /// REAL32 / REAL64.
    Real(f64),
    /// VISIBLE_STRING / UNICODE_STRING (lossy).
    Text(String),
    /// OCTET_STRING, DOMAIN, unknown types.
    Bytes(Vec<u8>),
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Bool(b) => write!(f, "{b}"),
            Self::Int(v) => write!(f, "{v}"),
            Self::Uint(v) => write!(f, "{v} (0x{v:X})"),
            Self::Real(v) => write!(f, "{v}"),
            Self::Text(s) => write!(f, "{s:?}"),
            Self::Bytes(b) => {
                f.write_str("[")?;
                for (i, x) in b.iter().enumerate() {
                    write!(f, "{}{x:02X}", if i == 0 { "" } else { " " })?;
                }
                f.write_str("]")
            }
        }
    }
}

impl fmt::Display for DataType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Unknown(c) => write!(f, "data type 0x{c:04X}"),
            other => write!(f, "{other:?}"),
        }
    }
}

impl DataType {
    /// From the EDS `DataType` code.
    pub fn from_code(code: u16) -> Self {
        match code {
            0x01 => Self::Boolean,
            0x02 => Self::Integer8,
            0x03 => Self::Integer16,
            0x04 => Self::Integer32,
            0x05 => Self::Unsigned8,
            0x06 => Self::Unsigned16,
            0x07 => Self::Unsigned32,
            0x08 => Self::Real32,
            0x09 => Self::VisibleString,
            0x0A => Self::OctetString,
            0x0B => Self::UnicodeString,
            0x0F => Self::Domain,
            0x10 => Self::Integer24,
            0x11 => Self::Real64,
            0x15 => Self::Integer64,
            0x16 => Self::Unsigned24,
            0x1B => Self::Unsigned64,
            other => Self::Unknown(other),
        }
    }

    /// Size in bytes of fixed-size types.
    pub fn size(self) -> Option<usize> {
        Some(match self {
            Self::Boolean | Self::Integer8 | Self::Unsigned8 => 1,
            Self::Integer16 | Self::Unsigned16 => 2,
            Self::Integer24 | Self::Unsigned24 => 3,
            Self::Integer32 | Self::Unsigned32 | Self::Real32 => 4,
            Self::Integer64 | Self::Unsigned64 | Self::Real64 => 8,
            _ => return None,
        })
    }

    fn signed(self) -> bool {
        matches!(self, Self::Integer8 | Self::Integer16 | Self::Integer24 | Self::Integer32 | Self::Integer64)
    }

    /// Decodes raw little-endian bytes (as an SDO upload returns them).
    pub fn decode(self, raw: &[u8]) -> Result<Value, ValueError> {
        if let Some(want) = self.size() {
            if raw.len() != want {
                return Err(ValueError::Length { data_type: self, len: raw.len(), want });
            }
            let mut buf = [0u8; 8];
            buf.get_mut(..want).unwrap_or(&mut []).copy_from_slice(raw);
            let u = u64::from_le_bytes(buf);
            return Ok(match self {
                Self::Boolean => Value::Bool(u != 0),
                Self::Real32 => Value::Real(f64::from(f32::from_bits(u32::try_from(u).unwrap_or(0)))),
                Self::Real64 => Value::Real(f64::from_bits(u)),
                t if t.signed() => {
                    Value::Int(crate::pdo::sign_extend(u, u8::try_from(want * 8).unwrap_or(64)))
                }
                _ => Value::Uint(u),
            });
        }
        Ok(match self {
            Self::VisibleString => {
                Value::Text(String::from_utf8_lossy(raw).trim_end_matches('\0').to_owned())
            }
            Self::UnicodeString => {
                let units: Vec<u16> =
                    raw.chunks_exact(2).filter_map(|c| c.try_into().ok().map(u16::from_le_bytes)).collect();
                Value::Text(String::from_utf16_lossy(&units))
            }
            _ => Value::Bytes(raw.to_vec()),
        })
    }

    /// Encodes a value written as text (decimal, `0x` hex, `-` signed, `true`/`false`,
    /// strings verbatim, octet strings / domains as hex digits) into little-endian bytes.
    pub fn encode_text(self, text: &str) -> Result<Vec<u8>, ValueError> {
        let t = text.trim();
        let bad = || ValueError::Parse { data_type: self, text: text.to_owned() };
        if let Some(size) = self.size() {
            let bytes: [u8; 8] = match self {
                Self::Boolean => match t.to_ascii_lowercase().as_str() {
                    "true" | "1" => 1u64.to_le_bytes(),
                    "false" | "0" => 0u64.to_le_bytes(),
                    _ => return Err(bad()),
                },
                Self::Real32 => u64::from(t.parse::<f32>().map_err(|_| bad())?.to_bits()).to_le_bytes(),
                Self::Real64 => t.parse::<f64>().map_err(|_| bad())?.to_bits().to_le_bytes(),
                ty => {
                    let v = parse_int(t).ok_or_else(bad)?;
                    let bits = size * 8;
                    let ok = if ty.signed() {
                        bits >= 64 || (v >= -(1i128 << (bits - 1)) && v < (1i128 << (bits - 1)))
                    } else {
                        v >= 0 && (bits >= 64 && v <= i128::from(u64::MAX) || v < (1i128 << bits))
                    };
                    if !ok {
                        return Err(bad());
                    }
                    (v as u64).to_le_bytes()
                }
            };
            return Ok(bytes.get(..size).unwrap_or(&[]).to_vec());
        }
        match self {
            Self::VisibleString => Ok(text.as_bytes().to_vec()),
            Self::UnicodeString => Ok(text.encode_utf16().flat_map(u16::to_le_bytes).collect()),
            _ => {
                let digits: Vec<u8> = t.bytes().filter(|b| !b.is_ascii_whitespace()).collect();
                if !digits.chunks_exact(2).remainder().is_empty() {
                    return Err(bad());
                }
                digits
                    .chunks_exact(2)
                    .map(|p| {
                        std::str::from_utf8(p)
                            .ok()
                            .and_then(|s| u8::from_str_radix(s, 16).ok())
                            .ok_or_else(bad)
                    })
                    .collect()
            }
        }
    }
}

/// Parses an EDS integer: decimal, `0x` hex, optional `-`, optional leading `0` octal is
/// NOT applied (CiA 306 allows it, but EDS writers use leading zeros in decimal).
fn parse_int(t: &str) -> Option<i128> {
    let (neg, body) = match t.strip_prefix('-') {
        Some(b) => (true, b),
        None => (false, t),
    };
    let v = match body.strip_prefix("0x").or_else(|| body.strip_prefix("0X")) {
        Some(h) => i128::from_str_radix(h, 16).ok()?,
        None => body.parse::<i128>().ok()?,
    };
    Some(if neg { -v } else { v })
}

/// Access type of an object (EDS `AccessType`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// `ro`.
    ReadOnly,
    /// `wo`.
    WriteOnly,
    /// `rw`, `rwr`, `rww`.
    ReadWrite,
    /// `const`.
    Const,
}

impl Access {
    fn parse(s: &str) -> Self {
        match s.trim().to_ascii_lowercase().as_str() {
            "ro" => Self::ReadOnly,
            "wo" => Self::WriteOnly,
            "const" => Self::Const,
            _ => Self::ReadWrite,
        }
    }

    /// Whether an SDO upload is allowed.
    pub fn readable(self) -> bool {
        self != Self::WriteOnly
    }

    /// Whether an SDO download is allowed.
    pub fn writable(self) -> bool {
        matches!(self, Self::WriteOnly | Self::ReadWrite)
    }
}

/// One readable/writable entry (a VAR object, or a sub-object of an ARRAY / RECORD).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Variable {
    /// Object index.
    pub index: u16,
    /// Sub-index (0 for a VAR).
    pub sub: u8,
    /// Its `ParameterName`.
    pub name: String,
    /// Name of the parent object for sub-objects (None for a VAR).
    pub parent: Option<String>,
    /// Data type.
    pub data_type: DataType,
    /// Access.
    pub access: Access,
    /// `DefaultValue` text, verbatim (may contain `$NODEID`).
    pub default: Option<String>,
    /// `PDOMapping=1`.
    pub pdo_mappable: bool,
}

impl Variable {
    /// `Parent.Name` for sub-objects, the name for VARs.
    pub fn full_name(&self) -> String {
        match &self.parent {
            Some(p) => format!("{p}.{}", self.name),
            None => self.name.clone(),
        }
    }

    /// The default value for a node, resolving `$NODEID+...` expressions.
    pub fn default_value(&self, node_id: u8) -> Option<Result<Value, ValueError>> {
        let text = self.default.as_deref()?;
        let resolved = resolve_node_id(text, node_id);
        Some(self.data_type.encode_text(&resolved).and_then(|raw| self.data_type.decode(&raw)))
    }
}

fn resolve_node_id(text: &str, node_id: u8) -> String {
    let lower = text.to_ascii_lowercase();
    if !lower.contains("$nodeid") {
        return text.to_owned();
    }
    let sum: Option<i128> = lower
        .replace("$nodeid", &node_id.to_string())
        .split('+')
        .map(|t| parse_int(t.trim()))
        .try_fold(0i128, |acc, v| v.map(|v| acc + v));
    sum.map_or_else(|| text.to_owned(), |v| v.to_string())
}

/// An object dictionary loaded from an EDS.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ObjectDictionary {
    vars: BTreeMap<(u16, u8), Variable>,
    /// `[DeviceInfo]` entries, verbatim.
    pub device_info: BTreeMap<String, String>,
}

type Sections = BTreeMap<String, BTreeMap<String, String>>;

fn parse_ini(text: &str) -> Result<Sections, EdsError> {
    let mut out: Sections = BTreeMap::new();
    let mut current: Option<String> = None;
    for (n, raw) in text.lines().enumerate() {
        let line = raw.trim().trim_start_matches('\u{feff}');
        if line.is_empty() || line.starts_with(';') || line.starts_with('#') {
            continue;
        }
        if let Some(rest) = line.strip_prefix('[') {
            let name = rest.split(']').next().unwrap_or("").trim().to_ascii_lowercase();
            out.entry(name.clone()).or_default();
            current = Some(name);
            continue;
        }
        let syntax = || EdsError::Syntax { line: n + 1, text: raw.to_owned() };
        let (k, v) = line.split_once('=').ok_or_else(syntax)?;
        let section = current.as_ref().ok_or_else(syntax)?;
        let v = v.split(';').next().unwrap_or("").trim();
        out.entry(section.clone()).or_default().insert(k.trim().to_ascii_lowercase(), v.to_owned());
    }
    Ok(out)
}

fn num(section: &str, key: &'static str, value: &str) -> Result<u32, EdsError> {
    parse_int(value.trim()).and_then(|v| u32::try_from(v).ok()).ok_or_else(|| EdsError::BadField {
        section: section.to_owned(),
        key,
        value: value.to_owned(),
    })
}

impl ObjectDictionary {
    /// Parses EDS text.
    pub fn parse(text: &str) -> Result<Self, EdsError> {
        let sections = parse_ini(text)?;
        let mut od = ObjectDictionary {
            device_info: sections.get("deviceinfo").cloned().unwrap_or_default(),
            ..Default::default()
        };
        for (name, keys) in &sections {
            let Some(index) = (name.len() == 4).then(|| u16::from_str_radix(name, 16).ok()).flatten() else {
                continue;
            };
            let object_type =
                keys.get("objecttype").map(|v| num(name, "ObjectType", v)).transpose()?.unwrap_or(7);
            let obj_name = keys.get("parametername").cloned().unwrap_or_default();
            if object_type == 7 {
                od.insert(index, 0, None, name, keys)?;
                continue;
            }
            // ARRAY (8) / RECORD (9): explicit [XXXXsubN] sections.
            let prefix = format!("{name}sub");
            for (sname, skeys) in sections.range(prefix.clone()..) {
                let Some(sub_text) = sname.strip_prefix(&prefix) else { break };
                let sub = u8::from_str_radix(sub_text, 16).map_err(|_| EdsError::BadField {
                    section: sname.clone(),
                    key: "sub-index",
                    value: sub_text.to_owned(),
                })?;
                od.insert(index, sub, Some(obj_name.clone()), sname, skeys)?;
            }
            // CompactSubObj=N: sub 0 = count, subs 1..=N share the object's type.
            if let Some(n) = keys.get("compactsubobj").map(|v| num(name, "CompactSubObj", v)).transpose()? {
                let dt = keys.get("datatype").map(|v| num(name, "DataType", v)).transpose()?.unwrap_or(7);
                od.add(Variable {
                    index,
                    sub: 0,
                    name: "NrOfObjects".into(),
                    parent: Some(obj_name.clone()),
                    data_type: DataType::Unsigned8,
                    access: Access::ReadOnly,
                    default: Some(n.to_string()),
                    pdo_mappable: false,
                });
                for sub in 1..=n.min(254) {
                    let sub = u8::try_from(sub).unwrap_or(u8::MAX);
                    od.add(Variable {
                        index,
                        sub,
                        name: format!("{obj_name}{sub}"),
                        parent: Some(obj_name.clone()),
                        data_type: DataType::from_code(u16::try_from(dt).unwrap_or(0)),
                        access: keys.get("accesstype").map_or(Access::ReadWrite, |a| Access::parse(a)),
                        default: keys.get("defaultvalue").cloned(),
                        pdo_mappable: keys.get("pdomapping").is_some_and(|v| v.trim() == "1"),
                    });
                }
            }
        }
        Ok(od)
    }

    /// Reads and parses an EDS file.
    pub fn load(path: &std::path::Path) -> Result<Self, EdsError> {
        let text = std::fs::read(path)
            .map_err(|e| EdsError::Io { path: path.display().to_string(), reason: e.to_string() })?;
        Self::parse(&String::from_utf8_lossy(&text))
    }

    fn insert(
        &mut self,
        index: u16,
        sub: u8,
        parent: Option<String>,
        section: &str,
        keys: &BTreeMap<String, String>,
    ) -> Result<(), EdsError> {
        let dt = keys.get("datatype").map(|v| num(section, "DataType", v)).transpose()?.unwrap_or(0);
        let data_type = DataType::from_code(u16::try_from(dt).map_err(|_| EdsError::BadField {
            section: section.to_owned(),
            key: "DataType",
            value: dt.to_string(),
        })?);
        self.add(Variable {
            index,
            sub,
            name: keys.get("parametername").cloned().unwrap_or_default(),
            parent,
            data_type,
            access: keys.get("accesstype").map_or(Access::ReadWrite, |a| Access::parse(a)),
            default: keys.get("defaultvalue").filter(|v| !v.is_empty()).cloned(),
            pdo_mappable: keys.get("pdomapping").is_some_and(|v| v.trim() == "1"),
        });
        Ok(())
    }

    /// Adds (or replaces) an entry.
    pub fn add(&mut self, var: Variable) {
        self.vars.insert((var.index, var.sub), var);
    }

    /// The entry at `index:sub`.
    pub fn lookup(&self, index: u16, sub: u8) -> Option<&Variable> {
        self.vars.get(&(index, sub))
    }

    /// The entry whose name or `Parent.Name` equals `name` (ASCII case-insensitive).
    pub fn find(&self, name: &str) -> Option<&Variable> {
        self.vars.values().find(|v| {
            v.full_name().eq_ignore_ascii_case(name)
                || (v.parent.is_none() && v.name.eq_ignore_ascii_case(name))
        })
    }

    /// Every entry in (index, sub) order.
    pub fn iter(&self) -> impl Iterator<Item = &Variable> {
        self.vars.values()
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.vars.len()
    }

    /// Whether there are no entries.
    pub fn is_empty(&self) -> bool {
        self.vars.is_empty()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn decode_and_encode() {
        // INTEGER32 -1000 = 0xFFFFFC18 LE.
        assert_eq!(DataType::Integer32.decode(&[0x18, 0xFC, 0xFF, 0xFF]).unwrap(), Value::Int(-1000));
        assert_eq!(DataType::Integer32.encode_text("-1000").unwrap(), vec![0x18, 0xFC, 0xFF, 0xFF]);
        assert_eq!(DataType::Unsigned16.encode_text("0x6041").unwrap(), vec![0x41, 0x60]);
        assert!(DataType::Unsigned8.encode_text("256").is_err());
        assert!(DataType::Integer8.encode_text("-129").is_err());
        assert_eq!(DataType::Integer8.decode(&[0xFF]).unwrap(), Value::Int(-1));
        assert_eq!(DataType::Real32.decode(&1.5f32.to_le_bytes()).unwrap(), Value::Real(1.5));
        assert_eq!(DataType::VisibleString.decode(b"abc\0").unwrap(), Value::Text("abc".into()));
        assert_eq!(DataType::Domain.encode_text("01 ab").unwrap(), vec![0x01, 0xAB]);
        assert!(matches!(DataType::Unsigned16.decode(&[1]), Err(ValueError::Length { want: 2, .. })));
        assert_eq!(resolve_node_id("$NODEID+0x180", 5), "389");
    }
}
