//! One object-dictionary entry (an index/subindex pair) and one object (an index with its
//! subindices): data type, access, PDO mappability, value and value range.

use std::borrow::Cow;
use std::collections::BTreeMap;

use crate::object_access::SdoAbortCode;

/// A POWERLINK/CANopen basic data type (EPSG DS 301 / CiA 301 data type codes, as the XDD's
/// `dataType` attribute writes them).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DataType {
    /// BOOLEAN (0x0001): one byte, 0 or 1 (a 1-bit entry in a PDO mapping).
    Boolean,
    /// INTEGER8 (0x0002).
    Integer8,
    /// INTEGER16 (0x0003).
    Integer16,
    /// INTEGER32 (0x0004).
    Integer32,
    /// UNSIGNED8 (0x0005).
    Unsigned8,
    /// UNSIGNED16 (0x0006).
    Unsigned16,
    /// UNSIGNED32 (0x0007).
    Unsigned32,
    /// REAL32 (0x0008), IEEE 754 single.
    Real32,
    /// VISIBLE_STRING (0x0009): variable length, up to the entry's capacity.
    VisibleString,
    /// OCTET_STRING (0x000A): variable length, up to the entry's capacity.
    OctetString,
    /// DOMAIN (0x000F): variable length, up to the entry's capacity.
    Domain,
    /// REAL64 (0x0011), IEEE 754 double.
    Real64,
    /// INTEGER64 (0x0015).
    Integer64,
    /// UNSIGNED64 (0x001B), e.g. a PDO mapping entry.
    Unsigned64,
}

impl DataType {
    /// The data type code (XDD `dataType`, e.g. 0x0007 for UNSIGNED32).
    pub fn code(self) -> u16 {
        match self {
            DataType::Boolean => 0x0001,
            DataType::Integer8 => 0x0002,
            DataType::Integer16 => 0x0003,
            DataType::Integer32 => 0x0004,
            DataType::Unsigned8 => 0x0005,
            DataType::Unsigned16 => 0x0006,
            DataType::Unsigned32 => 0x0007,
            DataType::Real32 => 0x0008,
            DataType::VisibleString => 0x0009,
            DataType::OctetString => 0x000A,
            DataType::Domain => 0x000F,
            DataType::Real64 => 0x0011,
            DataType::Integer64 => 0x0015,
            DataType::Unsigned64 => 0x001B,
        }
    }

    /// The data type of a code, if it is one of these.
    pub fn from_code(code: u16) -> Option<Self> {
        Some(match code {
            0x0001 => DataType::Boolean,
            0x0002 => DataType::Integer8,
            0x0003 => DataType::Integer16,
            0x0004 => DataType::Integer32,
            0x0005 => DataType::Unsigned8,
            0x0006 => DataType::Unsigned16,
            0x0007 => DataType::Unsigned32,
            0x0008 => DataType::Real32,
            0x0009 => DataType::VisibleString,
            0x000A => DataType::OctetString,
            0x000F => DataType::Domain,
            0x0011 => DataType::Real64,
            0x0015 => DataType::Integer64,
            0x001B => DataType::Unsigned64,
            _ => return None,
        })
    }

    /// Size in bytes of a fixed-size type; `None` for strings and domains.
    pub fn size(self) -> Option<usize> {
        match self {
            DataType::Boolean | DataType::Integer8 | DataType::Unsigned8 => Some(1),
            DataType::Integer16 | DataType::Unsigned16 => Some(2),
            DataType::Integer32 | DataType::Unsigned32 | DataType::Real32 => Some(4),
            DataType::Integer64 | DataType::Unsigned64 | DataType::Real64 => Some(8),
            DataType::VisibleString | DataType::OctetString | DataType::Domain => None,
        }
    }

    /// Whether values are signed integers.
    fn is_signed(self) -> bool {
        matches!(self, DataType::Integer8 | DataType::Integer16 | DataType::Integer32 | DataType::Integer64)
    }

    /// Whether values are integers (BOOLEAN counts as one: 0 or 1).
    fn is_integer(self) -> bool {
        matches!(
            self,
            DataType::Boolean
                | DataType::Integer8
                | DataType::Integer16
                | DataType::Integer32
                | DataType::Integer64
                | DataType::Unsigned8
                | DataType::Unsigned16
                | DataType::Unsigned32
                | DataType::Unsigned64
        )
    }
}

