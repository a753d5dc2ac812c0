//! A POWERLINK object dictionary (sans-IO): entries by index and subindex with their data
//! type, SDO access, PDO mappability, value range and current value (little-endian bytes).
//!
//! * [`ObjectDictionary`] serves an SDO server through [`ObjectAccess`] (every refusal is an
//!   [`SdoAbortCode`]), gives the runtime typed getters ([`ObjectDictionary::u32`] ...) and
//!   setters that bypass SDO access rights ([`ObjectDictionary::set`]), and keeps the PDO
//!   channels: [`ObjectDictionary::pres_payload`] builds the PRes payload from the TPDO
//!   mapping, [`ObjectDictionary::apply_preq_payload`] writes the RPDO-mapped objects from a
//!   PReq payload.
//! * [`ObjectDictionary::controlled_node`] (`cn_profile.rs`) builds the dictionary of a CN
//!   that the openPOWERLINK demo MN boots and configures: the communication profile and the
//!   CiA 401 digital I/O of openPOWERLINK's `00000000_POWERLINK_CiA401_CN.xdd`.
//! * [`ObjectDictionary::safety_node`] (`safety_node.rs`) adds to it the safety lease object
//!   of a supervisor that is a CN (0x2100), mapped into its PRes by default.
//! * `mapping.rs`: the 64-bit mapping entries and the typed [`PdoMapping`].
//! * [`ObjectDictionary::from_xdd`] (`xdd.rs`) reads the dictionary from a POWERLINK device
//!   description (XDD, or an XDC with configured `actualValue`s) instead.
//!
//! A PDO mapping is checked whenever it could change: a write that would leave an enabled
//! mapping invalid (object missing or not mappable, layout, overlap, payload limit) is
//! refused and changes nothing, so the enabled mappings are always valid. Mapping entries
//! (subindex 1..) can be written only while subindex 0 is 0 (CiA 301's disable, change,
//! enable sequence, which openPOWERLINK's MN follows: `demo_3cn_*.txt`).

mod cn_profile;
mod entry;
mod mapping;
mod safety_node;
mod xdd;

use std::collections::{BTreeMap, BTreeSet};
use std::ops::RangeInclusive;

pub use cn_profile::{DeviceIdentity, MOTUS_CN_FEATURE_FLAGS};
pub use entry::{Access, DataType, Entry, Object, ObjectKind, PdoMappable};
pub use mapping::{
    MappedObject, MappingEntry, MappingError, PdoDirection, PdoError, PdoMapping, ISOCHRONOUS_MAX_PAYLOAD,
    RPDO_COMM_BASE, RPDO_MAPPING_BASE, TPDO_COMM_BASE, TPDO_MAPPING_BASE,
};
pub use safety_node::{SafetyNodeTiming, SAFETY_LEASE_OBJECT};
pub use xdd::{XddError, XddLocation};

use crate::object_access::{ObjectAccess, SdoAbortCode};

/// NMT_CycleTiming_REC: subindex 4 PReqActPayloadLimit_U16, 5 PResActPayloadLimit_U16.
const CYCLE_TIMING: u16 = 0x1F98;
/// NMT_PReqPayloadLimitList_AU16 (MN: PReq payload limit per CN).
const PREQ_LIMIT_LIST: u16 = 0x1F8B;
/// NMT_PResPayloadLimitList_AU16 (PRes payload limit per node).
const PRES_LIMIT_LIST: u16 = 0x1F8D;

/// An object dictionary: objects by index, each with its entries by subindex.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ObjectDictionary {
    objects: BTreeMap<u16, Object>,
    remote_writes: BTreeSet<(u16, u8)>,
    rpdo: Vec<PdoMapping>,
    tpdo: Vec<PdoMapping>,
}

impl ObjectDictionary {
    /// An empty dictionary.
    pub fn new() -> Self {
        ObjectDictionary::default()
    }

    /// Adds or replaces the object at `index`, returning the one it replaced. An enabled PDO
    /// mapping that the change makes invalid (the checks of [`ObjectDictionary::pdo_mapping`])
    /// is left out of the PDO channels.
    pub fn insert(&mut self, index: u16, object: Object) -> Option<Object> {
        let old = self.objects.insert(index, object);
        let _ = self.refresh_pdo();
        old
    }

