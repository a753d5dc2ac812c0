//! The object dictionary: objects (VAR / ARRAY / RECORD) with their entries (index, sub-index,
//! name, data type, access, PDO mappability, default and current value, limits) and the
//! access checks of the SDO server (CiA 301 §7.4, abort codes of specs/canopen.md 3.3).
//!
//! Values are kept as little-endian bytes, as they travel on the bus.

use std::collections::BTreeMap;

use motus_canopen_protocol::SdoAbortCode;

/// A CiA 301 basic data type (the codes of the EDS `DataType` key).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DataType {
    /// 0x0001 BOOLEAN.
    Boolean,
    /// 0x0002 INTEGER8.
    Integer8,
    /// 0x0003 INTEGER16.
    Integer16,
    /// 0x0004 INTEGER32.
    Integer32,
    /// 0x0005 UNSIGNED8.
    Unsigned8,
    /// 0x0006 UNSIGNED16.
    Unsigned16,
    /// 0x0007 UNSIGNED32.
    Unsigned32,
    /// 0x0009 VISIBLE_STRING.
    VisibleString,
}

impl DataType {
    /// The CiA 301 data type code.
    pub fn code(self) -> u16 {
        match self {
            Self::Boolean => 0x0001,
            Self::Integer8 => 0x0002,
            Self::Integer16 => 0x0003,
            Self::Integer32 => 0x0004,
            Self::Unsigned8 => 0x0005,
            Self::Unsigned16 => 0x0006,
            Self::Unsigned32 => 0x0007,
            Self::VisibleString => 0x0009,
        }
    }

    /// Size in bytes of a fixed-size type; `None` for strings.
    pub fn size(self) -> Option<usize> {
        match self {
            Self::Boolean | Self::Integer8 | Self::Unsigned8 => Some(1),
            Self::Integer16 | Self::Unsigned16 => Some(2),
            Self::Integer32 | Self::Unsigned32 => Some(4),
            Self::VisibleString => None,
        }
    }

    /// Whether the type is a signed integer.
    pub fn is_signed(self) -> bool {
        matches!(self, Self::Integer8 | Self::Integer16 | Self::Integer32)
    }

    /// Decodes little-endian bytes of this type as an integer (sign-extended when signed).
    pub fn to_int(self, bytes: &[u8]) -> Option<i64> {
        let size = self.size()?;
        if bytes.len() != size {
            return None;
        }
        let raw = bytes.iter().rev().fold(0u64, |acc, &b| (acc << 8) | u64::from(b));
        let bits = 8 * size as u32;
        Some(if self.is_signed() && raw >> (bits - 1) & 1 == 1 {
            (raw as i64) - (1i64 << bits)
        } else {
            raw as i64
        })
    }

    /// Encodes an integer as little-endian bytes of this type (truncating).
    pub fn from_int(self, value: i64) -> Vec<u8> {
        let size = self.size().unwrap_or(4);
        value.to_le_bytes().iter().take(size).copied().collect()
    }
}

/// Access type of an entry (EDS `AccessType`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// Read only (may change at run time).
    Ro,
    /// Write only.
    Wo,
    /// Read and write.
    Rw,
    /// Constant.
    Const,
}

impl Access {
    /// The EDS spelling.
    pub fn eds(self) -> &'static str {
        match self {
            Self::Ro => "ro",
            Self::Wo => "wo",
            Self::Rw => "rw",
            Self::Const => "const",
        }
    }

    /// Whether an SDO upload is allowed.
    pub fn readable(self) -> bool {
        !matches!(self, Self::Wo)
    }

    /// Whether an SDO download is allowed.
    pub fn writable(self) -> bool {
        matches!(self, Self::Wo | Self::Rw)
    }
}

/// Object code (EDS `ObjectType`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ObjectKind {
    /// 0x7 VAR.
    Var,
    /// 0x8 ARRAY.
    Array,
    /// 0x9 RECORD.
    Record,
}

impl ObjectKind {
    /// The EDS object type code.
    pub fn code(self) -> u8 {
        match self {
            Self::Var => 0x7,
            Self::Array => 0x8,
            Self::Record => 0x9,
        }
    }
}

/// The default value of an entry.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Default {
    /// A fixed integer.
    Int(i64),
    /// An integer plus the node id (EDS `$NODEID+0x...`), e.g. PDO COB-IDs.
    NodeRelative(i64),
    /// A string.
    Text(String),
}

impl Default {
    /// The value for a node id, as bytes of `dt`.
    pub fn bytes(&self, dt: DataType, node_id: u8) -> Vec<u8> {
        match self {
            Self::Int(v) => dt.from_int(*v),
            Self::NodeRelative(v) => dt.from_int(v + i64::from(node_id & 0x7F)),
            Self::Text(t) => t.as_bytes().to_vec(),
        }
    }
}

