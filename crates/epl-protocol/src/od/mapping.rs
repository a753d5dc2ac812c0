//! PDO mapping (`specs/powerlink.md` §7): the 64-bit mapping entries of 0x1600+n (RPDO) and
//! 0x1A00+n (TPDO), decoded into a [`PdoMapping`] checked against the dictionary.
//!
//! A mapping entry holds, from the least significant bit: object index (16 bits), subindex
//! (8), reserved (8), offset in bits from the start of the PDO payload (16), length in bits
//! (16). Unlike CANopen's packed 32-bit entries, each entry carries its own offset, so gaps
//! are allowed. Subindex 0 of the mapping object is the number of entries in use; 0 disables
//! the PDO. The communication object 0x1400+n / 0x1800+n names the frame in subindex 1
//! (NodeID: 0 = the PReq to me, for an RPDO, or my own PRes, for a TPDO; otherwise that node's
//! PRes, or on an MN the PReq to that node) and the mapping version in subindex 2.

use thiserror::Error;

use super::entry::DataType;
use crate::object_access::SdoAbortCode;

/// Largest isochronous payload (bytes) when no payload-limit object says otherwise
/// (C_DLL_ISOCHR_MAX_PAYL, the XDD's 0x1F98/1 and /2).
pub const ISOCHRONOUS_MAX_PAYLOAD: u16 = 1490;

/// First RPDO communication object (0x1400); its mapping object is 0x200 higher.
pub const RPDO_COMM_BASE: u16 = 0x1400;
/// First RPDO mapping object (0x1600).
pub const RPDO_MAPPING_BASE: u16 = 0x1600;
/// First TPDO communication object (0x1800).
pub const TPDO_COMM_BASE: u16 = 0x1800;
/// First TPDO mapping object (0x1A00).
pub const TPDO_MAPPING_BASE: u16 = 0x1A00;

/// One raw 64-bit mapping entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct MappingEntry {
    /// Object index (bits 0-15).
    pub index: u16,
    /// Object subindex (bits 16-23).
    pub subindex: u8,
    /// Reserved (bits 24-31), kept.
    pub reserved: u8,
    /// Offset in bits from the start of the PDO payload (bits 32-47).
    pub bit_offset: u16,
    /// Length in bits (bits 48-63).
    pub bit_length: u16,
}

impl MappingEntry {
    /// Decodes an UNSIGNED64 mapping entry (e.g. `0x0008_0000_0001_6000`: 0x6000/1, offset 0,
    /// 8 bits).
    pub fn from_raw(raw: u64) -> Self {
        let [i0, i1, sub, reserved, o0, o1, l0, l1] = raw.to_le_bytes();
        MappingEntry {
            index: u16::from_le_bytes([i0, i1]),
            subindex: sub,
            reserved,
            bit_offset: u16::from_le_bytes([o0, o1]),
            bit_length: u16::from_le_bytes([l0, l1]),
        }
    }

    /// The UNSIGNED64 value of the entry.
    pub fn to_raw(self) -> u64 {
        let [i0, i1] = self.index.to_le_bytes();
        let [o0, o1] = self.bit_offset.to_le_bytes();
        let [l0, l1] = self.bit_length.to_le_bytes();
        u64::from_le_bytes([i0, i1, self.subindex, self.reserved, o0, o1, l0, l1])
    }
}

/// Which way a PDO goes, seen from the dictionary's owner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PdoDirection {
    /// Received PDO (0x1400/0x1600 channels): the payload is written into the dictionary.
    Receive,
    /// Transmitted PDO (0x1800/0x1A00 channels): the payload is read from the dictionary.
    Transmit,
}

impl PdoDirection {
    /// The first communication object of the direction (0x1400 or 0x1800).
    pub fn comm_base(self) -> u16 {
        match self {
            PdoDirection::Receive => RPDO_COMM_BASE,
            PdoDirection::Transmit => TPDO_COMM_BASE,
        }
    }

    /// The first mapping object of the direction (0x1600 or 0x1A00).
    pub fn mapping_base(self) -> u16 {
        match self {
            PdoDirection::Receive => RPDO_MAPPING_BASE,
            PdoDirection::Transmit => TPDO_MAPPING_BASE,
        }
    }