/// Access to an entry over SDO (the XDD's `accessType`). The device itself (the runtime)
/// may update any entry with [`ObjectDictionary::set`](super::ObjectDictionary::set).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Access {
    /// `ro`: read only (the device may change the value).
    ReadOnly,
    /// `wo`: write only.
    WriteOnly,
    /// `rw`: read and write.
    ReadWrite,
    /// `const`: read only, never changes.
    Const,
}

impl Access {
    /// Whether an SDO client may read the entry.
    pub fn readable(self) -> bool {
        !matches!(self, Access::WriteOnly)
    }

    /// Whether an SDO client may write the entry.
    pub fn writable(self) -> bool {
        matches!(self, Access::WriteOnly | Access::ReadWrite)
    }
}

/// Whether an entry may be mapped into a PDO (the XDD's `PDOmapping`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PdoMappable {
    /// `no`.
    No,
    /// `TPDO`: only into a transmitted PDO (for a CN: its PRes).
    Tpdo,
    /// `RPDO`: only into a received PDO (for a CN: the PReq or a consumed PRes).
    Rpdo,
    /// `optional` or `default`: either direction.
    Both,
}

impl PdoMappable {
    /// Mappable into a transmitted PDO.
    pub fn tpdo(self) -> bool {
        matches!(self, PdoMappable::Tpdo | PdoMappable::Both)
    }

    /// Mappable into a received PDO.
    pub fn rpdo(self) -> bool {
        matches!(self, PdoMappable::Rpdo | PdoMappable::Both)
    }
}

/// One entry (index/subindex): its name, type, access, PDO mappability, value range and
/// current value (the little-endian wire bytes).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Entry {
    name: Cow<'static, str>,
    data_type: DataType,
    access: Access,
    pdo: PdoMappable,
    value: Vec<u8>,
    default: Vec<u8>,
    low: Option<i128>,
    high: Option<i128>,
    capacity: usize,
}

impl Entry {
    /// An entry holding `value` (little-endian bytes) with no limits and no PDO mapping; for a
    /// string or domain, the value's length is the capacity. The caller makes the value suit
    /// the type (the typed builders, the device-description reader).
    pub(super) fn fixed(
        name: impl Into<Cow<'static, str>>,
        data_type: DataType,
        access: Access,
        value: Vec<u8>,
    ) -> Self {
        let capacity = value.len();
        Entry {
            name: name.into(),
            data_type,
            access,
            pdo: PdoMappable::No,
            default: value.clone(),
            value,
            low: None,
            high: None,
            capacity,
        }
    }

    /// A BOOLEAN entry (range 0..=1).
    pub fn boolean(name: impl Into<Cow<'static, str>>, access: Access, value: bool) -> Self {
        Entry::fixed(name, DataType::Boolean, access, vec![u8::from(value)]).limits(0, 1)
    }

    /// An INTEGER8 entry.
    pub fn integer8(name: impl Into<Cow<'static, str>>, access: Access, value: i8) -> Self {
        Entry::fixed(name, DataType::Integer8, access, value.to_le_bytes().to_vec())
    }

    /// An INTEGER16 entry.
    pub fn integer16(name: impl Into<Cow<'static, str>>, access: Access, value: i16) -> Self {
        Entry::fixed(name, DataType::Integer16, access, value.to_le_bytes().to_vec())
    }

    /// An INTEGER32 entry.
    pub fn integer32(name: impl Into<Cow<'static, str>>, access: Access, value: i32) -> Self {
        Entry::fixed(name, DataType::Integer32, access, value.to_le_bytes().to_vec())
    }

    /// An INTEGER64 entry.
    pub fn integer64(name: impl Into<Cow<'static, str>>, access: Access, value: i64) -> Self {
        Entry::fixed(name, DataType::Integer64, access, value.to_le_bytes().to_vec())
    }

    /// An UNSIGNED8 entry.
    pub fn unsigned8(name: impl Into<Cow<'static, str>>, access: Access, value: u8) -> Self {
        Entry::fixed(name, DataType::Unsigned8, access, vec![value])
    }

    /// An UNSIGNED16 entry.
    pub fn unsigned16(name: impl Into<Cow<'static, str>>, access: Access, value: u16) -> Self {
        Entry::fixed(name, DataType::Unsigned16, access, value.to_le_bytes().to_vec())
    }