    /// The object at `index`.
    pub fn object(&self, index: u16) -> Option<&Object> {
        self.objects.get(&index)
    }

    /// The entry at `index`/`subindex`.
    pub fn entry(&self, index: u16, subindex: u8) -> Option<&Entry> {
        self.objects.get(&index)?.entry(subindex)
    }

    /// The objects in index order.
    pub fn objects(&self) -> impl Iterator<Item = (u16, &Object)> {
        self.objects.iter().map(|(i, o)| (*i, o))
    }

    /// Number of objects (indices).
    pub fn len(&self) -> usize {
        self.objects.len()
    }

    /// No object at all.
    pub fn is_empty(&self) -> bool {
        self.objects.is_empty()
    }

    /// The current value of `index`/`subindex` (little-endian bytes), whatever its access.
    pub fn value(&self, index: u16, subindex: u8) -> Option<&[u8]> {
        self.entry(index, subindex).map(Entry::value)
    }

    fn fixed<const N: usize>(&self, index: u16, subindex: u8) -> Option<[u8; N]> {
        self.value(index, subindex)?.try_into().ok()
    }

    /// A one-byte value (UNSIGNED8), `None` if absent or not one byte long.
    pub fn u8(&self, index: u16, subindex: u8) -> Option<u8> {
        self.fixed(index, subindex).map(u8::from_le_bytes)
    }

    /// A two-byte value (UNSIGNED16), `None` if absent or of another size.
    pub fn u16(&self, index: u16, subindex: u8) -> Option<u16> {
        self.fixed(index, subindex).map(u16::from_le_bytes)
    }

    /// A four-byte value (UNSIGNED32), `None` if absent or of another size.
    pub fn u32(&self, index: u16, subindex: u8) -> Option<u32> {
        self.fixed(index, subindex).map(u32::from_le_bytes)
    }

    /// An eight-byte value (UNSIGNED64), `None` if absent or of another size.
    pub fn u64(&self, index: u16, subindex: u8) -> Option<u64> {
        self.fixed(index, subindex).map(u64::from_le_bytes)
    }

    /// A one-byte value as INTEGER8.
    pub fn i8(&self, index: u16, subindex: u8) -> Option<i8> {
        self.fixed(index, subindex).map(i8::from_le_bytes)
    }

    /// A two-byte value as INTEGER16.
    pub fn i16(&self, index: u16, subindex: u8) -> Option<i16> {
        self.fixed(index, subindex).map(i16::from_le_bytes)
    }

    /// A four-byte value as INTEGER32.
    pub fn i32(&self, index: u16, subindex: u8) -> Option<i32> {
        self.fixed(index, subindex).map(i32::from_le_bytes)
    }

    /// An eight-byte value as INTEGER64.
    pub fn i64(&self, index: u16, subindex: u8) -> Option<i64> {
        self.fixed(index, subindex).map(i64::from_le_bytes)
    }

    /// A four-byte value as REAL32.
    pub fn f32(&self, index: u16, subindex: u8) -> Option<f32> {
        self.fixed(index, subindex).map(f32::from_le_bytes)
    }

    /// A one-byte value as BOOLEAN (non-zero is true).
    pub fn bool(&self, index: u16, subindex: u8) -> Option<bool> {
        self.u8(index, subindex).map(|v| v != 0)
    }

    /// A VISIBLE_STRING's text, `None` if absent or not UTF-8.
    pub fn visible_string(&self, index: u16, subindex: u8) -> Option<&str> {
        std::str::from_utf8(self.value(index, subindex)?).ok()
    }

    /// Sets a value as the device itself does (the runtime: NMT state, inputs, counters):
    /// SDO access rights are not checked, everything else is as for an SDO write (existence,
    /// size, range, PDO mapping consistency). Not recorded in
    /// [`ObjectDictionary::take_remote_writes`].
    ///
    /// # Errors
    /// The abort code an SDO write of the same value would get, access rights aside.
    pub fn set(&mut self, index: u16, subindex: u8, value: &[u8]) -> Result<(), SdoAbortCode> {
        self.update(index, subindex, value, false)
    }