    /// The direction and channel number of a mapping object index (0x1600-0x16FF,
    /// 0x1A00-0x1AFF).
    pub fn of_mapping_index(index: u16) -> Option<(Self, u8)> {
        for dir in [PdoDirection::Receive, PdoDirection::Transmit] {
            if let Some(n) = index.checked_sub(dir.mapping_base()).and_then(|n| u8::try_from(n).ok()) {
                return Some((dir, n));
            }
        }
        None
    }

    /// Whether `index` is a communication or mapping object of either direction.
    pub fn is_pdo_object(index: u16) -> bool {
        [RPDO_COMM_BASE, RPDO_MAPPING_BASE, TPDO_COMM_BASE, TPDO_MAPPING_BASE]
            .iter()
            .any(|base| index.checked_sub(*base).is_some_and(|n| n <= 0xFF))
    }
}

/// One mapped object, checked against the dictionary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct MappedObject {
    /// Object index.
    pub index: u16,
    /// Object subindex.
    pub subindex: u8,
    /// The object's data type.
    pub data_type: DataType,
    /// Offset in bits from the start of the payload.
    pub bit_offset: u16,
    /// Length in bits (a whole number of bytes, or 1 for a BOOLEAN).
    pub bit_length: u16,
}

impl MappedObject {
    /// The payload byte holding the first bit.
    pub fn byte_offset(&self) -> usize {
        usize::from(self.bit_offset / 8)
    }

    /// The bit within [`MappedObject::byte_offset`] where the object starts (0 unless it is a
    /// 1-bit BOOLEAN at an unaligned offset).
    pub fn bit_in_byte(&self) -> u8 {
        // The remainder of a division by 8 fits a u8.
        (self.bit_offset % 8) as u8
    }

    /// The number of payload bytes the object touches.
    pub fn byte_len(&self) -> usize {
        (usize::from(self.bit_in_byte()) + usize::from(self.bit_length)).div_ceil(8)
    }

    /// The first payload bit after the object.
    pub fn bit_end(&self) -> u32 {
        u32::from(self.bit_offset) + u32::from(self.bit_length)
    }
}

/// An enabled PDO channel: the frame it goes with and its mapped objects.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PdoMapping {
    /// Receive (PReq / consumed PRes) or transmit (own PRes / PReq from an MN).
    pub direction: PdoDirection,
    /// The communication object (0x1400+n or 0x1800+n).
    pub comm_index: u16,
    /// The mapping object (0x1600+n or 0x1A00+n).
    pub mapping_index: u16,
    /// Communication subindex 1: 0 = the PReq to this node (RPDO) or this node's PRes (TPDO),
    /// otherwise the node whose PRes is consumed (RPDO) or, on an MN, the node the PReq goes
    /// to (TPDO).
    pub node_id: u8,
    /// Communication subindex 2: the mapping version (a PRes/PReq carries it as its PDO
    /// version).
    pub version: u8,
    /// The mapped objects in mapping-entry order.
    pub objects: Vec<MappedObject>,
}

impl PdoMapping {
    /// The payload length the mapping covers: the byte after the last mapped bit.
    pub fn byte_len(&self) -> usize {
        let bits = self.objects.iter().map(MappedObject::bit_end).max().unwrap_or(0);
        usize::try_from(bits.div_ceil(8)).unwrap_or(usize::MAX)
    }
}

