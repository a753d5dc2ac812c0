//! An object dictionary from a POWERLINK device description: an XDD (XML Device Description,
//! EPSG DS 311) or an XDC (the same description configured for one node, with `actualValue`
//! attributes), read by [`ObjectDictionary::from_xdd`]. Sans-IO: text in, dictionary out.
//!
//! What is read is the `<ObjectList>` (in the communication network profile's
//! `ApplicationLayers`); everything else (device identity section, `DataTypeList`,
//! `NetworkManagement` ...) is ignored. Each `<Object>` becomes an object of the dictionary:
//!
//! * `index` (hexadecimal, `1000`; an optional `0x` is accepted), `name`, `objectType` 7 (VAR),
//!   8 (ARRAY) or 9 (RECORD). A VAR carries its entry's attributes itself (subindex 0); an
//!   ARRAY or RECORD holds `<SubObject subIndex="00" ...>` children (hexadecimal subindex),
//!   which must include subindex 0 (NumberOfEntries, UNSIGNED8); the elements of an ARRAY
//!   (subindices 1..) share one data type. An `objectType` on a SubObject, if given, is 7.
//! * Each entry: `name`, `dataType` (the standard codes: 0001 BOOLEAN, 0002-0004 and 0015
//!   INTEGER8/16/32/64, 0005-0007 and 001B UNSIGNED8/16/32/64, 0008 REAL32, 0011 REAL64, 0009
//!   VISIBLE_STRING, 000A OCTET_STRING, 000F DOMAIN), `accessType` (`const`, `ro`, `wo`, `rw`;
//!   `rww` and `rwr`, read-write with a mapping preference, are `rw`), `PDOmapping` (`no`, the
//!   default when absent; `TPDO`; `RPDO`; `optional` and `default` are both directions),
//!   `lowLimit` / `highLimit` (integer types only), `defaultValue` and `actualValue`.
//! * Values: integers in decimal (with a sign) or hexadecimal with `0x` (for a signed type the
//!   hexadecimal digits are the two's complement bit pattern of its width: INTEGER8 `0xFF` is
//!   -1); BOOLEAN also `true` / `false`; REAL32/64 as decimal numbers or `0x` bit patterns;
//!   VISIBLE_STRING the attribute's text; OCTET_STRING and DOMAIN an even number of
//!   hexadecimal digits (`0x` optional), the bytes in the order written. Every value must fit
//!   its type and the entry's limits.
//! * The initial value is `actualValue` when present (an XDC), else `defaultValue`, else zero
//!   (empty for strings and domains). It is also the entry's default, the value the NMT resets
//!   restore ([`ObjectDictionary::restore_defaults`]): a configured XDC describes the node as
//!   it starts.
//! * A string or domain takes at most as many bytes as its initial value (the description
//!   gives no length), as in the built-in dictionary.
//! * Limits implied as in the built-in dictionary: a BOOLEAN is limited to 0..=1, and a
//!   NumberOfEntries that is not `const` to 0..=the highest subindex, unless the file gives
//!   limits.
//!
//! Refused, each with an [`XddError`] naming the line, the object (and subindex) and the
//! attribute: XML that is not well-formed or has a DTD; no `<ObjectList>` or two; an object
//! or subindex defined twice; a missing or malformed attribute; a data type other than those
//! above (e.g. INTEGER24, or a complex type); `objectType` other than 7/8/9 (DOMAIN 2,
//! DEFTYPE 5, DEFSTRUCT 6, NULL 0); `uniqueIDRef` (an entry whose type and value live in a
//! `<parameter>` of the ApplicationProcess section); limits on non-integer types; a value out
//! of its type or limits; an enabled PDO mapping (`actualValue` on 0x1600+/0x1A00+) that is
//! invalid for the dictionary ([`ObjectDictionary::pdo_mapping`]). Unknown attributes are
//! ignored, as is the `dataType` of an ARRAY or RECORD object itself.
//!
//! openPOWERLINK's demo CN description `00000000_POWERLINK_CiA401_CN.xdd` gives the same
//! dictionary as [`ObjectDictionary::controlled_node`] apart from that function's documented
//! deviations (the unit tests compare them entry by entry).