    /// [`ObjectDictionary::set`] of a one-byte value.
    ///
    /// # Errors
    /// As [`ObjectDictionary::set`].
    pub fn set_u8(&mut self, index: u16, subindex: u8, value: u8) -> Result<(), SdoAbortCode> {
        self.set(index, subindex, &[value])
    }

    /// [`ObjectDictionary::set`] of a two-byte value.
    ///
    /// # Errors
    /// As [`ObjectDictionary::set`].
    pub fn set_u16(&mut self, index: u16, subindex: u8, value: u16) -> Result<(), SdoAbortCode> {
        self.set(index, subindex, &value.to_le_bytes())
    }

    /// [`ObjectDictionary::set`] of a four-byte value.
    ///
    /// # Errors
    /// As [`ObjectDictionary::set`].
    pub fn set_u32(&mut self, index: u16, subindex: u8, value: u32) -> Result<(), SdoAbortCode> {
        self.set(index, subindex, &value.to_le_bytes())
    }

    /// [`ObjectDictionary::set`] of an eight-byte value.
    ///
    /// # Errors
    /// As [`ObjectDictionary::set`].
    pub fn set_u64(&mut self, index: u16, subindex: u8, value: u64) -> Result<(), SdoAbortCode> {
        self.set(index, subindex, &value.to_le_bytes())
    }

    /// [`ObjectDictionary::set`] of an INTEGER8.
    ///
    /// # Errors
    /// As [`ObjectDictionary::set`].
    pub fn set_i8(&mut self, index: u16, subindex: u8, value: i8) -> Result<(), SdoAbortCode> {
        self.set(index, subindex, &value.to_le_bytes())
    }

    /// [`ObjectDictionary::set`] of an INTEGER16.
    ///
    /// # Errors
    /// As [`ObjectDictionary::set`].
    pub fn set_i16(&mut self, index: u16, subindex: u8, value: i16) -> Result<(), SdoAbortCode> {
        self.set(index, subindex, &value.to_le_bytes())
    }

    /// [`ObjectDictionary::set`] of an INTEGER32.
    ///
    /// # Errors
    /// As [`ObjectDictionary::set`].
    pub fn set_i32(&mut self, index: u16, subindex: u8, value: i32) -> Result<(), SdoAbortCode> {
        self.set(index, subindex, &value.to_le_bytes())
    }

    /// [`ObjectDictionary::set`] of a BOOLEAN.
    ///
    /// # Errors
    /// As [`ObjectDictionary::set`].
    pub fn set_bool(&mut self, index: u16, subindex: u8, value: bool) -> Result<(), SdoAbortCode> {
        self.set(index, subindex, &[u8::from(value)])
    }

    /// [`ObjectDictionary::set`] that also makes `value` the entry's default, which the NMT
    /// resets restore ([`ObjectDictionary::restore_defaults`]): the device's own
    /// configuration, such as a default PDO mapping.
    ///
    /// # Errors
    /// As [`ObjectDictionary::set`]; nothing changes then.
    pub fn set_default(&mut self, index: u16, subindex: u8, value: &[u8]) -> Result<(), SdoAbortCode> {
        self.set(index, subindex, value)?;
        if let Some(entry) = self.objects.get_mut(&index).and_then(|o| o.entry_mut(subindex)) {
            entry.keep_as_default();
        }
        Ok(())
    }

    /// The entries written through [`ObjectAccess::write`] (by an SDO client) since the last
    /// call, so the runtime can act on them (a new cycle length 0x1006, a reset command
    /// 0x1F9E ...).
    pub fn take_remote_writes(&mut self) -> BTreeSet<(u16, u8)> {
        std::mem::take(&mut self.remote_writes)
    }

    /// Puts every entry of the objects in `indices` back to the value it was built with, as
    /// the NMT resets do (openPOWERLINK: ResetCommunication restores the communication
    /// profile 0x1000-0x1FFF, ResetNode/ResetApplication everything). The PDO channels follow.
    pub fn restore_defaults(&mut self, indices: RangeInclusive<u16>) {
        for object in self.objects.range_mut(indices).map(|(_, o)| o) {
            for sub in object.entries().map(|(s, _)| s).collect::<Vec<_>>() {
                if let Some(e) = object.entry_mut(sub) {
                    e.restore();
                }
            }
        }
        let _ = self.refresh_pdo();
    }

