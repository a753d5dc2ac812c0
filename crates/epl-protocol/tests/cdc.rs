//! The openPOWERLINK demo's concise DCFs (tests/data/*.cdc, from
//! `shared/oracles/openpowerlink/cdc/`) against their text listings (`*.txt`, openCONFIGURATOR's
//! `mnobd.txt`), and node 1's configuration applied to the built-in CN dictionary.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_epl_protocol::cdc::{encode_block, NodeAssignment};
use motus_epl_protocol::{Cdc, CdcEntry, DeviceIdentity, ObjectAccess, ObjectDictionary};

fn data(name: &str) -> Vec<u8> {
    std::fs::read(format!("{}/tests/data/{name}", env!("CARGO_MANIFEST_DIR"))).unwrap()
}

/// One entry of the text listing.
#[derive(Debug)]
enum Listed {
    /// `index sub size value`.
    Value(u16, u8, u32, u64),
    /// `1F22 node size`, then the nested block: its count line and its entries.
    Nested(u8, u32, u32, Vec<Listed>),
}

fn hex(s: &str) -> u64 {
    u64::from_str_radix(s, 16).unwrap()
}

/// The listing (test oracle, read independently of the binary parser): the count line and
/// the entries; a 0x1F22 line takes the lines up to the next blank one.
fn listing(name: &str) -> (u32, Vec<Listed>) {
    let text = String::from_utf8(data(name)).unwrap();
    let lines: Vec<&str> = text.lines().map(str::trim).filter(|l| !l.starts_with("//")).collect();
    let mut count = None;
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let f: Vec<&str> = lines[i].split_whitespace().collect();
        i += 1;
        match f.as_slice() {
            [c] if count.is_none() => count = Some(u32::try_from(hex(c)).unwrap()),
            [idx, node, size] if idx.eq_ignore_ascii_case("1F22") => {
                let mut nested = Vec::new();
                let mut nested_count = None;
                while i < lines.len() && !lines[i].is_empty() {
                    let g: Vec<&str> = lines[i].split_whitespace().collect();
                    match g.as_slice() {
                        [c] => nested_count = Some(u32::try_from(hex(c)).unwrap()),
                        [a, b, c, d] => nested.push(value(a, b, c, d)),
                        other => panic!("{name}: {other:?}"),
                    }
                    i += 1;
                }
                let node = u8::try_from(hex(node)).unwrap();
                out.push(Listed::Nested(
                    node,
                    u32::try_from(hex(size)).unwrap(),
                    nested_count.unwrap(),
                    nested,
                ));
            }
            [a, b, c, d] => out.push(value(a, b, c, d)),
            [] => {}
            other => panic!("{name}: {other:?}"),
        }
    }
    (count.unwrap(), out)
}

fn value(a: &str, b: &str, c: &str, d: &str) -> Listed {
    Listed::Value(
        u16::try_from(hex(a)).unwrap(),
        u8::try_from(hex(b)).unwrap(),
        u32::try_from(hex(c)).unwrap(),
        hex(d),
    )
}

fn check_value(entry: &CdcEntry, listed: &Listed, what: &str) {
    let Listed::Value(index, sub, size, v) = listed else { panic!("{what}: {listed:?}") };
    assert_eq!((entry.index, entry.subindex), (*index, *sub), "{what}");
    assert_eq!(entry.data.len(), usize::try_from(*size).unwrap(), "{what} {index:#06x}/{sub}");
    assert_eq!(entry.unsigned(), Some(*v), "{what} {index:#06x}/{sub}");
}

/// Every entry of the `.cdc` equals its line in the `.txt`, nested configurations included.
fn compare(cdc_name: &str, txt_name: &str) -> Cdc {
    let cdc = Cdc::parse(&data(cdc_name)).unwrap();
    let (count, listed) = listing(txt_name);
    assert_eq!(cdc.entries().len(), usize::try_from(count).unwrap(), "{cdc_name}");
    assert_eq!(cdc.entries().len(), listed.len(), "{cdc_name}");
    for (entry, l) in cdc.entries().iter().zip(&listed) {
        match l {
            Listed::Value(..) => check_value(entry, l, cdc_name),
            Listed::Nested(node, size, nested_count, nested) => {
                assert_eq!((entry.index, entry.subindex), (0x1F22, *node), "{cdc_name}");
                assert_eq!(entry.data.len(), usize::try_from(*size).unwrap(), "{cdc_name} 0x1F22/{node}");
                let config = cdc.node_config(*node).unwrap();
                assert_eq!(config.len(), usize::try_from(*nested_count).unwrap());
                assert_eq!(config.len(), nested.len());
                for (e, n) in config.iter().zip(nested) {
                    check_value(e, n, &format!("{cdc_name} 0x1F22/{node}"));
                }
            }
        }
    }
    assert_eq!(cdc.to_bytes(), data(cdc_name), "{cdc_name}: written back byte for byte");
    cdc
}