use std::collections::BTreeMap;
use std::fmt;

use roxmltree::{Document, Node, ParsingOptions};
use thiserror::Error;

use super::entry::{Access, DataType, Entry, Object, ObjectKind, PdoMappable};
use super::mapping::MappingError;
use super::ObjectDictionary;
use crate::object_access::SdoAbortCode;

/// Most XML nodes (elements, text, comments) a description may have: the openPOWERLINK demo
/// CN's has about 4,500; this bounds the memory an arbitrary input takes.
const MAX_NODES: u32 = 1 << 20;

/// Where in the description a problem is: the line (1-based) and the object index and
/// subindex as far as they are known.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct XddLocation {
    /// Line of the element (1-based).
    pub line: u32,
    /// The object's index, once read.
    pub index: Option<u16>,
    /// The subindex, for a SubObject once read.
    pub subindex: Option<u8>,
}

impl fmt::Display for XddLocation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}", self.line)?;
        match (self.index, self.subindex) {
            (Some(index), Some(sub)) => write!(f, ", object 0x{index:04X} subindex 0x{sub:02X}"),
            (Some(index), None) => write!(f, ", object 0x{index:04X}"),
            (None, _) => Ok(()),
        }
    }
}

/// Why a device description was refused ([`ObjectDictionary::from_xdd`]).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum XddError {
    /// Not well-formed XML (or a DTD, which is not accepted).
    #[error("line {line}: not well-formed XML: {message}")]
    Xml {
        /// Line of the error (1-based).
        line: u32,
        /// The XML parser's message.
        message: String,
    },
    /// No `<ObjectList>` element: not a POWERLINK device description.
    #[error("no <ObjectList> element: not a POWERLINK device description (XDD/XDC)")]
    NoObjectList,
    /// A second `<ObjectList>`.
    #[error("{at}: a second <ObjectList>")]
    SecondObjectList {
        /// Where.
        at: XddLocation,
    },
    /// An element that does not belong there (only `<Object>` in the `<ObjectList>`, only
    /// `<SubObject>` in an ARRAY or RECORD, nothing in a VAR).
    #[error("{at}: unexpected element <{element}>")]
    UnexpectedElement {
        /// Where.
        at: XddLocation,
        /// The element's name.
        element: String,
    },
    /// A required attribute is missing.
    #[error("{at}: attribute {attribute} missing")]
    MissingAttribute {
        /// Where.
        at: XddLocation,
        /// The attribute.
        attribute: &'static str,
    },
    /// An attribute's text is not what it must be.
    #[error("{at}: {attribute}=\"{value}\": {reason}")]
    InvalidAttribute {
        /// Where.
        at: XddLocation,
        /// The attribute.
        attribute: &'static str,
        /// Its text.
        value: String,
        /// What is wrong.
        reason: String,
    },
    /// A `dataType` code this dictionary does not hold (a complex type or an unusual size).
    #[error(
        "{at}: dataType=\"{code}\" is not supported (BOOLEAN, INTEGER8/16/32/64, UNSIGNED8/16/32/64, \
         REAL32/64, VISIBLE_STRING, OCTET_STRING, DOMAIN)"
    )]
    UnknownDataType {
        /// Where.
        at: XddLocation,
        /// The attribute's text.
        code: String,
    },
    /// A value (`defaultValue`, `actualValue`, `lowLimit`, `highLimit`) that does not fit its
    /// data type or the entry's limits.
    #[error("{at}: {attribute}=\"{value}\" is not a valid {} value: {reason}", type_name(*.data_type))]
    InvalidValue {
        /// Where.
        at: XddLocation,
        /// The attribute.
        attribute: &'static str,
        /// Its text.
        value: String,
        /// The entry's data type.
        data_type: DataType,
        /// What is wrong.
        reason: String,
    },
    /// The same index twice.
    #[error("{at}: object defined twice")]
    DuplicateObject {
        /// Where the second definition is.
        at: XddLocation,
    },
    /// The same subindex twice in one object.
    #[error("{at}: subindex defined twice")]
    DuplicateSubObject {
        /// Where the second definition is.
        at: XddLocation,
    },
    /// A feature of device descriptions that this reader does not support.
    #[error("{at}: not supported: {what}")]
    Unsupported {
        /// Where.
        at: XddLocation,
        /// What.
        what: String,
    },
    /// An object whose shape is wrong (no NumberOfEntries, array elements of different
    /// types ...).
    #[error("{at}: {reason}")]
    Structure {
        /// Where.
        at: XddLocation,
        /// What is wrong.
        reason: String,
    },
    /// An enabled PDO mapping of the description is invalid for its dictionary.
    #[error("invalid PDO mapping: {0}")]
    PdoMapping(#[from] MappingError),
}