    /// The existence, access, size and range checks and the store, for SDO (`remote`) and
    /// local writes.
    fn update(&mut self, index: u16, subindex: u8, value: &[u8], remote: bool) -> Result<(), SdoAbortCode> {
        let object = self.objects.get(&index).ok_or(SdoAbortCode::ObjectDoesNotExist)?;
        let entry = object.entry(subindex).ok_or(SdoAbortCode::SubIndexDoesNotExist)?;
        if remote && !entry.access().writable() {
            return Err(SdoAbortCode::ReadOnly);
        }
        entry.check(value)?;
        let mapping_entry = subindex != 0 && PdoDirection::of_mapping_index(index).is_some();
        if mapping_entry && self.u8(index, 0).is_some_and(|n| n != 0) {
            return Err(SdoAbortCode::UnsupportedAccess);
        }
        let affects_pdo = PdoDirection::is_pdo_object(index)
            || matches!(index, CYCLE_TIMING | PREQ_LIMIT_LIST | PRES_LIMIT_LIST);
        let entry = self
            .objects
            .get_mut(&index)
            .and_then(|o| o.entry_mut(subindex))
            .ok_or(SdoAbortCode::SubIndexDoesNotExist)?;
        let old = entry.value().to_vec();
        entry.store(value);
        if affects_pdo {
            if let Err(e) = self.refresh_pdo() {
                if let Some(entry) = self.objects.get_mut(&index).and_then(|o| o.entry_mut(subindex)) {
                    entry.store(&old);
                }
                let _ = self.refresh_pdo();
                return Err(e.abort_code());
            }
        }
        if remote {
            self.remote_writes.insert((index, subindex));
        }
        Ok(())
    }

    /// The payload limit of the frame a channel goes with, in bytes.
    fn payload_limit(&self, direction: PdoDirection, node_id: u8) -> u16 {
        let limit = match (direction, node_id) {
            (PdoDirection::Receive, 0) => self.u16(CYCLE_TIMING, 4),
            (PdoDirection::Transmit, 0) => self.u16(CYCLE_TIMING, 5),
            (PdoDirection::Receive, n) => self.u16(PRES_LIMIT_LIST, n),
            (PdoDirection::Transmit, n) => self.u16(PREQ_LIMIT_LIST, n),
        };
        limit.unwrap_or(ISOCHRONOUS_MAX_PAYLOAD)
    }

    /// The mapping of `mapping_index` (0x1600+n or 0x1A00+n) decoded and checked against the
    /// dictionary: `Ok(None)` when disabled (subindex 0 is 0) or not a mapping object.
    ///
    /// Checks, per enabled entry: the mapped object exists; it is mappable in this direction
    /// (and readable for a TPDO, not const for an RPDO); its length is its type's size (1 bit
    /// or 8 for a BOOLEAN; whole bytes within the capacity for strings and domains); a
    /// multi-bit object starts on a byte; entries do not overlap; the payload fits the
    /// frame's limit (0x1F98/4 for the PReq, 0x1F98/5 for the own PRes, 0x1F8D/n for node
    /// n's PRes, 0x1F8B/n for an MN's PReq to node n; 1490 bytes without such an object).
    ///
    /// # Errors
    /// The first check that fails.
    pub fn pdo_mapping(&self, mapping_index: u16) -> Result<Option<PdoMapping>, MappingError> {
        let Some((direction, _)) = PdoDirection::of_mapping_index(mapping_index) else {
            return Ok(None);
        };
        let count = self.u8(mapping_index, 0).unwrap_or(0);
        if count == 0 {
            return Ok(None);
        }
        let comm_index = direction.comm_base() + (mapping_index - direction.mapping_base());
        let node_id = self.u8(comm_index, 1).unwrap_or(0);
        let version = self.u8(comm_index, 2).unwrap_or(0);
        let mut objects: Vec<(u8, MappedObject)> = Vec::with_capacity(count.into());
        for subindex in 1..=count {
            let raw = self
                .u64(mapping_index, subindex)
                .ok_or(MappingError::MissingEntry { mapping: mapping_index, subindex })?;
            let m = MappingEntry::from_raw(raw);
            let object = self.check_mapped(direction, mapping_index, subindex, m)?;
            let (start, end) = (u32::from(object.bit_offset), object.bit_end());
            let overlap = objects.iter().find(|(_, o)| u32::from(o.bit_offset) < end && start < o.bit_end());
            if let Some((first, _)) = overlap {
                return Err(MappingError::Overlap {
                    mapping: mapping_index,
                    first: *first,
                    second: subindex,
                });
            }
            objects.push((subindex, object));
        }
        let mapping = PdoMapping {
            direction,
            comm_index,
            mapping_index,
            node_id,
            version,
            objects: objects.into_iter().map(|(_, o)| o).collect(),
        };
        let limit = self.payload_limit(direction, node_id);
        if mapping.byte_len() > usize::from(limit) {
            return Err(MappingError::TooLong { mapping: mapping_index, bytes: mapping.byte_len(), limit });
        }
        Ok(Some(mapping))
    }

