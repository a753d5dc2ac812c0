//! PDO configuration (CiA 301 §7.5.2.35–38) and packing of mapped values.
//!
//! [`PdoConfig::sdo_writes`] gives the ordered SDO writes that reconfigure one PDO the way
//! CANopenNode and python-canopen expect: disable (COB-ID bit 31), transmission type,
//! inhibit time, event timer, SYNC start, mapping sub 0 = 0, the entries, sub 0 = N,
//! then the final COB-ID.

/// COB-ID bit 31: PDO not valid.
pub const COB_ID_INVALID: u32 = 0x8000_0000;

/// Direction of a PDO seen from the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PdoDirection {
    /// Receive PDO (master → device): parameters 0x1400+n, mapping 0x1600+n.
    Rpdo,
    /// Transmit PDO (device → master): parameters 0x1800+n, mapping 0x1A00+n.
    Tpdo,
}

/// Why a PDO configuration or packing is invalid.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PdoError {
    /// PDO number outside 1..=512.
    #[error("PDO number {0} outside 1..=512")]
    BadNumber(u16),
    /// More than 8 entries or more than 64 bits mapped.
    #[error("mapping of {entries} entries / {bits} bits exceeds 8 entries / 64 bits")]
    TooLong {
        /// Entries.
        entries: usize,
        /// Total bits.
        bits: u32,
    },
    /// An entry of length 0 or above 64 bits.
    #[error("mapping entry 0x{index:04X}:{sub:02X} has invalid length {bits} bits")]
    BadEntry {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Length.
        bits: u8,
    },
    /// A field that only TPDOs have (inhibit time, SYNC start) was given for an RPDO.
    #[error("{0} is not a parameter of an RPDO")]
    NotForRpdo(&'static str),
    /// The number of values does not match the mapping.
    #[error("{values} values for {entries} mapped entries")]
    ValueCount {
        /// Values given.
        values: usize,
        /// Entries mapped.
        entries: usize,
    },
    /// The PDO data is shorter than the mapping.
    #[error("PDO data of {len} bytes is shorter than the mapping ({bits} bits)")]
    DataTooShort {
        /// Data length.
        len: usize,
        /// Mapping length.
        bits: u32,
    },
}

/// Configuration of one PDO.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PdoConfig {
    /// COB-ID written last (bit 31 set = leave the PDO disabled; for TPDOs bit 30 = no RTR).
    pub cob_id: u32,
    /// Transmission type (0–240 synchronous, 254/255 event-driven).
    pub transmission_type: u8,
    /// TPDO inhibit time in 100 µs units (sub 3), written if present.
    pub inhibit_100us: Option<u16>,
    /// Event timer in ms (sub 5), written if present.
    pub event_timer_ms: Option<u16>,
    /// TPDO SYNC start value (sub 6), written if present.
    pub sync_start: Option<u8>,
    /// Mapped objects in order: (index, sub-index, length in bits).
    pub mapping: Vec<(u16, u8, u8)>,
}

/// One SDO write of a configuration sequence.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SdoWrite {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Little-endian value.
    pub data: Vec<u8>,
}

fn w(index: u16, sub: u8, data: &[u8]) -> SdoWrite {
    SdoWrite { index, sub, data: data.to_vec() }
}

/// Checks a mapping and returns its total length in bits.
pub fn mapping_bits(mapping: &[(u16, u8, u8)]) -> Result<u32, PdoError> {
    let mut bits = 0u32;
    for &(index, sub, len) in mapping {
        if len == 0 || len > 64 {
            return Err(PdoError::BadEntry { index, sub, bits: len });
        }
        bits += u32::from(len);
    }
    if mapping.len() > 8 || bits > 64 {
        return Err(PdoError::TooLong { entries: mapping.len(), bits });
    }
    Ok(bits)
}

/// A mapping entry as stored in 0x1600/0x1A00 sub 1..8: index << 16 | sub << 8 | bits.
pub fn mapping_entry(index: u16, sub: u8, bits: u8) -> u32 {
    u32::from(index) << 16 | u32::from(sub) << 8 | u32::from(bits)
}