/// The data type's name as the standard writes it.
fn type_name(data_type: DataType) -> &'static str {
    match data_type {
        DataType::Boolean => "BOOLEAN",
        DataType::Integer8 => "INTEGER8",
        DataType::Integer16 => "INTEGER16",
        DataType::Integer32 => "INTEGER32",
        DataType::Integer64 => "INTEGER64",
        DataType::Unsigned8 => "UNSIGNED8",
        DataType::Unsigned16 => "UNSIGNED16",
        DataType::Unsigned32 => "UNSIGNED32",
        DataType::Unsigned64 => "UNSIGNED64",
        DataType::Real32 => "REAL32",
        DataType::Real64 => "REAL64",
        DataType::VisibleString => "VISIBLE_STRING",
        DataType::OctetString => "OCTET_STRING",
        DataType::Domain => "DOMAIN",
    }
}

impl ObjectDictionary {
    /// The object dictionary a POWERLINK device description (XDD or XDC, EPSG DS 311)
    /// describes: each `<Object>` / `<SubObject>` of its `<ObjectList>` with its name,
    /// `objectType` (7 VAR, 8 ARRAY, 9 RECORD), `dataType` (the basic types of [`DataType`]),
    /// `accessType` (`rww`/`rwr` are `rw`), `PDOmapping`, integer `lowLimit`/`highLimit` and
    /// value. Integers are decimal or `0x` hexadecimal (a signed type's bit pattern), BOOLEAN
    /// also `true`/`false`, OCTET_STRING and DOMAIN hexadecimal bytes; a string or domain takes
    /// at most its initial value's length. In an XDC, `actualValue` overrides `defaultValue`
    /// as the initial and the default value (what the NMT resets restore); without either the
    /// value is zero (empty). A BOOLEAN is limited to 0..=1, a NumberOfEntries that is not
    /// `const` to 0..=the highest subindex, unless the file gives limits. The PDO channels are
    /// those the description's mapping objects enable. `od/xdd.rs` documents the rest.
    ///
    /// # Errors
    /// [`XddError`], naming the line, object, subindex and attribute at fault: malformed XML
    /// (or a DTD), no `<ObjectList>`, duplicates, missing or malformed attributes, values out
    /// of their type or limits, unsupported features (other data types or object codes,
    /// `uniqueIDRef`, limits on non-integer types), an invalid enabled PDO mapping. Never
    /// panics.
    pub fn from_xdd(text: &str) -> Result<ObjectDictionary, XddError> {
        let options =
            ParsingOptions { allow_dtd: false, nodes_limit: MAX_NODES, ..ParsingOptions::default() };
        let doc = Document::parse_with_options(text, options)
            .map_err(|e| XddError::Xml { line: e.pos().row, message: e.to_string() })?;
        let mut lists = doc.descendants().filter(|n| n.is_element() && n.tag_name().name() == "ObjectList");
        let list = lists.next().ok_or(XddError::NoObjectList)?;
        if let Some(second) = lists.next() {
            return Err(XddError::SecondObjectList { at: location(&doc, second, None, None) });
        }
        let mut objects: BTreeMap<u16, Object> = BTreeMap::new();
        for node in list.children().filter(Node::is_element) {
            if node.tag_name().name() != "Object" {
                return Err(unexpected(&doc, node, None));
            }
            let (index, object) = parse_object(&doc, node)?;
            if objects.contains_key(&index) {
                return Err(XddError::DuplicateObject { at: location(&doc, node, Some(index), None) });
            }
            objects.insert(index, object);
        }
        if objects.is_empty() {
            return Err(XddError::Structure {
                at: location(&doc, list, None, None),
                reason: "the ObjectList holds no Object".to_owned(),
            });
        }
        let mut od = ObjectDictionary::new();
        od.objects = objects;
        od.refresh_pdo()?;
        Ok(od)
    }
}