    /// An UNSIGNED32 entry.
    pub fn unsigned32(name: impl Into<Cow<'static, str>>, access: Access, value: u32) -> Self {
        Entry::fixed(name, DataType::Unsigned32, access, value.to_le_bytes().to_vec())
    }

    /// An UNSIGNED64 entry.
    pub fn unsigned64(name: impl Into<Cow<'static, str>>, access: Access, value: u64) -> Self {
        Entry::fixed(name, DataType::Unsigned64, access, value.to_le_bytes().to_vec())
    }

    /// A REAL32 entry.
    pub fn real32(name: impl Into<Cow<'static, str>>, access: Access, value: f32) -> Self {
        Entry::fixed(name, DataType::Real32, access, value.to_le_bytes().to_vec())
    }

    /// A REAL64 entry.
    pub fn real64(name: impl Into<Cow<'static, str>>, access: Access, value: f64) -> Self {
        Entry::fixed(name, DataType::Real64, access, value.to_le_bytes().to_vec())
    }

    /// A VISIBLE_STRING entry whose capacity is the text's length (raise it with
    /// [`Entry::capacity`]).
    pub fn visible_string(name: impl Into<Cow<'static, str>>, access: Access, text: &str) -> Self {
        Entry::fixed(name, DataType::VisibleString, access, text.as_bytes().to_vec())
    }

    /// An OCTET_STRING entry whose capacity is the value's length.
    pub fn octet_string(name: impl Into<Cow<'static, str>>, access: Access, value: &[u8]) -> Self {
        Entry::fixed(name, DataType::OctetString, access, value.to_vec())
    }

    /// An empty DOMAIN entry taking up to `capacity` bytes.
    pub fn domain(name: impl Into<Cow<'static, str>>, access: Access, capacity: usize) -> Self {
        Entry::fixed(name, DataType::Domain, access, Vec::new()).capacity(capacity)
    }

    /// The value range of an integer entry (inclusive; a write outside it is refused with
    /// [`SdoAbortCode::ValueTooLow`] / [`SdoAbortCode::ValueTooHigh`]).
    pub fn limits(mut self, low: i128, high: i128) -> Self {
        self.low = Some(low);
        self.high = Some(high);
        self
    }

    /// Only a lower bound (inclusive).
    pub fn low_limit(mut self, low: i128) -> Self {
        self.low = Some(low);
        self
    }

    /// Only an upper bound (inclusive).
    pub fn high_limit(mut self, high: i128) -> Self {
        self.high = Some(high);
        self
    }

    /// The PDO mappability.
    pub fn pdo(mut self, pdo: PdoMappable) -> Self {
        self.pdo = pdo;
        self
    }

    /// The largest value a string or domain entry takes, in bytes (never below the current
    /// value's length; no effect on fixed-size types).
    pub fn capacity(mut self, bytes: usize) -> Self {
        if self.data_type.size().is_none() {
            self.capacity = bytes.max(self.value.len());
        }
        self
    }

    /// The entry's name (the XDD's `name`).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The data type.
    pub fn data_type(&self) -> DataType {
        self.data_type
    }

    /// SDO access.
    pub fn access(&self) -> Access {
        self.access
    }

    /// PDO mappability.
    pub fn pdo_mappable(&self) -> PdoMappable {
        self.pdo
    }

    /// The current value (little-endian wire bytes).
    pub fn value(&self) -> &[u8] {
        &self.value
    }

    /// The value the entry was built with (restored by
    /// [`ObjectDictionary::restore_defaults`](super::ObjectDictionary::restore_defaults)).
    pub fn default_value(&self) -> &[u8] {
        &self.default
    }

    /// The value range (low, high), each bound optional.
    pub fn range(&self) -> (Option<i128>, Option<i128>) {
        (self.low, self.high)
    }

    /// The largest value in bytes (the fixed size for fixed-size types).
    pub fn max_len(&self) -> usize {
        self.data_type.size().unwrap_or(self.capacity)
    }

    /// The value as an integer (sign-extended for INTEGERn), if the type is an integer one and
    /// the value has its size.
    pub fn as_i128(&self) -> Option<i128> {
        integer_value(self.data_type, &self.value)
    }

