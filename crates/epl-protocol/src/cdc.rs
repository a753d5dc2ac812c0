//! The concise DCF (`.cdc`): the binary configuration an openPOWERLINK MN reads at start-up,
//! as openCONFIGURATOR writes it (`shared/oracles/openpowerlink/mkcdc.py` documents the
//! layout; `cdc/*.txt` list the demo files entry by entry).
//!
//! Layout, all little-endian: an UNSIGNED32 entry count, then per entry the object index
//! (u16), subindex (u8), data size (u32) and the data. The MN's own objects come first (node
//! assignment 0x1F81/n, cycle length 0x1006, PDO channels ...). An entry 0x1F22/n
//! (CFM_ConciseDcfList) holds, as its data, a nested concise DCF of the same layout: the
//! entries the MN writes to CN n by SDO while booting it ([`Cdc::node_config`]).
//!
//! [`Cdc::parse`] never panics; it refuses a file that ends inside an entry, announces more
//! entries than its bytes can hold, has bytes after its last entry, or has a 0x1F22 entry
//! that is not such a nested DCF, naming the byte offset of the fault. [`Cdc::to_bytes`]
//! writes the same bytes back.

use std::collections::BTreeMap;

use thiserror::Error;

/// CFM_ConciseDcfList_ADOM: subindex n holds node n's concise DCF.
pub const CONCISE_DCF_LIST: u16 = 0x1F22;
/// NMT_NodeAssignment_AU32: subindex n holds node n's assignment bits.
pub const NODE_ASSIGNMENT: u16 = 0x1F81;
/// NMT_CycleLen_U32: the cycle length in microseconds.
pub const CYCLE_LENGTH: u16 = 0x1006;

/// Bytes of an entry header: index (2), subindex (1), size (4).
const ENTRY_HEADER: usize = 7;
/// Bytes of the entry count.
const COUNT: usize = 4;

bitflags::bitflags! {
    /// The bits of a node assignment (0x1F81/n, NMT_NodeAssignment_AU32).
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
    pub struct NodeAssignment: u32 {
        /// Bit 0: the node exists.
        const NODE_EXISTS = 1 << 0;
        /// Bit 1: the node is a CN.
        const IS_CN = 1 << 1;
        /// Bit 2: the MN may start the CN (NMTStartNode).
        const START_CN = 1 << 2;
        /// Bit 3: the CN is mandatory for the segment to start.
        const MANDATORY = 1 << 3;
        /// Bit 4: keep alive (not used in EPL V2).
        const KEEP_ALIVE = 1 << 4;
        /// Bit 5: check the CN's software version.
        const SW_VERSION_CHECK = 1 << 5;
        /// Bit 6: update the CN's software.
        const SW_UPDATE = 1 << 6;
        /// Bit 8: asynchronous-only node (never polled by PReq).
        const ASYNC_ONLY = 1 << 8;
        /// Bit 9: multiplexed CN.
        const MULTIPLEXED = 1 << 9;
        /// Bit 10: routing type 1.
        const RT1 = 1 << 10;
        /// Bit 11: routing type 2.
        const RT2 = 1 << 11;
        /// Bit 12: the node consumes the MN's PRes.
        const MN_PRES = 1 << 12;
        /// Bit 14: PollResponse chaining.
        const PRES_CHAINING = 1 << 14;
        /// Bit 31: the assignment is valid.
        const VALID = 1 << 31;
    }
}

/// One concise DCF entry: the value to write to `index`/`subindex`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CdcEntry {
    /// Object index.
    pub index: u16,
    /// Object subindex.
    pub subindex: u8,
    /// The value's bytes (little-endian; for 0x1F22/n a nested concise DCF).
    pub data: Vec<u8>,
}

impl CdcEntry {
    /// The value as an unsigned integer when it is 1, 2, 4 or 8 bytes long.
    pub fn unsigned(&self) -> Option<u64> {
        match self.data.len() {
            1 | 2 | 4 | 8 => {
                let mut buf = [0u8; 8];
                buf.get_mut(..self.data.len())?.copy_from_slice(&self.data);
                Some(u64::from_le_bytes(buf))
            }
            _ => None,
        }
    }

    /// The value as UNSIGNED32 when it is 4 bytes long.
    pub fn u32(&self) -> Option<u32> {
        Some(u32::from_le_bytes(self.data.as_slice().try_into().ok()?))
    }
}