/// The location of `node`.
fn location(doc: &Document<'_>, node: Node<'_, '_>, index: Option<u16>, subindex: Option<u8>) -> XddLocation {
    XddLocation { line: doc.text_pos_at(node.range().start).row, index, subindex }
}

fn unexpected(doc: &Document<'_>, node: Node<'_, '_>, index: Option<u16>) -> XddError {
    XddError::UnexpectedElement {
        at: location(doc, node, index, None),
        element: node.tag_name().name().to_owned(),
    }
}

/// Hexadecimal digits (1..=`max_digits`, at most 16; `0x` optional).
fn parse_hex(text: &str, max_digits: usize) -> Option<u64> {
    hex_digits(text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")).unwrap_or(text), max_digits)
}

/// 1..=`max_digits` hexadecimal digits (at most 16), nothing else.
fn hex_digits(digits: &str, max_digits: usize) -> Option<u64> {
    if digits.is_empty() || digits.len() > max_digits || !digits.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    u64::from_str_radix(digits, 16).ok()
}

/// A value read for a data type: its little-endian bytes and, for integer types, the number.
struct Value {
    bytes: Vec<u8>,
    number: Option<i128>,
}

/// The range and size in bytes of an integer type (BOOLEAN: 0..=1).
fn integer_bounds(data_type: DataType) -> Option<(i128, i128, usize)> {
    Some(match data_type {
        DataType::Boolean => (0, 1, 1),
        DataType::Integer8 => (i8::MIN.into(), i8::MAX.into(), 1),
        DataType::Integer16 => (i16::MIN.into(), i16::MAX.into(), 2),
        DataType::Integer32 => (i32::MIN.into(), i32::MAX.into(), 4),
        DataType::Integer64 => (i64::MIN.into(), i64::MAX.into(), 8),
        DataType::Unsigned8 => (0, u8::MAX.into(), 1),
        DataType::Unsigned16 => (0, u16::MAX.into(), 2),
        DataType::Unsigned32 => (0, u32::MAX.into(), 4),
        DataType::Unsigned64 => (0, u64::MAX.into(), 8),
        _ => return None,
    })
}

/// An integer in decimal (signed) or `0x` hexadecimal (for a signed type of `bytes` bytes,
/// the two's complement bit pattern).
fn parse_integer(text: &str, min: i128, bytes: usize) -> Result<i128, String> {
    let (negative, rest) = match text.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, text.strip_prefix('+').unwrap_or(text)),
    };
    let (radix, digits) = match rest.strip_prefix("0x").or_else(|| rest.strip_prefix("0X")) {
        Some(digits) => (16, digits),
        None => (10, rest),
    };
    if digits.is_empty() || !digits.chars().all(|c| c.is_digit(radix)) {
        return Err("not a number (decimal, or hexadecimal with 0x)".to_owned());
    }
    let magnitude = u128::from_str_radix(digits, radix)
        .ok()
        .and_then(|m| i128::try_from(m).ok())
        .ok_or_else(|| "too large".to_owned())?;
    if radix == 16 && !negative && min < 0 {
        let bits = bytes * 8;
        let span = 1i128 << bits;
        if magnitude >= span {
            return Err(format!("more than {bits} bits"));
        }
        return Ok(if magnitude >= span / 2 { magnitude - span } else { magnitude });
    }
    Ok(if negative { -magnitude } else { magnitude })
}

