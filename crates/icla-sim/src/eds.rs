//! Export of the object dictionary as a CiA 306 EDS (electronic data sheet) that
//! python-canopen 2.4.1 (`canopen.import_od`) reads: `[FileInfo]`, `[DeviceInfo]` with the
//! supported bit rates and PDO counts, the three object lists, one section per object and
//! per sub-index (`ParameterName`, `ObjectType`, `DataType`, `AccessType`, `DefaultValue`,
//! `PDOMapping`, `SubNumber`, `LowLimit` / `HighLimit`). Node-relative defaults are written
//! `$NODEID+0x...` so the file fits every node id.

use std::fmt::Write as _;

use crate::config::{bitrate_of_index, Identity};
use crate::od::{Default, Entry, ObjectDictionary, ObjectKind};

/// Objects CiA 301 makes mandatory.
const MANDATORY: [u16; 3] = [0x1000, 0x1001, 0x1018];

fn default_text(e: &Entry) -> String {
    match &e.default {
        Default::Int(v) if *v < 0 => v.to_string(),
        Default::Int(v) if *v > 9 => format!("0x{v:X}"),
        Default::Int(v) => v.to_string(),
        Default::NodeRelative(v) => format!("$NODEID+0x{v:X}"),
        Default::Text(t) => t.clone(),
    }
}

fn entry_section(out: &mut String, section: &str, e: &Entry) {
    let _ = writeln!(out, "[{section}]");
    let _ = writeln!(out, "ParameterName={}", e.name);
    let _ = writeln!(out, "ObjectType=0x7");
    let _ = writeln!(out, "DataType=0x{:04X}", e.data_type.code());
    let _ = writeln!(out, "AccessType={}", e.access.eds());
    let _ = writeln!(out, "DefaultValue={}", default_text(e));
    if let Some(l) = e.low {
        let _ = writeln!(out, "LowLimit={l}");
    }
    if let Some(h) = e.high {
        let _ = writeln!(out, "HighLimit={h}");
    }
    let _ = writeln!(out, "PDOMapping={}", u8::from(e.pdo_mappable));
    out.push('\n');
}

fn list(out: &mut String, name: &str, indices: &[u16]) {
    let _ = writeln!(out, "[{name}]");
    let _ = writeln!(out, "SupportedObjects={}", indices.len());
    for (i, index) in indices.iter().enumerate() {
        let _ = writeln!(out, "{}=0x{index:04X}", i + 1);
    }
    out.push('\n');
}