/// Why a PDO mapping cannot be enabled. Each has the SDO abort code a write that would enable
/// it is refused with ([`MappingError::abort_code`]).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum MappingError {
    /// Subindex 0 enables more entries than the mapping object holds.
    #[error("{mapping:#06x}/{subindex}: mapping entry does not exist")]
    MissingEntry {
        /// The mapping object.
        mapping: u16,
        /// The missing subindex.
        subindex: u8,
    },
    /// The mapped object is not in the dictionary.
    #[error("{mapping:#06x}/{subindex}: mapped object {index:#06x}/{object_subindex} does not exist")]
    ObjectMissing {
        /// The mapping object.
        mapping: u16,
        /// The mapping entry's subindex.
        subindex: u8,
        /// Mapped object index.
        index: u16,
        /// Mapped object subindex.
        object_subindex: u8,
    },
    /// The mapped object may not be mapped in this direction (or is not readable for a TPDO,
    /// writable for an RPDO).
    #[error(
        "{mapping:#06x}/{subindex}: object {index:#06x}/{object_subindex} cannot be mapped into this PDO"
    )]
    NotMappable {
        /// The mapping object.
        mapping: u16,
        /// The mapping entry's subindex.
        subindex: u8,
        /// Mapped object index.
        index: u16,
        /// Mapped object subindex.
        object_subindex: u8,
    },
    /// The length does not fit the object (whole bytes equal to a fixed-size type, 1 bit for
    /// a BOOLEAN, whole bytes within a string's capacity) or a multi-bit object starts inside
    /// a byte.
    #[error(
        "{mapping:#06x}/{subindex}: {bit_length} bits at bit {bit_offset} do not fit object \
         {index:#06x}/{object_subindex}"
    )]
    BadLayout {
        /// The mapping object.
        mapping: u16,
        /// The mapping entry's subindex.
        subindex: u8,
        /// Mapped object index.
        index: u16,
        /// Mapped object subindex.
        object_subindex: u8,
        /// Offset in bits.
        bit_offset: u16,
        /// Length in bits.
        bit_length: u16,
    },
    /// Two mapped objects share payload bits.
    #[error("{mapping:#06x}: entries {first} and {second} overlap")]
    Overlap {
        /// The mapping object.
        mapping: u16,
        /// The earlier entry's subindex.
        first: u8,
        /// The later entry's subindex.
        second: u8,
    },
    /// The mapped payload is longer than the frame's payload limit.
    #[error("{mapping:#06x}: mapped payload of {bytes} bytes exceeds the limit of {limit} bytes")]
    TooLong {
        /// The mapping object.
        mapping: u16,
        /// Bytes the mapping covers.
        bytes: usize,
        /// The payload limit (0x1F98/4 or /5, 0x1F8B/0x1F8D for other nodes).
        limit: u16,
    },
    /// Another enabled channel of the same direction already serves this node's frame.
    #[error("{mapping:#06x}: node {node_id}'s frame already has the enabled mapping {other:#06x}")]
    DuplicateChannel {
        /// The mapping object.
        mapping: u16,
        /// The node ID of its communication object.
        node_id: u8,
        /// The mapping object enabled first.
        other: u16,
    },
}

impl MappingError {
    /// The SDO abort code for a write that would enable this mapping.
    pub fn abort_code(&self) -> SdoAbortCode {
        match self {
            MappingError::MissingEntry { .. } => SdoAbortCode::ValueTooHigh,
            MappingError::ObjectMissing { .. } | MappingError::NotMappable { .. } => {
                SdoAbortCode::NotMappable
            }
            MappingError::TooLong { .. } => SdoAbortCode::PdoLengthExceeded,
            MappingError::BadLayout { .. }
            | MappingError::Overlap { .. }
            | MappingError::DuplicateChannel { .. } => SdoAbortCode::ParameterIncompatibility,
        }
    }
}

/// Why a received PDO payload was not applied.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum PdoError {
    /// The payload is shorter than the mapping (openPOWERLINK ignores such a payload too).
    #[error("PDO from node {node_id} ({mapping:#06x}): payload of {got} bytes, mapping needs {needed}")]
    PayloadTooShort {
        /// The node ID of the channel (0: the PReq).
        node_id: u8,
        /// The mapping object.
        mapping: u16,
        /// Bytes the mapping covers.
        needed: usize,
        /// Bytes received.
        got: usize,
    },
}