impl PdoConfig {
    /// The ordered SDO writes configuring PDO `number` (1-based) in `direction`.
    pub fn sdo_writes(&self, direction: PdoDirection, number: u16) -> Result<Vec<SdoWrite>, PdoError> {
        if !(1..=512).contains(&number) {
            return Err(PdoError::BadNumber(number));
        }
        let (comm, map) = match direction {
            PdoDirection::Rpdo => (0x1400 + number - 1, 0x1600 + number - 1),
            PdoDirection::Tpdo => (0x1800 + number - 1, 0x1A00 + number - 1),
        };
        if direction == PdoDirection::Rpdo {
            if self.inhibit_100us.is_some() {
                return Err(PdoError::NotForRpdo("inhibit time"));
            }
            if self.sync_start.is_some() {
                return Err(PdoError::NotForRpdo("SYNC start value"));
            }
        }
        mapping_bits(&self.mapping)?;
        let mut out = vec![
            w(comm, 1, &(self.cob_id | COB_ID_INVALID).to_le_bytes()),
            w(comm, 2, &[self.transmission_type]),
        ];
        if let Some(v) = self.inhibit_100us {
            out.push(w(comm, 3, &v.to_le_bytes()));
        }
        if let Some(v) = self.event_timer_ms {
            out.push(w(comm, 5, &v.to_le_bytes()));
        }
        if let Some(v) = self.sync_start {
            out.push(w(comm, 6, &[v]));
        }
        out.push(w(map, 0, &[0]));
        for (i, &(index, sub, bits)) in self.mapping.iter().enumerate() {
            let n = u8::try_from(i + 1).unwrap_or(u8::MAX);
            out.push(w(map, n, &mapping_entry(index, sub, bits).to_le_bytes()));
        }
        out.push(w(map, 0, &[u8::try_from(self.mapping.len()).unwrap_or(u8::MAX)]));
        out.push(w(comm, 1, &self.cob_id.to_le_bytes()));
        Ok(out)
    }
}

/// Packs raw values (the low `bits` of each) into PDO data, least significant bit first,
/// in mapping order (CiA 301 §7.4.7.1: little-endian, entries back to back).
pub fn pack(mapping: &[(u16, u8, u8)], values: &[u64]) -> Result<Vec<u8>, PdoError> {
    let bits = mapping_bits(mapping)?;
    if values.len() != mapping.len() {
        return Err(PdoError::ValueCount { values: values.len(), entries: mapping.len() });
    }
    let mut acc: u128 = 0;
    let mut pos = 0u32;
    for (&(_, _, len), &v) in mapping.iter().zip(values) {
        let mask = if len >= 64 { u64::MAX } else { (1u64 << len) - 1 };
        acc |= u128::from(v & mask) << pos;
        pos += u32::from(len);
    }
    let bytes = usize::try_from(bits.div_ceil(8)).unwrap_or(8);
    Ok(acc.to_le_bytes().get(..bytes).unwrap_or(&[]).to_vec())
}

/// Unpacks PDO data into raw values (zero-extended), in mapping order.
pub fn unpack(mapping: &[(u16, u8, u8)], data: &[u8]) -> Result<Vec<u64>, PdoError> {
    let bits = mapping_bits(mapping)?;
    if data.len() * 8 < usize::try_from(bits).unwrap_or(usize::MAX) {
        return Err(PdoError::DataTooShort { len: data.len(), bits });
    }
    let mut buf = [0u8; 16];
    let n = data.len().min(8);
    buf.get_mut(..n).unwrap_or(&mut []).copy_from_slice(data.get(..n).unwrap_or(&[]));
    let acc = u128::from_le_bytes(buf);
    let mut pos = 0u32;
    Ok(mapping
        .iter()
        .map(|&(_, _, len)| {
            let mask = if len >= 64 { u64::MAX } else { (1u64 << len) - 1 };
            let v = u64::try_from((acc >> pos) & u128::from(mask)).unwrap_or(0);
            pos += u32::from(len);
            v
        })
        .collect())
}