/// One entry (index, sub-index) of the dictionary.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Entry {
    /// Parameter name.
    pub name: String,
    /// Data type.
    pub data_type: DataType,
    /// Access type.
    pub access: Access,
    /// Whether the entry may be mapped into a PDO.
    pub pdo_mappable: bool,
    /// Default value.
    pub default: Default,
    /// Lowest allowed value (integers), if limited.
    pub low: Option<i64>,
    /// Highest allowed value (integers), if limited.
    pub high: Option<i64>,
    /// Current value (little-endian bytes).
    pub value: Vec<u8>,
}

/// One object: a VAR (sub-index 0 only), an ARRAY or a RECORD.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Object {
    /// Object name.
    pub name: String,
    /// Object code.
    pub kind: ObjectKind,
    /// Entries by sub-index.
    pub entries: BTreeMap<u8, Entry>,
}

/// The object dictionary of one node.
#[derive(Debug, Clone, PartialEq, Eq, core::default::Default)]
pub struct ObjectDictionary {
    objects: BTreeMap<u16, Object>,
}

/// Builder arguments of an entry, kept short at the call sites.
#[derive(Debug, Clone)]
pub struct Spec {
    /// Data type.
    pub data_type: DataType,
    /// Access.
    pub access: Access,
    /// PDO mappable.
    pub pdo: bool,
    /// Default.
    pub default: Default,
    /// Limits (low, high).
    pub limits: (Option<i64>, Option<i64>),
}

impl Spec {
    /// An entry of type `data_type`, access `access`, default `default`, not mappable, no limits.
    pub fn new(data_type: DataType, access: Access, default: i64) -> Self {
        Self { data_type, access, pdo: false, default: Default::Int(default), limits: (None, None) }
    }

    /// Marks the entry PDO-mappable.
    pub fn mappable(mut self) -> Self {
        self.pdo = true;
        self
    }

    /// Sets the limits.
    pub fn limits(mut self, low: i64, high: i64) -> Self {
        self.limits = (Some(low), Some(high));
        self
    }

    /// Makes the default node-relative.
    pub fn node_relative(mut self) -> Self {
        if let Default::Int(v) = self.default {
            self.default = Default::NodeRelative(v);
        }
        self
    }
}

impl ObjectDictionary {
    /// An empty dictionary.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds an object (replacing any object at that index).
    pub fn add_object(&mut self, index: u16, name: &str, kind: ObjectKind) {
        self.objects.insert(index, Object { name: name.to_owned(), kind, entries: BTreeMap::new() });
    }

    /// Adds a VAR object.
    pub fn add_var(&mut self, index: u16, name: &str, spec: Spec) {
        self.add_object(index, name, ObjectKind::Var);
        self.add_entry(index, 0, name, spec);
    }

    /// Adds an entry to an existing object (ignored if the object does not exist).
    pub fn add_entry(&mut self, index: u16, sub: u8, name: &str, spec: Spec) {
        if let Some(obj) = self.objects.get_mut(&index) {
            let value = spec.default.bytes(spec.data_type, 0);
            obj.entries.insert(
                sub,
                Entry {
                    name: name.to_owned(),
                    data_type: spec.data_type,
                    access: spec.access,
                    pdo_mappable: spec.pdo,
                    default: spec.default,
                    low: spec.limits.0,
                    high: spec.limits.1,
                    value,
                },
            );
        }
    }

    /// All objects by index.
    pub fn objects(&self) -> &BTreeMap<u16, Object> {
        &self.objects
    }

    /// One object.
    pub fn object(&self, index: u16) -> Option<&Object> {
        self.objects.get(&index)
    }

    /// One entry.
    pub fn entry(&self, index: u16, sub: u8) -> Option<&Entry> {
        self.objects.get(&index)?.entries.get(&sub)
    }

    /// Locates an entry, with the abort code when it is missing.
    pub fn locate(&self, index: u16, sub: u8) -> Result<&Entry, SdoAbortCode> {
        let obj = self.objects.get(&index).ok_or(SdoAbortCode::ObjectDoesNotExist)?;
        obj.entries.get(&sub).ok_or(SdoAbortCode::SubIndexDoesNotExist)
    }

    /// Resets the values of every entry with index in `range` to its default for `node_id`.
    pub fn reset(&mut self, range: std::ops::RangeInclusive<u16>, node_id: u8) {
        for (_, obj) in self.objects.range_mut(range) {
            for e in obj.entries.values_mut() {
                e.value = e.default.bytes(e.data_type, node_id);
            }
        }
    }

    /// The value as an integer (0 when missing).
    pub fn int(&self, index: u16, sub: u8) -> i64 {
        self.entry(index, sub).and_then(|e| e.data_type.to_int(&e.value)).unwrap_or(0)
    }

    /// The value as u32 (two's complement of signed values).
    pub fn u32(&self, index: u16, sub: u8) -> u32 {
        self.int(index, sub) as u32
    }

    /// The raw bytes.
    pub fn bytes(&self, index: u16, sub: u8) -> Option<&[u8]> {
        self.entry(index, sub).map(|e| e.value.as_slice())
    }