/// Why bytes are not a concise DCF. Offsets count from the start of the file, also inside a
/// nested 0x1F22 DCF.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum CdcError {
    /// The data ends inside the entry count or an entry header.
    #[error("offset {offset}: {what} needs {needed} bytes, only {available} left")]
    Truncated {
        /// Offset of the field.
        offset: usize,
        /// "entry count" or "entry header".
        what: &'static str,
        /// Bytes the field needs.
        needed: usize,
        /// Bytes left.
        available: usize,
    },
    /// An entry's data goes beyond the end of the file (or of its nested DCF).
    #[error(
        "offset {offset}: entry {index:#06x}/{subindex} announces {size} data bytes, only {available} left"
    )]
    DataTruncated {
        /// Offset of the entry header.
        offset: usize,
        /// Entry index.
        index: u16,
        /// Entry subindex.
        subindex: u8,
        /// Announced data size.
        size: u32,
        /// Bytes left after the header.
        available: usize,
    },
    /// The entry count is more than the remaining bytes can hold (7 bytes per entry at
    /// least).
    #[error("offset {offset}: {count} entries cannot fit in the {available} bytes that follow")]
    TooManyEntries {
        /// Offset of the count.
        offset: usize,
        /// The count.
        count: u32,
        /// Bytes after the count.
        available: usize,
    },
    /// Bytes follow the last entry.
    #[error("offset {offset}: {count} bytes after the last entry")]
    TrailingBytes {
        /// Offset of the first extra byte.
        offset: usize,
        /// How many.
        count: usize,
    },
    /// A 0x1F22/n entry whose data is not a concise DCF.
    #[error("0x1f22/{node} (node {node}'s configuration): {source}")]
    NodeConfig {
        /// The node (subindex).
        node: u8,
        /// What is wrong inside it.
        source: Box<CdcError>,
    },
}

/// A parsed concise DCF.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Cdc {
    entries: Vec<CdcEntry>,
    node_configs: BTreeMap<u8, Vec<CdcEntry>>,
}

impl Cdc {
    /// Parses a concise DCF, including every node's nested configuration (0x1F22/n).
    ///
    /// # Errors
    /// A [`CdcError`] naming the byte offset and what is wrong there.
    pub fn parse(bytes: &[u8]) -> Result<Cdc, CdcError> {
        let entries = parse_block(bytes, 0)?;
        let mut node_configs = BTreeMap::new();
        let mut offset = COUNT;
        for entry in &entries {
            let data_offset = offset + ENTRY_HEADER;
            if entry.index == CONCISE_DCF_LIST && entry.subindex != 0 {
                let config = if entry.data.is_empty() {
                    Vec::new()
                } else {
                    parse_block(&entry.data, data_offset)
                        .map_err(|e| CdcError::NodeConfig { node: entry.subindex, source: Box::new(e) })?
                };
                node_configs.insert(entry.subindex, config);
            }
            offset = data_offset + entry.data.len();
        }
        Ok(Cdc { entries, node_configs })
    }

    /// The entries in file order (a 0x1F22/n entry's data is the raw nested DCF).
    pub fn entries(&self) -> &[CdcEntry] {
        &self.entries
    }

    /// The last value given for `index`/`subindex` (an MN applies the entries in order, so a
    /// later one wins).
    pub fn value(&self, index: u16, subindex: u8) -> Option<&CdcEntry> {
        self.entries.iter().rev().find(|e| e.index == index && e.subindex == subindex)
    }

    /// The entries the MN writes to CN `node` while configuring it (its 0x1F22/`node`
    /// nested DCF, in order), `None` when the file has no configuration for the node.
    pub fn node_config(&self, node: u8) -> Option<Vec<CdcEntry>> {
        self.node_configs.get(&node).cloned()
    }

    /// The nodes with a 0x1F22 configuration, ascending.
    pub fn configured_nodes(&self) -> Vec<u8> {
        self.node_configs.keys().copied().collect()
    }

    /// The cycle length in microseconds (0x1006, the last value).
    pub fn cycle_length(&self) -> Option<u32> {
        self.value(CYCLE_LENGTH, 0)?.u32()
    }

    /// The node assignment of `node` (0x1F81/`node`, the last value).
    pub fn node_assignment(&self, node: u8) -> Option<NodeAssignment> {
        self.value(NODE_ASSIGNMENT, node)?.u32().map(NodeAssignment::from_bits_retain)
    }