    /// One mapping entry checked against the dictionary.
    fn check_mapped(
        &self,
        direction: PdoDirection,
        mapping: u16,
        subindex: u8,
        m: MappingEntry,
    ) -> Result<MappedObject, MappingError> {
        let (index, object_subindex) = (m.index, m.subindex);
        let entry = self.entry(index, object_subindex).ok_or(MappingError::ObjectMissing {
            mapping,
            subindex,
            index,
            object_subindex,
        })?;
        let mappable = match direction {
            PdoDirection::Transmit => entry.pdo_mappable().tpdo() && entry.access().readable(),
            PdoDirection::Receive => entry.pdo_mappable().rpdo() && entry.access() != Access::Const,
        };
        if !mappable {
            return Err(MappingError::NotMappable { mapping, subindex, index, object_subindex });
        }
        let bits = usize::from(m.bit_length);
        let length_ok = match entry.data_type().size() {
            Some(size) => bits == size * 8 || (entry.data_type() == DataType::Boolean && bits == 1),
            None => bits > 0 && bits % 8 == 0 && bits / 8 <= entry.max_len(),
        };
        let aligned = bits == 1 || m.bit_offset % 8 == 0;
        if !length_ok || !aligned {
            return Err(MappingError::BadLayout {
                mapping,
                subindex,
                index,
                object_subindex,
                bit_offset: m.bit_offset,
                bit_length: m.bit_length,
            });
        }
        Ok(MappedObject {
            index,
            subindex: object_subindex,
            data_type: entry.data_type(),
            bit_offset: m.bit_offset,
            bit_length: m.bit_length,
        })
    }

    /// Rebuilds the enabled PDO channels; the first invalid one is reported (and left out).
    fn refresh_pdo(&mut self) -> Result<(), MappingError> {
        let mut rpdo: Vec<PdoMapping> = Vec::new();
        let mut tpdo: Vec<PdoMapping> = Vec::new();
        let mut first_error = None;
        let mapping_indices: Vec<u16> = self
            .objects
            .range(RPDO_MAPPING_BASE..=RPDO_MAPPING_BASE + 0xFF)
            .chain(self.objects.range(TPDO_MAPPING_BASE..=TPDO_MAPPING_BASE + 0xFF))
            .map(|(i, _)| *i)
            .collect();
        for index in mapping_indices {
            match self.pdo_mapping(index) {
                Ok(Some(m)) => {
                    let list = match m.direction {
                        PdoDirection::Receive => &mut rpdo,
                        PdoDirection::Transmit => &mut tpdo,
                    };
                    if let Some(other) = list.iter().find(|o| o.node_id == m.node_id) {
                        first_error.get_or_insert(MappingError::DuplicateChannel {
                            mapping: index,
                            node_id: m.node_id,
                            other: other.mapping_index,
                        });
                    } else {
                        list.push(m);
                    }
                }
                Ok(None) => {}
                Err(e) => {
                    first_error.get_or_insert(e);
                }
            }
        }
        self.rpdo = rpdo;
        self.tpdo = tpdo;
        first_error.map_or(Ok(()), Err)
    }