/// Copies an object's value into the payload at its mapped place.
pub(super) fn put(payload: &mut [u8], obj: &MappedObject, value: &[u8]) {
    let start = obj.byte_offset();
    if obj.bit_length == 1 {
        let bit = 1u8 << obj.bit_in_byte();
        if let Some(b) = payload.get_mut(start) {
            if value.first().is_some_and(|v| *v != 0) {
                *b |= bit;
            } else {
                *b &= !bit;
            }
        }
        return;
    }
    let len = usize::from(obj.bit_length / 8);
    if let Some(dst) = payload.get_mut(start..start + len) {
        let n = value.len().min(len);
        if let (Some(d), Some(s)) = (dst.get_mut(..n), value.get(..n)) {
            d.copy_from_slice(s);
        }
        if let Some(rest) = dst.get_mut(n..) {
            rest.fill(0);
        }
    }
}

/// An object's value read from its mapped place in a payload (`None` if the payload is too
/// short).
pub(super) fn take(payload: &[u8], obj: &MappedObject) -> Option<Vec<u8>> {
    let start = obj.byte_offset();
    if obj.bit_length == 1 {
        let b = payload.get(start)?;
        return Some(vec![(b >> obj.bit_in_byte()) & 1]);
    }
    payload.get(start..start + usize::from(obj.bit_length / 8)).map(<[u8]>::to_vec)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]
    use super::*;

    #[test]
    fn decodes_the_demo_entries() {
        // demo_3cn_*.txt, 0x1F22/1: the CN's 0x1600/1 and 0x1A00/1.
        let rx = MappingEntry::from_raw(0x0008_0000_0001_6200);
        assert_eq!(
            rx,
            MappingEntry { index: 0x6200, subindex: 1, reserved: 0, bit_offset: 0, bit_length: 8 }
        );
        assert_eq!(rx.to_raw(), 0x0008_0000_0001_6200);
        let mn = MappingEntry::from_raw(0x0008_0000_0001_A4C0);
        assert_eq!((mn.index, mn.subindex, mn.bit_length), (0xA4C0, 1, 8));
        let odd = MappingEntry::from_raw(0x0010_0018_7F02_2001);
        assert_eq!(
            odd,
            MappingEntry { index: 0x2001, subindex: 2, reserved: 0x7F, bit_offset: 24, bit_length: 16 }
        );
        assert_eq!(odd.to_raw(), 0x0010_0018_7F02_2001);
    }

    #[test]
    fn direction_of_indices() {
        assert_eq!(PdoDirection::of_mapping_index(0x1600), Some((PdoDirection::Receive, 0)));
        assert_eq!(PdoDirection::of_mapping_index(0x16FF), Some((PdoDirection::Receive, 255)));
        assert_eq!(PdoDirection::of_mapping_index(0x1A02), Some((PdoDirection::Transmit, 2)));
        assert_eq!(PdoDirection::of_mapping_index(0x1800), None);
        assert_eq!(PdoDirection::of_mapping_index(0x1700), None);
        assert!(PdoDirection::is_pdo_object(0x1400));
        assert!(PdoDirection::is_pdo_object(0x1AFF));
        assert!(!PdoDirection::is_pdo_object(0x1C00));
        assert!(!PdoDirection::is_pdo_object(0x1700));
    }

    #[test]
    fn put_and_take_bits_and_bytes() {
        let bit = MappedObject {
            index: 1,
            subindex: 1,
            data_type: DataType::Boolean,
            bit_offset: 10,
            bit_length: 1,
        };
        assert_eq!((bit.byte_offset(), bit.bit_in_byte(), bit.byte_len()), (1, 2, 1));
        let mut p = [0u8; 3];
        put(&mut p, &bit, &[1]);
        assert_eq!(p, [0, 0b100, 0]);
        assert_eq!(take(&p, &bit), Some(vec![1]));
        put(&mut p, &bit, &[0]);
        assert_eq!(p, [0; 3]);
        let word = MappedObject {
            index: 2,
            subindex: 1,
            data_type: DataType::Unsigned16,
            bit_offset: 8,
            bit_length: 16,
        };
        put(&mut p, &word, &[0x34, 0x12]);
        assert_eq!(p, [0, 0x34, 0x12]);
        assert_eq!(take(&p, &word), Some(vec![0x34, 0x12]));
        assert_eq!(take(&p[..2], &word), None);
    }
}