/// A REAL32/64 of `bytes` bytes: a decimal number or a `0x` bit pattern.
fn parse_real(text: &str, bytes: usize) -> Result<Vec<u8>, String> {
    if let Some(digits) = text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        let bits = hex_digits(digits, bytes * 2)
            .ok_or_else(|| format!("not a {}-bit hexadecimal pattern", bytes * 8))?;
        return Ok(bits.to_le_bytes().get(..bytes).map(<[u8]>::to_vec).unwrap_or_default());
    }
    let not_a_number = || "not a finite decimal number".to_owned();
    if bytes == 4 {
        let v: f32 = text.parse().map_err(|_| not_a_number())?;
        return if v.is_finite() { Ok(v.to_le_bytes().to_vec()) } else { Err(not_a_number()) };
    }
    let v: f64 = text.parse().map_err(|_| not_a_number())?;
    if v.is_finite() {
        Ok(v.to_le_bytes().to_vec())
    } else {
        Err(not_a_number())
    }
}

/// Bytes as an even number of hexadecimal digits (`0x` optional).
fn parse_octets(text: &str) -> Result<Vec<u8>, String> {
    let digits = text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")).unwrap_or(text);
    let nibble = |b: u8| char::from(b).to_digit(16).and_then(|d| u8::try_from(d).ok());
    if digits.len() % 2 != 0 {
        return Err("an odd number of hexadecimal digits".to_owned());
    }
    digits
        .as_bytes()
        .chunks_exact(2)
        .map(|pair| match pair {
            [hi, lo] => Some((nibble(*hi)? << 4) | nibble(*lo)?),
            _ => None,
        })
        .collect::<Option<Vec<u8>>>()
        .ok_or_else(|| "not hexadecimal digits".to_owned())
}

/// A value of `data_type` from its attribute text.
fn parse_value(data_type: DataType, text: &str) -> Result<Value, String> {
    let trimmed = text.trim();
    if let Some((min, max, size)) = integer_bounds(data_type) {
        let number = match trimmed {
            t if data_type == DataType::Boolean && t.eq_ignore_ascii_case("true") => 1,
            t if data_type == DataType::Boolean && t.eq_ignore_ascii_case("false") => 0,
            t => parse_integer(t, min, size)?,
        };
        if number < min || number > max {
            return Err(format!("out of range {min}..={max}"));
        }
        let bytes = number.to_le_bytes().get(..size).map(<[u8]>::to_vec).unwrap_or_default();
        return Ok(Value { bytes, number: Some(number) });
    }
    let bytes = match data_type {
        DataType::Real32 => parse_real(trimmed, 4)?,
        DataType::Real64 => parse_real(trimmed, 8)?,
        DataType::OctetString | DataType::Domain => parse_octets(trimmed)?,
        _ => text.as_bytes().to_vec(),
    };
    Ok(Value { bytes, number: None })
}

/// An element with the object index and subindex it stands for, for reading attributes.
struct Element<'a, 'input> {
    doc: &'a Document<'input>,
    node: Node<'a, 'input>,
    index: Option<u16>,
    subindex: Option<u8>,
}