    /// The CNs the MN manages: nodes 1-254 whose node assignment has "node exists" and "is
    /// a CN" set, ascending.
    pub fn assigned_nodes(&self) -> Vec<u8> {
        (1..=254u8)
            .filter(|&n| {
                self.node_assignment(n)
                    .is_some_and(|a| a.contains(NodeAssignment::NODE_EXISTS | NodeAssignment::IS_CN))
            })
            .collect()
    }

    /// The file's bytes (what [`Cdc::parse`] read, byte for byte).
    pub fn to_bytes(&self) -> Vec<u8> {
        encode_block(&self.entries)
    }
}

/// A concise DCF's bytes from its entries.
pub fn encode_block(entries: &[CdcEntry]) -> Vec<u8> {
    let mut out =
        Vec::with_capacity(COUNT + entries.iter().map(|e| ENTRY_HEADER + e.data.len()).sum::<usize>());
    out.extend_from_slice(&u32::try_from(entries.len()).unwrap_or(u32::MAX).to_le_bytes());
    for e in entries {
        out.extend_from_slice(&e.index.to_le_bytes());
        out.push(e.subindex);
        out.extend_from_slice(&u32::try_from(e.data.len()).unwrap_or(u32::MAX).to_le_bytes());
        out.extend_from_slice(&e.data);
    }
    out
}

/// One concise DCF (count + entries) filling all of `bytes`, which start at file offset
/// `base`.
fn parse_block(bytes: &[u8], base: usize) -> Result<Vec<CdcEntry>, CdcError> {
    let (count, mut rest) = split(bytes, COUNT, base, "entry count")?;
    let count_bytes: [u8; 4] = count.try_into().unwrap_or_default();
    let count = u32::from_le_bytes(count_bytes);
    let mut offset = base + COUNT;
    let fits = usize::try_from(count)
        .ok()
        .and_then(|c| c.checked_mul(ENTRY_HEADER))
        .is_some_and(|n| n <= rest.len());
    if !fits {
        return Err(CdcError::TooManyEntries { offset: base, count, available: rest.len() });
    }
    let mut entries = Vec::with_capacity(usize::try_from(count).unwrap_or(0));
    for _ in 0..count {
        let (header, after) = split(rest, ENTRY_HEADER, offset, "entry header")?;
        let &[i0, i1, subindex, s0, s1, s2, s3] = header else {
            return Err(CdcError::Truncated {
                offset,
                what: "entry header",
                needed: ENTRY_HEADER,
                available: header.len(),
            });
        };
        let index = u16::from_le_bytes([i0, i1]);
        let size = u32::from_le_bytes([s0, s1, s2, s3]);
        let data = usize::try_from(size)
            .ok()
            .and_then(|n| after.get(..n))
            .ok_or(CdcError::DataTruncated { offset, index, subindex, size, available: after.len() })?;
        entries.push(CdcEntry { index, subindex, data: data.to_vec() });
        rest = after.get(data.len()..).unwrap_or_default();
        offset += ENTRY_HEADER + data.len();
    }
    if !rest.is_empty() {
        return Err(CdcError::TrailingBytes { offset, count: rest.len() });
    }
    Ok(entries)
}

