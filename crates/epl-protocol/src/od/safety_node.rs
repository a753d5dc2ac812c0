//! The dictionary of a safety node: a supervisor that takes part in the segment as a CN and
//! publishes SafeToRun in its PRes, which every node of the segment receives (cross traffic).
//!
//! It is the CN dictionary of [`ObjectDictionary::controlled_node`] plus the manufacturer
//! object [`SAFETY_LEASE_OBJECT`] (0x2100, `MOTUS_SafetyLease_REC`), mapped by default into
//! the PRes (TPDO 0x1A00, defaults that every NMT reset restores), so that the PRes payload is
//! exactly the body of a [`crate::SafetyLease`]:
//!
//! | sub | PRes offset | type | meaning |
//! |---|---|---|---|
//! | 1 | 0 | UNSIGNED8 | layout version, 1 |
//! | 2 | 1 | UNSIGNED8 | bit 0: SafeToRun |
//! | 3 | 2 | UNSIGNED16 | lease counter: advances with every PRes the node sends |
//! | 4 | 4 | UNSIGNED32 | validity from reception, microseconds |
//! | 5 | 8 | OCTET_STRING(8) | first 8 bytes of the approved configuration fingerprint |
//!
//! A drive that follows a safety node takes a renewal only from that node's PRes, with the
//! RD flag set (the node is OPERATIONAL) and a counter that advanced; SafeToRun false stops it
//! at once, and no renewal within its lease time stops it too (a supervisor that died, or a
//! node that answers from a frozen buffer).

use std::time::Duration;

use super::entry::{Access, Entry, Object, PdoMappable};
use super::mapping::{MappingEntry, TPDO_MAPPING_BASE};
use super::{DeviceIdentity, ObjectDictionary};

/// Index of the safety lease record (manufacturer-specific area).
pub const SAFETY_LEASE_OBJECT: u16 = 0x2100;

/// NMT_CycleLen_U32 (µs).
const CYCLE_LEN: u16 = 0x1006;
/// DLL_CNLossOfSocTolerance_U32 (ns).
const SOC_TOLERANCE: u16 = 0x1C14;

/// The cycle the safety node expects until an MN configures it otherwise by SDO.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SafetyNodeTiming {
    /// The cycle length (0x1006).
    pub cycle: Duration,
    /// How late a SoC may be before it counts as lost (0x1C14).
    pub soc_tolerance: Duration,
}

impl Default for SafetyNodeTiming {
    /// 1 ms cycle, 1 ms tolerance.
    fn default() -> Self {
        Self { cycle: Duration::from_millis(1), soc_tolerance: Duration::from_millis(1) }
    }
}

/// (subindex, entry, bit offset, bit length) of the lease record.
fn lease_entries() -> [(u8, Entry, u16, u16); 5] {
    let tpdo = |e: Entry| e.pdo(PdoMappable::Tpdo);
    [
        (1, tpdo(Entry::unsigned8("LayoutVersion_U8", Access::Const, 1)), 0, 8),
        (2, tpdo(Entry::unsigned8("SafeToRun_U8", Access::ReadOnly, 0)), 8, 8),
        (3, tpdo(Entry::unsigned16("LeaseCounter_U16", Access::ReadOnly, 0)), 16, 16),
        (4, tpdo(Entry::unsigned32("ValidFor_us_U32", Access::ReadOnly, 0)), 32, 32),
        (5, tpdo(Entry::octet_string("Fingerprint_OSTR", Access::ReadOnly, &[0; 8])), 64, 64),
    ]
}

impl ObjectDictionary {
    /// The dictionary of a safety node with ID `node_id` (see the module documentation):
    /// [`ObjectDictionary::controlled_node`], the lease record 0x2100 mapped into the PRes,
    /// and `timing` as the default cycle length and loss-of-SoC tolerance.
    pub fn safety_node(node_id: u8, identity: &DeviceIdentity, timing: SafetyNodeTiming) -> ObjectDictionary {
        let mut od = ObjectDictionary::controlled_node(node_id, identity);
        let entries = lease_entries();
        od.insert(
            SAFETY_LEASE_OBJECT,
            Object::record("MOTUS_SafetyLease_REC", entries.iter().map(|e| e.1.clone())),
        );
        let cycle_us = u32::try_from(timing.cycle.as_micros()).unwrap_or(u32::MAX);
        let tolerance_ns = u32::try_from(timing.soc_tolerance.as_nanos()).unwrap_or(u32::MAX);
        let mut results = vec![
            od.set_default(CYCLE_LEN, 0, &cycle_us.to_le_bytes()),
            od.set_default(SOC_TOLERANCE, 0, &tolerance_ns.to_le_bytes()),
        ];
        for (sub, _, bit_offset, bit_length) in &entries {
            let entry = MappingEntry {
                index: SAFETY_LEASE_OBJECT,
                subindex: *sub,
                reserved: 0,
                bit_offset: *bit_offset,
                bit_length: *bit_length,
            };
            results.push(od.set_default(TPDO_MAPPING_BASE, *sub, &entry.to_raw().to_le_bytes()));
        }
        let count = u8::try_from(entries.len()).unwrap_or(0);
        results.push(od.set_default(TPDO_MAPPING_BASE, 0, &[count]));
        // The table above is fixed and checked by the tests; a failure would leave the PRes
        // without the lease, which every drive reads as "not safe" (fail closed).
        debug_assert!(results.iter().all(Result::is_ok), "safety node dictionary: {results:?}");
        od
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use crate::SafetyLease;

    #[test]
    fn the_pres_payload_is_the_lease_body_and_survives_a_reset() {
        let timing =
            SafetyNodeTiming { cycle: Duration::from_micros(400), soc_tolerance: Duration::from_millis(2) };
        let mut od = ObjectDictionary::safety_node(100, &DeviceIdentity::default(), timing);
        assert_eq!(od.u32(CYCLE_LEN, 0), Some(400));
        assert_eq!(od.u32(SOC_TOLERANCE, 0), Some(2_000_000));
        od.set_u8(SAFETY_LEASE_OBJECT, 2, 1).unwrap();
        od.set_u16(SAFETY_LEASE_OBJECT, 3, 0x0102).unwrap();
        od.set_u32(SAFETY_LEASE_OBJECT, 4, 20_000).unwrap();
        od.set(SAFETY_LEASE_OBJECT, 5, &[7; 8]).unwrap();
        let lease = SafetyLease { safe: true, seq: 0x0102, valid_for_us: 20_000, fingerprint: [7; 8] };
        assert_eq!(od.pres_payload(), lease.encode().to_vec());
        assert_eq!(SafetyLease::decode(&od.pres_payload()), Some(lease));
        // An NMT reset restores the communication profile: the mapping stays, the values of
        // the lease go back to "not safe".
        od.restore_defaults(0x0000..=0xFFFF);
        assert_eq!(od.u32(CYCLE_LEN, 0), Some(400));
        let back = SafetyLease::decode(&od.pres_payload()).unwrap();
        assert!(!back.safe);
        assert_eq!(back.seq, 0);
    }
}