/// Renders the EDS of `od`. `identity` fills `[DeviceInfo]`; the PDO counts come from the
/// communication objects present.
pub fn export(od: &ObjectDictionary, identity: &Identity) -> String {
    let mut out = String::new();
    out.push_str("; EDS exported by motus-icla-sim (simulated IclA D065, CiA 402 drive)\n");
    out.push_str("[FileInfo]\nFileName=icla-sim.eds\nFileVersion=1\nFileRevision=0\nEDSVersion=4.0\n");
    out.push_str("Description=Simulated IclA D065 integrated drive (Motus)\nCreatedBy=motus-icla-sim\n\n");
    out.push_str("[DeviceInfo]\nVendorName=Motus simulator (IclA D065)\n");
    let _ = writeln!(out, "VendorNumber=0x{:08X}", identity.vendor);
    out.push_str("ProductName=IclA D065 (Motus simulator)\n");
    let _ = writeln!(out, "ProductNumber=0x{:08X}", identity.product);
    let _ = writeln!(out, "RevisionNumber=0x{:08X}", identity.revision);
    for rate in [10u32, 20, 50, 125, 250, 500, 800, 1000] {
        let supported = (0..=8).any(|i| bitrate_of_index(i) == Some(rate * 1000));
        let _ = writeln!(out, "BaudRate_{rate}={}", u8::from(supported));
    }
    out.push_str("SimpleBootUpMaster=0\nSimpleBootUpSlave=1\nGranularity=8\nDynamicChannelsSupported=0\n");
    out.push_str("GroupMessaging=0\n");
    let objects = od.objects();
    let count = |lo: u16| (lo..lo + 0x200).filter(|i| objects.contains_key(i)).count();
    let _ = writeln!(out, "NrOfRXPDO={}", count(0x1400));
    let _ = writeln!(out, "NrOfTXPDO={}", count(0x1800));
    out.push_str("LSS_Supported=1\n\n");
    out.push_str("[DummyUsage]\n");
    for i in 1..=7 {
        let _ = writeln!(out, "Dummy{i:04}=0");
    }
    out.push('\n');
    let mandatory: Vec<u16> = objects.keys().copied().filter(|i| MANDATORY.contains(i)).collect();
    let optional: Vec<u16> = objects
        .keys()
        .copied()
        .filter(|i| !MANDATORY.contains(i) && !(0x2000..=0x5FFF).contains(i))
        .collect();
    let manufacturer: Vec<u16> = objects.keys().copied().filter(|i| (0x2000..=0x5FFF).contains(i)).collect();
    list(&mut out, "MandatoryObjects", &mandatory);
    list(&mut out, "OptionalObjects", &optional);
    list(&mut out, "ManufacturerObjects", &manufacturer);
    for (index, obj) in objects {
        match obj.kind {
            ObjectKind::Var => {
                if let Some(e) = obj.entries.get(&0) {
                    entry_section(&mut out, &format!("{index:04X}"), e);
                }
            }
            ObjectKind::Array | ObjectKind::Record => {
                let _ = writeln!(out, "[{index:04X}]");
                let _ = writeln!(out, "ParameterName={}", obj.name);
                let _ = writeln!(out, "ObjectType=0x{:X}", obj.kind.code());
                let _ = writeln!(out, "SubNumber=0x{:X}", obj.entries.len());
                out.push('\n');
                for (sub, e) in &obj.entries {
                    entry_section(&mut out, &format!("{index:04X}sub{sub:X}"), e);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use crate::config::SimConfig;
    use std::collections::BTreeMap;

    /// A small INI reader (independent of the writer) for the round trip.
    fn parse(text: &str) -> BTreeMap<String, BTreeMap<String, String>> {
        let mut sections: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
        let mut current = String::new();
        for line in text.lines().map(str::trim) {
            if line.is_empty() || line.starts_with(';') {
                continue;
            }
            if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
                current = name.to_owned();
                assert!(sections.insert(current.clone(), BTreeMap::new()).is_none(), "duplicate [{name}]");
            } else {
                let (k, v) = line.split_once('=').unwrap();
                sections.get_mut(&current).unwrap().insert(k.to_owned(), v.to_owned());
            }
        }
        sections
    }

    #[test]
    fn export_parses_back_with_every_object_and_the_fixture_keys() {
        let cfg = SimConfig::node(2);
        let od = crate::objects::build(&cfg);
        let eds = parse(&export(&od, &cfg.identity));
        // Same keys as specs fixture drive402.eds uses.
        assert_eq!(eds["DeviceInfo"]["BaudRate_20"], "1");
        assert_eq!(eds["DeviceInfo"]["NrOfRXPDO"], "4");
        assert_eq!(eds["DeviceInfo"]["NrOfTXPDO"], "4");
        assert_eq!(eds["DeviceInfo"]["VendorNumber"], "0x0800005A");
        assert_eq!(eds["MandatoryObjects"]["SupportedObjects"], "3");
        assert_eq!(eds["ManufacturerObjects"]["1"], "0x200B");
        let listed: usize = ["MandatoryObjects", "OptionalObjects", "ManufacturerObjects"]
            .iter()
            .map(|l| eds[*l]["SupportedObjects"].parse::<usize>().unwrap())
            .sum();
        assert_eq!(listed, od.objects().len());
        // VAR: the fixture's keys.
        let sw = &eds["6041"];
        assert_eq!(
            (
                sw["ObjectType"].as_str(),
                sw["DataType"].as_str(),
                sw["AccessType"].as_str(),
                sw["PDOMapping"].as_str()
            ),
            ("0x7", "0x0006", "ro", "1")
        );
        assert_eq!(eds["1000"]["DefaultValue"], "0x20192");
        // RECORD with node-relative COB-ID (TPDO1: bit 30 no RTR + 0x180).
        assert_eq!(eds["1800"]["ObjectType"], "0x9");
        assert_eq!(eds["1800"]["SubNumber"], "0x6");
        assert_eq!(eds["1800sub1"]["DefaultValue"], "$NODEID+0x40000180");
        assert_eq!(eds["1A00sub1"]["DefaultValue"], "0x60410010");
        // ARRAY 0x607D, signed limits written in decimal.
        assert_eq!(eds["607D"]["ObjectType"], "0x8");
        assert_eq!(eds["60FF"]["LowLimit"], "-747");
        assert_eq!(eds["1008"]["DefaultValue"], "IclA D065 (Motus simulator)");
        // Every sub-index section belongs to an object section written before it.
        for name in eds.keys() {
            if let Some((idx, _)) = name.split_once("sub") {
                assert!(eds.contains_key(idx), "{name}");
            }
        }
    }
}