    /// Sets an integer value without checks (device-side update of a live value).
    pub fn set_int(&mut self, index: u16, sub: u8, value: i64) {
        if let Some(e) = self.objects.get_mut(&index).and_then(|o| o.entries.get_mut(&sub)) {
            e.value = e.data_type.from_int(value);
        }
    }

    /// Sets raw bytes without checks.
    pub fn set_bytes(&mut self, index: u16, sub: u8, value: &[u8]) {
        if let Some(e) = self.objects.get_mut(&index).and_then(|o| o.entries.get_mut(&sub)) {
            e.value = value.to_vec();
        }
    }

    /// SDO upload checks: the entry exists and is readable; returns its bytes.
    pub fn read(&self, index: u16, sub: u8) -> Result<Vec<u8>, SdoAbortCode> {
        let e = self.locate(index, sub)?;
        if !e.access.readable() {
            return Err(SdoAbortCode::WriteOnly);
        }
        Ok(e.value.clone())
    }

    /// SDO download checks: exists, writable, length, limits. Returns the decoded integer
    /// (`None` for strings) without storing anything.
    pub fn check_write(&self, index: u16, sub: u8, data: &[u8]) -> Result<Option<i64>, SdoAbortCode> {
        let e = self.locate(index, sub)?;
        if !e.access.writable() {
            return Err(SdoAbortCode::ReadOnly);
        }
        let Some(size) = e.data_type.size() else {
            return Ok(None);
        };
        if data.len() != size {
            return Err(SdoAbortCode::TypeLengthMismatch);
        }
        let v = e.data_type.to_int(data).ok_or(SdoAbortCode::TypeLengthMismatch)?;
        if e.data_type == DataType::Boolean && v > 1 {
            return Err(SdoAbortCode::InvalidValue);
        }
        if e.high.is_some_and(|h| v > h) {
            return Err(SdoAbortCode::ValueTooHigh);
        }
        if e.low.is_some_and(|l| v < l) {
            return Err(SdoAbortCode::ValueTooLow);
        }
        Ok(Some(v))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    fn od() -> ObjectDictionary {
        let mut od = ObjectDictionary::new();
        od.add_var(
            0x6081,
            "Profile velocity",
            Spec::new(DataType::Unsigned32, Access::Rw, 248).limits(1, 5000),
        );
        od.add_var(0x6041, "Statusword", Spec::new(DataType::Unsigned16, Access::Ro, 0).mappable());
        od.add_var(0x200B, "Set position", Spec::new(DataType::Unsigned32, Access::Wo, 0));
        od.add_object(0x1800, "TPDO1", ObjectKind::Record);
        od.add_entry(
            0x1800,
            1,
            "COB-ID",
            Spec::new(DataType::Unsigned32, Access::Rw, 0x4000_0180).node_relative(),
        );
        od
    }

    #[test]
    fn access_checks_give_the_named_abort_codes() {
        let od = od();
        assert_eq!(od.read(0x6082, 0), Err(SdoAbortCode::ObjectDoesNotExist));
        assert_eq!(od.read(0x6081, 1), Err(SdoAbortCode::SubIndexDoesNotExist));
        assert_eq!(od.read(0x200B, 0), Err(SdoAbortCode::WriteOnly));
        assert_eq!(od.check_write(0x6041, 0, &[0, 0]), Err(SdoAbortCode::ReadOnly));
        assert_eq!(od.check_write(0x6081, 0, &[1, 0]), Err(SdoAbortCode::TypeLengthMismatch));
        // 5001 = 0x1389 LE 89 13 00 00 > high 5000.
        assert_eq!(od.check_write(0x6081, 0, &[0x89, 0x13, 0, 0]), Err(SdoAbortCode::ValueTooHigh));
        assert_eq!(od.check_write(0x6081, 0, &[0, 0, 0, 0]), Err(SdoAbortCode::ValueTooLow));
        assert_eq!(od.check_write(0x6081, 0, &[0x88, 0x13, 0, 0]), Ok(Some(5000)));
    }

    #[test]
    fn node_relative_defaults_follow_the_node_id() {
        let mut od = od();
        od.reset(0x1000..=0x1FFF, 3);
        assert_eq!(od.u32(0x1800, 1), 0x4000_0183);
        assert_eq!(od.bytes(0x1800, 1), Some(&[0x83, 0x01, 0x00, 0x40][..]));
    }

    #[test]
    fn signed_values_decode_with_sign() {
        assert_eq!(DataType::Integer8.to_int(&[0xFA]), Some(-6));
        assert_eq!(DataType::Integer32.to_int(&[0xFF, 0xFF, 0xFF, 0xFF]), Some(-1));
        assert_eq!(DataType::Unsigned32.to_int(&[0xFF, 0xFF, 0xFF, 0xFF]), Some(0xFFFF_FFFF));
        assert_eq!(DataType::Integer16.from_int(-2), vec![0xFE, 0xFF]);
    }
}