impl<'a> Element<'a, '_> {
    /// Where the element is (the line is worked out only for an error: finding it scans the
    /// text from the start).
    fn at(&self) -> XddLocation {
        location(self.doc, self.node, self.index, self.subindex)
    }

    fn optional(&self, attribute: &'static str) -> Option<&'a str> {
        self.node.attribute(attribute)
    }

    fn required(&self, attribute: &'static str) -> Result<&'a str, XddError> {
        self.optional(attribute).ok_or_else(|| XddError::MissingAttribute { at: self.at(), attribute })
    }

    fn invalid(&self, attribute: &'static str, value: &str, reason: impl Into<String>) -> XddError {
        XddError::InvalidAttribute {
            at: self.at(),
            attribute,
            value: value.to_owned(),
            reason: reason.into(),
        }
    }

    fn unsupported(&self, what: impl Into<String>) -> XddError {
        XddError::Unsupported { at: self.at(), what: what.into() }
    }

    fn refuse_unique_id_ref(&self) -> Result<(), XddError> {
        match self.optional("uniqueIDRef") {
            Some(r) => Err(self.unsupported(format!(
                "uniqueIDRef=\"{r}\" (type and value from an ApplicationProcess parameter)"
            ))),
            None => Ok(()),
        }
    }

    /// The value of `attribute`, if present, for `data_type`.
    fn value(&self, attribute: &'static str, data_type: DataType) -> Result<Option<Value>, XddError> {
        let Some(text) = self.optional(attribute) else {
            return Ok(None);
        };
        parse_value(data_type, text).map(Some).map_err(|reason| XddError::InvalidValue {
            at: self.at(),
            attribute,
            value: text.to_owned(),
            data_type,
            reason,
        })
    }

    /// A limit attribute: integer types only.
    fn limit(&self, attribute: &'static str, data_type: DataType) -> Result<Option<i128>, XddError> {
        if self.optional(attribute).is_some() && integer_bounds(data_type).is_none() {
            return Err(self.unsupported(format!("{attribute} on a {} entry", type_name(data_type))));
        }
        Ok(self.value(attribute, data_type)?.and_then(|v| v.number))
    }

    /// A hexadecimal index or subindex attribute of at most `digits` digits.
    fn hex(&self, attribute: &'static str, digits: usize) -> Result<u64, XddError> {
        let text = self.required(attribute)?;
        parse_hex(text.trim(), digits)
            .ok_or_else(|| self.invalid(attribute, text, format!("not 1 to {digits} hexadecimal digits")))
    }

    /// The entry this element (a VAR Object or a SubObject) describes.
    fn entry(&self) -> Result<Entry, XddError> {
        self.refuse_unique_id_ref()?;
        let name = self.required("name")?;
        let code_text = self.required("dataType")?;
        let code = u16::try_from(self.hex("dataType", 4)?).unwrap_or(u16::MAX);
        let data_type = DataType::from_code(code)
            .ok_or_else(|| XddError::UnknownDataType { at: self.at(), code: code_text.to_owned() })?;
        let access_text = self.required("accessType")?;
        let access = match access_text.trim() {
            "const" => Access::Const,
            "ro" => Access::ReadOnly,
            "wo" => Access::WriteOnly,
            "rw" | "rww" | "rwr" => Access::ReadWrite,
            _ => return Err(self.invalid("accessType", access_text, "not const, ro, wo, rw, rwr or rww")),
        };
        let pdo = match self.optional("PDOmapping").map(str::trim) {
            None | Some("no") => PdoMappable::No,
            Some("TPDO") => PdoMappable::Tpdo,
            Some("RPDO") => PdoMappable::Rpdo,
            Some("optional" | "default") => PdoMappable::Both,
            Some(other) => {
                return Err(self.invalid("PDOmapping", other, "not no, default, optional, TPDO or RPDO"))
            }
        };
        let low = self.limit("lowLimit", data_type)?;
        let high = self.limit("highLimit", data_type)?;
        if let (Some(l), Some(h)) = (low, high) {
            if l > h {
                let text = self.optional("lowLimit").unwrap_or_default();
                return Err(self.invalid("lowLimit", text, format!("above highLimit {h}")));
            }
        }
        let default = self.value("defaultValue", data_type)?;
        let actual = self.value("actualValue", data_type)?;
        let initial = match (&actual, &default) {
            (Some(v), _) | (None, Some(v)) => v.bytes.clone(),
            (None, None) => vec![0; data_type.size().unwrap_or(0)],
        };
        let (low, high) = match (low, high) {
            (None, None) if data_type == DataType::Boolean => (Some(0), Some(1)),
            limits => limits,
        };
        let mut entry = Entry::fixed(name.to_owned(), data_type, access, initial).pdo(pdo);
        if let Some(l) = low {
            entry = entry.low_limit(l);
        }
        if let Some(h) = high {
            entry = entry.high_limit(h);
        }
        // Without a value in the file the entry starts at zero, which its limits may refuse:
        // then the value is missing, not zero.
        if default.is_none() && actual.is_none() && entry.check(entry.value()).is_err() {
            return Err(XddError::MissingAttribute { at: self.at(), attribute: "defaultValue" });
        }
        for (attribute, value) in [("defaultValue", &default), ("actualValue", &actual)] {
            let Some(value) = value else { continue };
            let reason = match entry.check(&value.bytes) {
                Err(SdoAbortCode::ValueTooLow) => format!("below lowLimit {}", low.unwrap_or_default()),
                Err(SdoAbortCode::ValueTooHigh) => format!("above highLimit {}", high.unwrap_or_default()),
                Err(other) => format!("refused: {other:?}"),
                Ok(()) => continue,
            };
            return Err(XddError::InvalidValue {
                at: self.at(),
                attribute,
                value: self.optional(attribute).unwrap_or_default().to_owned(),
                data_type,
                reason,
            });
        }
        Ok(entry)
    }
}

/// One `<Object>`: its index and the object.
fn parse_object<'a, 'input>(
    doc: &'a Document<'input>,
    node: Node<'a, 'input>,
) -> Result<(u16, Object), XddError> {
    let mut el = Element { doc, node, index: None, subindex: None };
    let index = u16::try_from(el.hex("index", 4)?).unwrap_or(u16::MAX);
    el.index = Some(index);
    el.refuse_unique_id_ref()?;
    let name = el.required("name")?;
    let type_text = el.required("objectType")?;
    let kind = match type_text.trim() {
        "7" => ObjectKind::Var,
        "8" => ObjectKind::Array,
        "9" => ObjectKind::Record,
        t @ ("0" | "2" | "5" | "6") => {
            return Err(el.unsupported(format!("objectType {t} (only 7 VAR, 8 ARRAY, 9 RECORD)")))
        }
        _ => {
            return Err(el.invalid("objectType", type_text, "not an object code (7 VAR, 8 ARRAY, 9 RECORD)"))
        }
    };
    let mut children = node.children().filter(Node::is_element);
    if kind == ObjectKind::Var {
        if let Some(child) = children.next() {
            return Err(unexpected(doc, child, Some(index)));
        }
        return Ok((index, Object::var(el.entry()?)));
    }
    let mut entries: BTreeMap<u8, Entry> = BTreeMap::new();
    let mut elements: BTreeMap<u8, Element<'a, 'input>> = BTreeMap::new();
    for child in children {
        if child.tag_name().name() != "SubObject" {
            return Err(unexpected(doc, child, Some(index)));
        }
        let mut sub_el = Element { doc, node: child, index: Some(index), subindex: None };
        let sub = u8::try_from(sub_el.hex("subIndex", 2)?).unwrap_or(u8::MAX);
        sub_el.subindex = Some(sub);
        if let Some(t) = sub_el.optional("objectType").filter(|t| t.trim() != "7") {
            return Err(sub_el.unsupported(format!("objectType {t} in a SubObject (only 7, VAR)")));
        }
        if entries.contains_key(&sub) {
            return Err(XddError::DuplicateSubObject { at: sub_el.at() });
        }
        entries.insert(sub, sub_el.entry()?);
        elements.insert(sub, sub_el);
    }
    let structure = |sub: u8, reason: String| XddError::Structure {
        at: elements.get(&sub).map_or_else(|| el.at(), Element::at),
        reason,
    };
    let Some(sub0) = entries.get(&0) else {
        return Err(XddError::Structure {
            at: el.at(),
            reason: "an ARRAY or RECORD without SubObject 00 (NumberOfEntries)".to_owned(),
        });
    };
    if sub0.data_type() != DataType::Unsigned8 {
        let reason = format!("NumberOfEntries is {}, not UNSIGNED8", type_name(sub0.data_type()));
        return Err(structure(0, reason));
    }
    if kind == ObjectKind::Array {
        let mut members = entries.range(1..);
        if let Some((first_sub, first)) = members.next() {
            if let Some((sub, other)) = members.find(|(_, e)| e.data_type() != first.data_type()) {
                let reason = format!(
                    "ARRAY element of type {} where subindex 0x{first_sub:02X} is {}",
                    type_name(other.data_type()),
                    type_name(first.data_type())
                );
                return Err(structure(*sub, reason));
            }
        }
    }
    let highest = entries.keys().next_back().copied().unwrap_or(0);
    if sub0.access() != Access::Const && sub0.range() == (None, None) {
        let limited = sub0.clone().limits(0, highest.into());
        if limited.check(limited.value()).is_err() {
            return Err(structure(0, format!("NumberOfEntries above the highest subindex 0x{highest:02X}")));
        }
        entries.insert(0, limited);
    }
    Ok((index, Object::from_entries(name.to_owned(), kind, entries)))
}

#[cfg(test)]
#[path = "xdd_tests.rs"]
mod tests;