    /// Checks that `value` suits the entry (size, range), as a write would.
    ///
    /// # Errors
    /// [`SdoAbortCode::TypeLengthTooHigh`] / [`SdoAbortCode::TypeLengthTooLow`] for a wrong
    /// size, [`SdoAbortCode::ValueTooHigh`] / [`SdoAbortCode::ValueTooLow`] outside the range.
    pub fn check(&self, value: &[u8]) -> Result<(), SdoAbortCode> {
        match self.data_type.size() {
            Some(size) if value.len() > size => return Err(SdoAbortCode::TypeLengthTooHigh),
            Some(size) if value.len() < size => return Err(SdoAbortCode::TypeLengthTooLow),
            None if value.len() > self.capacity => return Err(SdoAbortCode::TypeLengthTooHigh),
            _ => {}
        }
        if let Some(v) = integer_value(self.data_type, value) {
            if self.low.is_some_and(|low| v < low) {
                return Err(SdoAbortCode::ValueTooLow);
            }
            if self.high.is_some_and(|high| v > high) {
                return Err(SdoAbortCode::ValueTooHigh);
            }
        }
        Ok(())
    }

    /// Makes the current value the default (what a reset restores).
    pub(super) fn keep_as_default(&mut self) {
        self.default.clone_from(&self.value);
    }

    /// Puts the default value back.
    pub(super) fn restore(&mut self) {
        self.value.clone_from(&self.default);
    }

    /// Stores a value already checked (or coming from a PDO, whose length the mapping fixed).
    pub(super) fn store(&mut self, value: &[u8]) {
        self.value.clear();
        self.value.extend_from_slice(value);
    }
}

/// The integer a value holds, for integer types of the right size.
fn integer_value(data_type: DataType, value: &[u8]) -> Option<i128> {
    if !data_type.is_integer() || Some(value.len()) != data_type.size() {
        return None;
    }
    let mut buf = [0u8; 16];
    let negative = data_type.is_signed() && value.last().is_some_and(|b| b & 0x80 != 0);
    if negative {
        buf = [0xFF; 16];
    }
    buf.get_mut(..value.len())?.copy_from_slice(value);
    Some(i128::from_le_bytes(buf))
}

/// The object code of an object (the XDD's `objectType`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ObjectKind {
    /// VAR (7): a single value at subindex 0.
    Var,
    /// ARRAY (8): subindex 0 holds the number of entries, subindices 1.. share one type.
    Array,
    /// RECORD (9): subindex 0 holds the number of entries, subindices 1.. of any types.
    Record,
}

/// One object: an index with its name, kind and entries by subindex.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Object {
    name: Cow<'static, str>,
    kind: ObjectKind,
    entries: BTreeMap<u8, Entry>,
}

impl Object {
    /// A VAR object: `entry` at subindex 0.
    pub fn var(entry: Entry) -> Self {
        Object { name: entry.name.clone(), kind: ObjectKind::Var, entries: BTreeMap::from([(0, entry)]) }
    }

    /// A RECORD: `subs` at subindices 1, 2, ... and subindex 0 "NumberOfEntries" (const
    /// UNSIGNED8, the highest subindex). At most 254 entries are taken.
    pub fn record(name: impl Into<Cow<'static, str>>, subs: impl IntoIterator<Item = Entry>) -> Self {
        let entries: BTreeMap<u8, Entry> = (1..=254u8).zip(subs).collect();
        Object::with_entries(name.into(), ObjectKind::Record, entries)
    }

    /// An ARRAY of `count` copies of `element` at subindices 1..=count and subindex 0
    /// "NumberOfEntries" (const UNSIGNED8 = count; change it with
    /// [`Object::number_of_entries`]).
    pub fn array(name: impl Into<Cow<'static, str>>, count: u8, element: Entry) -> Self {
        let count = count.min(254);
        let entries: BTreeMap<u8, Entry> = (1..=count).map(|sub| (sub, element.clone())).collect();
        Object::with_entries(name.into(), ObjectKind::Array, entries)
    }

    /// An object of `kind` with exactly these entries, subindex 0 included (as a device
    /// description lists them).
    pub(super) fn from_entries(
        name: impl Into<Cow<'static, str>>,
        kind: ObjectKind,
        entries: BTreeMap<u8, Entry>,
    ) -> Self {
        Object { name: name.into(), kind, entries }
    }

    fn with_entries(name: Cow<'static, str>, kind: ObjectKind, mut entries: BTreeMap<u8, Entry>) -> Self {
        let highest = entries.keys().next_back().copied().unwrap_or(0);
        entries.insert(0, Entry::unsigned8("NumberOfEntries", Access::Const, highest));
        Object { name, kind, entries }
    }