/// Sign-extends the low `bits` of a raw value (for INTEGERn mapped objects).
pub fn sign_extend(raw: u64, bits: u8) -> i64 {
    if bits == 0 || bits >= 64 {
        return raw as i64;
    }
    let shift = 64 - u32::from(bits);
    ((raw << shift) as i64) >> shift
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn tpdo1_sequence() {
        // TPDO1 of node 5: statusword (16) + modes display (8), event timer 20 ms, type 255.
        let cfg = PdoConfig {
            cob_id: 0x185,
            transmission_type: 255,
            inhibit_100us: Some(0),
            event_timer_ms: Some(20),
            sync_start: None,
            mapping: vec![(0x6041, 0, 16), (0x6061, 0, 8)],
        };
        let got = cfg.sdo_writes(PdoDirection::Tpdo, 1).unwrap();
        // Order and values from specs/canopen.md §3.5 and can-transports.md (item 5).
        let want = vec![
            w(0x1800, 1, &[0x85, 0x01, 0x00, 0x80]), // 0x80000185: disabled
            w(0x1800, 2, &[255]),
            w(0x1800, 3, &[0, 0]),
            w(0x1800, 5, &[20, 0]),
            w(0x1A00, 0, &[0]),
            w(0x1A00, 1, &[0x10, 0x00, 0x41, 0x60]), // 0x60410010
            w(0x1A00, 2, &[0x08, 0x00, 0x61, 0x60]), // 0x60610008
            w(0x1A00, 0, &[2]),
            w(0x1800, 1, &[0x85, 0x01, 0x00, 0x00]), // enabled
        ];
        assert_eq!(got, want);
    }

    #[test]
    fn rpdo_rejects_tpdo_fields_and_long_mappings() {
        let mut cfg = PdoConfig {
            cob_id: 0x205,
            transmission_type: 255,
            inhibit_100us: Some(1),
            event_timer_ms: None,
            sync_start: None,
            mapping: vec![(0x6040, 0, 16)],
        };
        assert_eq!(cfg.sdo_writes(PdoDirection::Rpdo, 1), Err(PdoError::NotForRpdo("inhibit time")));
        cfg.inhibit_100us = None;
        assert_eq!(cfg.sdo_writes(PdoDirection::Rpdo, 2).unwrap()[0].index, 0x1401);
        cfg.mapping = vec![(0x607A, 0, 32), (0x6081, 0, 32), (0x6040, 0, 8)];
        assert!(matches!(cfg.sdo_writes(PdoDirection::Rpdo, 1), Err(PdoError::TooLong { bits: 72, .. })));
        assert_eq!(cfg.sdo_writes(PdoDirection::Rpdo, 0), Err(PdoError::BadNumber(0)));
    }

    #[test]
    fn pack_by_hand() {
        // Controlword 0x000F (16 bits LE: 0F 00) then mode 1 (8 bits): 0F 00 01.
        let m = [(0x6040, 0, 16), (0x6060, 0, 8)];
        assert_eq!(pack(&m, &[0x000F, 1]).unwrap(), vec![0x0F, 0x00, 0x01]);
        // Bit fields: 4 bits 0xA then 4 bits 0x5 -> one byte 0x5A.
        let b = [(0x2000, 1, 4), (0x2000, 2, 4)];
        assert_eq!(pack(&b, &[0xA, 0x5]).unwrap(), vec![0x5A]);
        assert_eq!(unpack(&b, &[0x5A]).unwrap(), vec![0xA, 0x5]);
        // Position -1000 as INTEGER32: 18 FC FF FF.
        let p = [(0x6064, 0, 32)];
        let raw = unpack(&p, &[0x18, 0xFC, 0xFF, 0xFF]).unwrap()[0];
        assert_eq!(sign_extend(raw, 32), -1000);
        assert!(matches!(unpack(&p, &[1, 2]), Err(PdoError::DataTooShort { .. })));
    }

    proptest! {
        #[test]
        fn pack_unpack_round_trip(lens in proptest::collection::vec(1u8..=64, 1..=8), seed in any::<u64>()) {
            // Keep only prefixes that fit 64 bits.
            let mut total = 0u32;
            let lens: Vec<u8> = lens.into_iter().take_while(|l| { total += u32::from(*l); total <= 64 }).collect();
            prop_assume!(!lens.is_empty());
            let mapping: Vec<(u16, u8, u8)> = lens.iter().enumerate().map(|(i, l)| (0x2000, i as u8, *l)).collect();
            let values: Vec<u64> = lens.iter().enumerate().map(|(i, l)| {
                let v = seed.rotate_left(i as u32 * 7) ^ (i as u64 * 0x9E37_79B9);
                if *l == 64 { v } else { v & ((1u64 << l) - 1) }
            }).collect();
            let data = pack(&mapping, &values).unwrap();
            let bits: u32 = lens.iter().map(|l| u32::from(*l)).sum();
            prop_assert_eq!(data.len() as u32, bits.div_ceil(8));
            prop_assert_eq!(unpack(&mapping, &data).unwrap(), values);
        }
    }
}