/// `bytes` split after `n` bytes, or the truncation error for a field at `offset`.
fn split<'a>(
    bytes: &'a [u8],
    n: usize,
    offset: usize,
    what: &'static str,
) -> Result<(&'a [u8], &'a [u8]), CdcError> {
    bytes.split_at_checked(n).ok_or(CdcError::Truncated { offset, what, needed: n, available: bytes.len() })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]
    use super::*;

    fn entry(index: u16, subindex: u8, data: &[u8]) -> CdcEntry {
        CdcEntry { index, subindex, data: data.to_vec() }
    }

    #[test]
    fn round_trip_with_a_nested_config() {
        let inner = encode_block(&[entry(0x1006, 0, &1000u32.to_le_bytes()), entry(0x1600, 0, &[1])]);
        let entries = vec![
            entry(0x1F81, 1, &7u32.to_le_bytes()),
            entry(0x1F81, 2, &1u32.to_le_bytes()),
            entry(0x1006, 0, &1000u32.to_le_bytes()),
            entry(0x1F22, 1, &inner),
            entry(0x1F22, 3, &[]),
            entry(0x1006, 0, &2000u32.to_le_bytes()),
        ];
        let bytes = encode_block(&entries);
        let cdc = Cdc::parse(&bytes).unwrap();
        assert_eq!(cdc.entries(), entries);
        assert_eq!(cdc.to_bytes(), bytes);
        assert_eq!(cdc.cycle_length(), Some(2000), "the last value wins");
        assert_eq!(cdc.assigned_nodes(), [1], "node 2 exists but is not a CN");
        assert_eq!(
            cdc.node_assignment(1),
            Some(NodeAssignment::NODE_EXISTS | NodeAssignment::IS_CN | NodeAssignment::START_CN)
        );
        let cfg = cdc.node_config(1).unwrap();
        assert_eq!(cfg, [entry(0x1006, 0, &1000u32.to_le_bytes()), entry(0x1600, 0, &[1])]);
        assert_eq!(cfg[1].unsigned(), Some(1));
        assert_eq!(cdc.node_config(3), Some(vec![]));
        assert_eq!(cdc.node_config(2), None);
        assert_eq!(cdc.configured_nodes(), [1, 3]);
        assert_eq!(Cdc::parse(&[0, 0, 0, 0]).unwrap().entries(), []);
    }

    #[test]
    fn errors_name_the_offset() {
        assert_eq!(
            Cdc::parse(&[1, 0]),
            Err(CdcError::Truncated { offset: 0, what: "entry count", needed: 4, available: 2 })
        );
        assert_eq!(
            Cdc::parse(&[0xFF, 0xFF, 0xFF, 0xFF, 0, 0, 0]),
            Err(CdcError::TooManyEntries { offset: 0, count: u32::MAX, available: 3 })
        );
        // Entry 0x1006/0 says 4 bytes, 2 follow.
        let short = [1, 0, 0, 0, 0x06, 0x10, 0, 4, 0, 0, 0, 0xE8, 0x03];
        assert_eq!(
            Cdc::parse(&short),
            Err(CdcError::DataTruncated { offset: 4, index: 0x1006, subindex: 0, size: 4, available: 2 })
        );
        let huge = [1, 0, 0, 0, 0x06, 0x10, 0, 0xFF, 0xFF, 0xFF, 0xFF];
        assert!(matches!(Cdc::parse(&huge), Err(CdcError::DataTruncated { size: u32::MAX, .. })));
        // Two entries announced, one present and a partial header.
        let mut two = encode_block(&[entry(0x1006, 0, &[0; 4])]);
        two[0] = 2;
        two.extend_from_slice(&[0; 7]);
        two.truncate(two.len() - 1);
        assert_eq!(
            Cdc::parse(&two),
            Err(CdcError::Truncated { offset: 15, what: "entry header", needed: 7, available: 6 })
        );
        let mut trailing = encode_block(&[entry(0x1006, 0, &[0; 4])]);
        trailing.push(0);
        assert_eq!(Cdc::parse(&trailing), Err(CdcError::TrailingBytes { offset: 15, count: 1 }));
        // A nested DCF that is too short: offsets count from the start of the file.
        let bad = encode_block(&[entry(0x1F81, 1, &[0; 4]), entry(0x1F22, 1, &[1, 0, 0, 0, 0x06])]);
        let err = Cdc::parse(&bad).unwrap_err();
        assert_eq!(
            err,
            CdcError::NodeConfig {
                node: 1,
                source: Box::new(CdcError::TooManyEntries { offset: 15 + 7, count: 1, available: 1 })
            }
        );
        assert_eq!(
            err.to_string(),
            "0x1f22/1 (node 1's configuration): offset 22: 1 entries cannot fit in the 1 bytes that follow"
        );
        let bad = encode_block(&[entry(0x1F22, 1, &[1, 0, 0, 0, 0x06, 0x10, 0, 9, 0, 0, 0])]);
        assert_eq!(
            Cdc::parse(&bad),
            Err(CdcError::NodeConfig {
                node: 1,
                source: Box::new(CdcError::DataTruncated {
                    offset: 4 + 7 + 4,
                    index: 0x1006,
                    subindex: 0,
                    size: 9,
                    available: 0
                })
            })
        );
    }

    #[test]
    fn unsigned_values() {
        assert_eq!(entry(0, 0, &[1, 2]).unsigned(), Some(0x0201));
        assert_eq!(entry(0, 0, &[1, 2, 3]).unsigned(), None);
        assert_eq!(entry(0, 0, &[1, 0, 0, 0]).u32(), Some(1));
        assert_eq!(entry(0, 0, &[1]).u32(), None);
    }
}