    /// Replaces subindex 0 of an ARRAY or RECORD with an UNSIGNED8 of this access and value,
    /// limited to 0..=highest subindex (for arrays whose number of entries an MN writes, such
    /// as the PDO mapping objects).
    pub fn number_of_entries(mut self, access: Access, value: u8) -> Self {
        if self.kind != ObjectKind::Var {
            let highest = self.entries.keys().next_back().copied().unwrap_or(0);
            let sub0 = Entry::unsigned8("NumberOfEntries", access, value).limits(0, highest.into());
            self.entries.insert(0, sub0);
        }
        self
    }

    /// The object's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// VAR, ARRAY or RECORD.
    pub fn kind(&self) -> ObjectKind {
        self.kind
    }

    /// The entry at `subindex`.
    pub fn entry(&self, subindex: u8) -> Option<&Entry> {
        self.entries.get(&subindex)
    }

    pub(super) fn entry_mut(&mut self, subindex: u8) -> Option<&mut Entry> {
        self.entries.get_mut(&subindex)
    }

    /// The entries in subindex order.
    pub fn entries(&self) -> impl Iterator<Item = (u8, &Entry)> {
        self.entries.iter().map(|(sub, e)| (*sub, e))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]
    use super::*;

    #[test]
    fn data_type_codes_round_trip() {
        for code in 0..=0x40u16 {
            if let Some(t) = DataType::from_code(code) {
                assert_eq!(t.code(), code);
            }
        }
        assert_eq!(DataType::from_code(0x001B), Some(DataType::Unsigned64));
        assert_eq!(DataType::from_code(0x000E), None);
    }

    #[test]
    fn check_sizes_and_ranges() {
        let e = Entry::unsigned16("PReqActPayloadLimit_U16", Access::ReadWrite, 36).limits(36, 1490);
        assert_eq!(e.check(&[36, 0]), Ok(()));
        assert_eq!(e.check(&[0xD2, 0x05]), Ok(()));
        assert_eq!(e.check(&[0xD3, 0x05]), Err(SdoAbortCode::ValueTooHigh));
        assert_eq!(e.check(&[35, 0]), Err(SdoAbortCode::ValueTooLow));
        assert_eq!(e.check(&[36]), Err(SdoAbortCode::TypeLengthTooLow));
        assert_eq!(e.check(&[36, 0, 0]), Err(SdoAbortCode::TypeLengthTooHigh));
        let s = Entry::integer8("s", Access::ReadWrite, 0).limits(-10, 10);
        assert_eq!(s.check(&[0xF6]), Ok(()));
        assert_eq!(s.check(&[0xF5]), Err(SdoAbortCode::ValueTooLow));
        let b = Entry::boolean("b", Access::ReadWrite, true);
        assert_eq!(b.check(&[2]), Err(SdoAbortCode::ValueTooHigh));
        let v = Entry::visible_string("v", Access::ReadWrite, "ab").capacity(4);
        assert_eq!(v.check(b"abcd"), Ok(()));
        assert_eq!(v.check(b""), Ok(()));
        assert_eq!(v.check(b"abcde"), Err(SdoAbortCode::TypeLengthTooHigh));
        let u64e = Entry::unsigned64("m", Access::ReadWrite, u64::MAX);
        assert_eq!(u64e.as_i128(), Some(i128::from(u64::MAX)));
        assert_eq!(Entry::integer32("i", Access::ReadOnly, -5).as_i128(), Some(-5));
    }

    #[test]
    fn record_and_array_subindex_zero() {
        let r = Object::record(
            "R",
            [Entry::unsigned8("a", Access::ReadWrite, 1), Entry::unsigned8("b", Access::ReadWrite, 2)],
        );
        assert_eq!(r.entry(0).unwrap().value(), [2]);
        assert_eq!(r.entry(0).unwrap().access(), Access::Const);
        let a = Object::array("A", 25, Entry::unsigned64("ObjectMapping", Access::ReadWrite, 0))
            .number_of_entries(Access::ReadWrite, 0);
        let sub0 = a.entry(0).unwrap();
        assert_eq!(sub0.value(), [0]);
        assert_eq!(sub0.check(&[25]), Ok(()));
        assert_eq!(sub0.check(&[26]), Err(SdoAbortCode::ValueTooHigh));
        assert_eq!(a.entries().count(), 26);
    }
}