/// Node `node`'s configuration written by SDO into a fresh CN dictionary: nothing refused.
fn apply_node_config(cdc: &Cdc, node: u8) -> ObjectDictionary {
    let mut od = ObjectDictionary::controlled_node(node, &DeviceIdentity::default());
    for e in cdc.node_config(node).unwrap() {
        assert_eq!(
            od.write(e.index, e.subindex, &e.data),
            Ok(()),
            "node {node}: {:#06x}/{}",
            e.index,
            e.subindex
        );
        assert_eq!(od.read(e.index, e.subindex).unwrap(), e.data);
    }
    od
}

#[test]
fn demo_3cn_1ms_matches_its_listing() {
    let cdc = compare("demo_3cn_1ms.cdc", "demo_3cn_1ms.txt");
    assert_eq!(cdc.entries().len(), 49);
    assert_eq!(cdc.cycle_length(), Some(1000));
    assert_eq!(cdc.assigned_nodes(), [1, 32, 110]);
    assert_eq!(cdc.configured_nodes(), [1, 32, 110]);
    let a = cdc.node_assignment(1).unwrap();
    assert_eq!(
        a,
        NodeAssignment::NODE_EXISTS
            | NodeAssignment::IS_CN
            | NodeAssignment::START_CN
            | NodeAssignment::VALID
    );
    let cfg = cdc.node_config(1).unwrap();
    assert_eq!(cfg.len(), 14);
    assert_eq!(cfg[2].index, 0x1006);
    assert_eq!(cfg[2].u32(), Some(1000));
    assert_eq!(cdc.node_config(2), None);
}

#[test]
fn demo_3cn_50ms_matches_its_listing() {
    let cdc = compare("demo_3cn_50ms.cdc", "demo_3cn_50ms.txt");
    assert_eq!(cdc.entries().len(), 49);
    assert_eq!(cdc.cycle_length(), Some(50_000));
    assert_eq!(cdc.assigned_nodes(), [1, 32, 110]);
    assert_eq!(cdc.node_config(110).unwrap()[2].u32(), Some(50_000));
}

#[test]
fn no_cn_config_is_the_50ms_file_without_0x1f22() {
    let full = Cdc::parse(&data("demo_3cn_50ms.cdc")).unwrap();
    let cdc = Cdc::parse(&data("no_cn_config_50ms.cdc")).unwrap();
    assert_eq!(cdc.entries().len(), 46);
    let expected: Vec<CdcEntry> = full.entries().iter().filter(|e| e.index != 0x1F22).cloned().collect();
    assert_eq!(cdc.entries(), expected);
    assert_eq!(cdc.cycle_length(), Some(50_000));
    assert_eq!(cdc.assigned_nodes(), [1, 32, 110]);
    assert!(cdc.configured_nodes().is_empty());
    assert_eq!(cdc.node_config(1), None);
    assert_eq!(cdc.to_bytes(), encode_block(&expected));
}

#[test]
fn node_configs_apply_to_the_cn_dictionary() {
    for (file, cycle) in [("demo_3cn_1ms.cdc", 1000), ("demo_3cn_50ms.cdc", 50_000)] {
        let cdc = Cdc::parse(&data(file)).unwrap();
        for node in cdc.configured_nodes() {
            let mut od = apply_node_config(&cdc, node);
            assert_eq!(od.u32(0x1006, 0), Some(cycle), "{file}");
            assert_eq!(od.u32(0x1020, 1), Some(0x3124));
            assert_eq!(od.u32(0x1020, 2), Some(0x0373_5955));
            assert_eq!(od.u32(0x1C0B, 3), Some(0x50));
            assert_eq!(od.u32(0x1C0D, 3), Some(0x50));
            assert_eq!(od.u32(0x1C14, 0), Some(50_000_000));
            assert_eq!(od.u16(0x1F98, 4), Some(36));
            assert_eq!(od.u16(0x1F98, 5), Some(36));
            // The mapping: 0x6000/1 -> PRes byte 0, PReq byte 0 -> 0x6200/1.
            od.set_u8(0x6000, 1, 0xA5).unwrap();
            assert_eq!(od.pres_payload(), [0xA5]);
            assert_eq!(od.apply_preq_payload(&[0x3C]), Ok(1));
            assert_eq!(od.u8(0x6200, 1), Some(0x3C));
        }
    }
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn parse_never_panics_and_round_trips(bytes in prop::collection::vec(any::<u8>(), 0..200)) {
            if let Ok(cdc) = Cdc::parse(&bytes) {
                prop_assert_eq!(cdc.to_bytes(), bytes);
            }
        }

        #[test]
        fn corrupted_demo_files_never_panic(pos in 0usize..951, byte in any::<u8>(), cut in 0usize..952) {
            let mut bytes = data("demo_3cn_1ms.cdc");
            bytes[pos] = byte;
            bytes.truncate(cut);
            if let Ok(cdc) = Cdc::parse(&bytes) {
                prop_assert_eq!(cdc.to_bytes(), bytes);
            }
        }
    }
}