    /// The enabled TPDO channel for node `node_id`'s frame (0: this node's own PRes; on an
    /// MN, n: the PReq to node n). POWERLINK has one channel per frame.
    pub fn tpdo(&self, node_id: u8) -> Option<&PdoMapping> {
        self.tpdo.iter().find(|m| m.node_id == node_id)
    }

    /// The enabled RPDO channel for node `node_id`'s frame (0: the PReq to this node; n:
    /// node n's PRes).
    pub fn rpdo(&self, node_id: u8) -> Option<&PdoMapping> {
        self.rpdo.iter().find(|m| m.node_id == node_id)
    }

    /// The payload of this node's PRes: the TPDO-mapped objects (channel with NodeID 0) at
    /// their mapped offsets, as long as the mapping ([`PdoMapping::byte_len`], the PRes size
    /// field); empty when no TPDO is enabled. Padding the frame is the caller's.
    pub fn pres_payload(&self) -> Vec<u8> {
        self.tpdo_payload(0)
    }

    /// The payload of the TPDO channel for node `node_id`'s frame (see
    /// [`ObjectDictionary::tpdo`]); empty when there is none.
    pub fn tpdo_payload(&self, node_id: u8) -> Vec<u8> {
        let Some(mapping) = self.tpdo(node_id) else {
            return Vec::new();
        };
        let mut out = vec![0; mapping.byte_len()];
        for object in &mapping.objects {
            if let Some(value) = self.value(object.index, object.subindex) {
                mapping::put(&mut out, object, value);
            }
        }
        out
    }

    /// Writes the RPDO-mapped objects (channel with NodeID 0) from a PReq payload; returns
    /// how many objects were written (0 without an enabled RPDO for the PReq). Whether the
    /// PReq's RD flag and PDO version allow using the payload is the caller's decision.
    ///
    /// # Errors
    /// [`PdoError::PayloadTooShort`]: the payload ends before the mapping does; nothing is
    /// written.
    pub fn apply_preq_payload(&mut self, payload: &[u8]) -> Result<usize, PdoError> {
        self.apply_rpdo_payload(0, payload)
    }

    /// Writes the objects of the RPDO channel for node `node_id`'s frame (0: the PReq, n: node
    /// n's PRes, cross traffic) from its payload; returns how many objects were written.
    ///
    /// # Errors
    /// [`PdoError::PayloadTooShort`]: the payload ends before the mapping does; nothing is
    /// written.
    pub fn apply_rpdo_payload(&mut self, node_id: u8, payload: &[u8]) -> Result<usize, PdoError> {
        let ObjectDictionary { objects, rpdo, .. } = self;
        let Some(mapping) = rpdo.iter().find(|m| m.node_id == node_id) else {
            return Ok(0);
        };
        let needed = mapping.byte_len();
        if payload.len() < needed {
            return Err(PdoError::PayloadTooShort {
                node_id,
                mapping: mapping.mapping_index,
                needed,
                got: payload.len(),
            });
        }
        let mut written = 0;
        for object in &mapping.objects {
            let value = mapping::take(payload, object);
            let entry = objects.get_mut(&object.index).and_then(|o| o.entry_mut(object.subindex));
            if let (Some(value), Some(entry)) = (value, entry) {
                entry.store(&value);
                written += 1;
            }
        }
        Ok(written)
    }
}

impl ObjectAccess for ObjectDictionary {
    fn read(&mut self, index: u16, subindex: u8) -> Result<Vec<u8>, SdoAbortCode> {
        let object = self.objects.get(&index).ok_or(SdoAbortCode::ObjectDoesNotExist)?;
        let entry = object.entry(subindex).ok_or(SdoAbortCode::SubIndexDoesNotExist)?;
        if !entry.access().readable() {
            return Err(SdoAbortCode::WriteOnly);
        }
        Ok(entry.value().to_vec())
    }

    fn write(&mut self, index: u16, subindex: u8, value: &[u8]) -> Result<(), SdoAbortCode> {
        self.update(index, subindex, value, true)
    }
}

#[cfg(test)]
mod tests;
