#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use std::collections::BTreeSet;

use super::*;
use crate::od::DeviceIdentity;

/// openPOWERLINK's demo CN description and its configuration for node 1 (tests/data/README.md).
const XDD: &str = include_str!("../../tests/data/00000000_POWERLINK_CiA401_CN.xdd");
const XDC: &str = include_str!("../../tests/data/00000000_POWERLINK_CiA401_CN_1.xdc");

/// Every way two dictionaries differ: `0xIIII/S field` per entry field (name, type, access,
/// pdo, limits, default, value, capacity), `0xIIII name|kind` per object, `missing` for an
/// object or entry in only one of them.
fn differences(a: &ObjectDictionary, b: &ObjectDictionary) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let indices: BTreeSet<u16> = a.objects().chain(b.objects()).map(|(i, _)| i).collect();
    for index in indices {
        let (Some(oa), Some(ob)) = (a.object(index), b.object(index)) else {
            out.insert(format!("0x{index:04X} missing"));
            continue;
        };
        if oa.name() != ob.name() {
            out.insert(format!("0x{index:04X} name"));
        }
        if oa.kind() != ob.kind() {
            out.insert(format!("0x{index:04X} kind"));
        }
        let subs: BTreeSet<u8> = oa.entries().chain(ob.entries()).map(|(s, _)| s).collect();
        for sub in subs {
            let (Some(ea), Some(eb)) = (oa.entry(sub), ob.entry(sub)) else {
                out.insert(format!("0x{index:04X}/{sub} missing"));
                continue;
            };
            let fields = [
                ("name", ea.name() != eb.name()),
                ("type", ea.data_type() != eb.data_type()),
                ("access", ea.access() != eb.access()),
                ("pdo", ea.pdo_mappable() != eb.pdo_mappable()),
                ("limits", ea.range() != eb.range()),
                ("default", ea.default_value() != eb.default_value()),
                ("value", ea.value() != eb.value()),
                ("capacity", ea.max_len() != eb.max_len()),
            ];
            for (field, differs) in fields {
                if differs {
                    out.insert(format!("0x{index:04X}/{sub} {field}"));
                }
            }
        }
    }
    out
}

/// The entries (`0xIIII/S`) named in a set of differences.
fn entries_of(diffs: &BTreeSet<String>) -> BTreeSet<String> {
    diffs.iter().map(|d| d.split(' ').next().unwrap().to_owned()).collect()
}

fn set(items: &[&str]) -> BTreeSet<String> {
    items.iter().map(|s| (*s).to_owned()).collect()
}

/// The identity the XDD's defaults describe.
fn xdd_identity() -> DeviceIdentity {
    DeviceIdentity {
        device_type: 0x000F_0191,
        vendor_id: 0,
        product_code: 0,
        revision_number: 0x0002_0007,
        serial_number: 0,
        device_name: "openPOWERLINK device".to_owned(),
        hardware_version: "1.00".to_owned(),
        software_version: "OPLK V2.7.2".to_owned(),
        mac_address: [0; 6],
        feature_flags: 0x0005_8265,
    }
}

#[test]
fn reference_xdd_is_the_built_in_dictionary_but_for_the_documented_deviations() {
    let xdd = ObjectDictionary::from_xdd(XDD).unwrap();
    assert_eq!(xdd.len(), 41);
    let built_in = ObjectDictionary::controlled_node(1, &xdd_identity());
    let diffs = differences(&xdd, &built_in);
    // The deviations documented at `ObjectDictionary::controlled_node`, identity values aside
    // (the identity above is the XDD's).
    let expected = set(&[
        // InterfacePhysAddress_OSTR: no value in the XDD; built in: the MAC address.
        "0x1030/5 capacity",
        "0x1030/5 default",
        "0x1030/5 value",
        // NMT_CurrNMTState_U8: no value in the XDD; built in: GS_INITIALISING.
        "0x1F8C/0 default",
        "0x1F8C/0 value",
        // NodeID_U8: no value in the XDD; built in: the node ID.
        "0x1F93/1 default",
        "0x1F93/1 value",
        // PResMaxLatency_U32: 2000 ns in the XDD, 50 000 ns built in.
        "0x1F98/3 default",
        "0x1F98/3 value",
    ]);
    assert_eq!(diffs, expected, "{diffs:#?}");
    assert_eq!(xdd.value(0x1030, 5), Some(&[][..]));
    assert_eq!(xdd.u8(0x1F8C, 0), Some(0));
    assert_eq!(xdd.u8(0x1F93, 1), Some(0));
    assert_eq!((xdd.u32(0x1F98, 3), built_in.u32(0x1F98, 3)), (Some(2000), Some(50_000)));
    // No PDO enabled in the XDD.
    assert!(xdd.tpdo(0).is_none() && xdd.rpdo(0).is_none());

    // With Motus's own identity the other differences are identity objects only.
    let motus = ObjectDictionary::controlled_node(1, &DeviceIdentity::default());
    let identity_objects = set(&["0x1008/0", "0x100A/0", "0x1F82/0"]);
    let mut expected = entries_of(&expected);
    expected.extend(identity_objects);
    assert_eq!(entries_of(&differences(&xdd, &motus)), expected);
}

#[test]
fn xdc_gives_the_actual_values() {
    let xdd = ObjectDictionary::from_xdd(XDD).unwrap();
    let mut xdc = ObjectDictionary::from_xdd(XDC).unwrap();
    // Exactly the entries with an actualValue other than the default, and the XDC's older
    // software version.
    let expected = set(&[
        "0x1006/0", "0x100A/0", "0x1020/1", "0x1020/2", "0x1600/0", "0x1600/1", "0x1A00/0", "0x1A00/1",
        "0x1C0B/3", "0x1C0D/3", "0x1C14/0",
    ]);
    assert_eq!(entries_of(&differences(&xdd, &xdc)), expected);
    assert_eq!(xdc.u32(0x1006, 0), Some(50_000));
    assert_eq!(xdc.entry(0x1006, 0).unwrap().default_value(), 50_000u32.to_le_bytes());
    assert_eq!(xdc.u32(0x1020, 1), Some(0x3124));
    assert_eq!(xdc.u32(0x1020, 2), Some(0x0373_5982));
    assert_eq!(xdc.u32(0x1C0B, 3), Some(0x50));
    assert_eq!(xdc.u32(0x1C0D, 3), Some(0x50));
    assert_eq!(xdc.u32(0x1C14, 0), Some(50_000_000));
    assert_eq!(xdc.u16(0x1F98, 8), Some(300));
    assert_eq!(xdc.visible_string(0x100A, 0), Some("OPLK V2.7.0"));
    assert_eq!((xdc.u8(0x1600, 0), xdc.u64(0x1600, 1)), (Some(1), Some(0x0008_0000_0001_6200)));
    assert_eq!((xdc.u8(0x1A00, 0), xdc.u64(0x1A00, 1)), (Some(1), Some(0x0008_0000_0001_6000)));
    // The configured mappings are the PDO channels: 0x6200/1 from the PReq, 0x6000/1 in the PRes.
    let rpdo = xdc.rpdo(0).unwrap();
    assert_eq!((rpdo.objects[0].index, rpdo.objects[0].subindex, rpdo.byte_len()), (0x6200, 1, 1));
    let tpdo = xdc.tpdo(0).unwrap();
    assert_eq!((tpdo.objects[0].index, tpdo.objects[0].subindex, tpdo.byte_len()), (0x6000, 1, 1));
    assert_eq!(xdc.apply_preq_payload(&[0x55]), Ok(1));
    assert_eq!(xdc.u8(0x6200, 1), Some(0x55));
    xdc.set_u8(0x6000, 1, 0xA5).unwrap();
    assert_eq!(xdc.pres_payload(), [0xA5]);
    // The actual values are what a reset restores.
    xdc.set_u32(0x1006, 0, 1000).unwrap();
    xdc.restore_defaults(0x1000..=0x1FFF);
    assert_eq!(xdc.u32(0x1006, 0), Some(50_000));
    assert_eq!(xdc.u8(0x1A00, 0), Some(1));
}

/// A description with `objects` in its ObjectList; the first object is on line 4.
fn doc(objects: &str) -> String {
    format!(
        "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n<ISO15745ProfileContainer \
         xmlns=\"http://www.ethernet-powerlink.org\">\n<ObjectList>\n{objects}\n</ObjectList>\n\
         </ISO15745ProfileContainer>\n"
    )
}

/// A VAR 0x2000 of `data_type` with `attributes` added.
fn var(data_type: &str, attributes: &str) -> String {
    format!(
        "<Object index=\"2000\" name=\"X\" objectType=\"7\" dataType=\"{data_type}\" accessType=\"rw\" \
         {attributes}/>"
    )
}

fn parse(objects: &str) -> Result<ObjectDictionary, XddError> {
    ObjectDictionary::from_xdd(&doc(objects))
}

fn at(line: u32, index: Option<u16>, subindex: Option<u8>) -> XddLocation {
    XddLocation { line, index, subindex }
}

/// The value of 0x2000/0 read as `data_type` from `text`.
fn value_of(data_type: &str, text: &str) -> Result<Vec<u8>, XddError> {
    parse(&var(data_type, &format!("defaultValue=\"{text}\"")))
        .map(|od| od.value(0x2000, 0).unwrap().to_vec())
}

#[test]
fn values_of_every_type() {
    let ok = |t: &str, v: &str| value_of(t, v).unwrap();
    assert_eq!(ok("0001", "true"), [1]);
    assert_eq!(ok("0001", "FALSE"), [0]);
    assert_eq!(ok("0001", "1"), [1]);
    assert_eq!(ok("0002", "0xFF"), [0xFF]);
    assert_eq!(ok("0002", "-128"), [0x80]);
    assert_eq!(ok("0003", "-300"), (-300i16).to_le_bytes());
    assert_eq!(ok("0003", "0x8000"), i16::MIN.to_le_bytes());
    assert_eq!(ok("0004", " +7 "), [7, 0, 0, 0]);
    assert_eq!(ok("0015", "-9223372036854775808"), i64::MIN.to_le_bytes());
    assert_eq!(ok("0005", "0x20"), [0x20]);
    assert_eq!(ok("0006", "1490"), 1490u16.to_le_bytes());
    assert_eq!(ok("0007", "0x000F0191"), 0x000F_0191u32.to_le_bytes());
    assert_eq!(ok("001B", "0xFFFFFFFFFFFFFFFF"), u64::MAX.to_le_bytes());
    assert_eq!(ok("001b", "18446744073709551615"), u64::MAX.to_le_bytes());
    assert_eq!(ok("0008", "1.5"), 1.5f32.to_le_bytes());
    assert_eq!(ok("0008", "0x3FC00000"), 1.5f32.to_le_bytes());
    assert_eq!(ok("0011", "-2.25"), (-2.25f64).to_le_bytes());
    assert_eq!(ok("0011", "0x3FF8000000000000"), 1.5f64.to_le_bytes());
    assert_eq!(ok("0009", " a b "), b" a b ");
    assert_eq!(ok("000A", "0x0011AAff"), [0x00, 0x11, 0xAA, 0xFF]);
    assert_eq!(ok("000F", "0102"), [1, 2]);
    // Without a value: zero, or empty for strings.
    let od = parse(&var("0007", "")).unwrap();
    assert_eq!(od.u32(0x2000, 0), Some(0));
    let od = parse(&var("0009", "")).unwrap();
    assert_eq!(od.value(0x2000, 0), Some(&[][..]));
    // A string takes at most its value's length.
    let mut od = parse(&var("0009", "defaultValue=\"abc\"")).unwrap();
    assert_eq!(od.set(0x2000, 0, b"xyz"), Ok(()));
    assert_eq!(od.set(0x2000, 0, b"wxyz"), Err(SdoAbortCode::TypeLengthTooHigh));
}

#[test]
fn attributes_of_entries() {
    let od = parse(
        "<Object index=\"0x2001\" name=\"R\" objectType=\"9\">\n\
         <SubObject subIndex=\"00\" name=\"NumberOfEntries\" objectType=\"7\" dataType=\"0005\" accessType=\"rw\" defaultValue=\"5\"/>\n\
         <SubObject subIndex=\"01\" name=\"A\" dataType=\"0001\" accessType=\"rww\" PDOmapping=\"default\"/>\n\
         <SubObject subIndex=\"05\" name=\"B\" dataType=\"0006\" accessType=\"wo\" PDOmapping=\"RPDO\" lowLimit=\"10\" highLimit=\"0x20\" defaultValue=\"10\" actualValue=\"0x1F\"/>\n\
         </Object>",
    )
    .unwrap();
    let object = od.object(0x2001).unwrap();
    assert_eq!((object.name(), object.kind()), ("R", ObjectKind::Record));
    assert_eq!(object.entries().map(|(s, _)| s).collect::<Vec<_>>(), [0, 1, 5]);
    let sub0 = object.entry(0).unwrap();
    // A writable NumberOfEntries is limited to the highest subindex.
    assert_eq!(
        (sub0.access(), sub0.range(), sub0.value()),
        (Access::ReadWrite, (Some(0), Some(5)), &[5][..])
    );
    let a = object.entry(1).unwrap();
    assert_eq!(
        (a.access(), a.pdo_mappable(), a.range()),
        (Access::ReadWrite, PdoMappable::Both, (Some(0), Some(1)))
    );
    let b = object.entry(5).unwrap();
    assert_eq!((b.name(), b.data_type(), b.access()), ("B", DataType::Unsigned16, Access::WriteOnly));
    assert_eq!((b.pdo_mappable(), b.range()), (PdoMappable::Rpdo, (Some(10), Some(0x20))));
    assert_eq!((b.value(), b.default_value()), (&[0x1F, 0][..], &[0x1F, 0][..]));
}

#[test]
fn malformed_descriptions_are_refused_with_where_and_what() {
    let r = |objects: &str| parse(objects).unwrap_err();
    let x = |text: &str| ObjectDictionary::from_xdd(text).unwrap_err();
    let obj = Some(0x2000);

    assert!(matches!(x("<ObjectList><Object index=\"1000\"></ObjectList>"), XddError::Xml { line: 1, .. }));
    assert!(matches!(r("<Object index=\"2000\"\n name=\"X\""), XddError::Xml { line, .. } if line >= 5));
    assert!(matches!(x("<!DOCTYPE x [<!ENTITY a \"b\">]><ObjectList/>"), XddError::Xml { .. }));
    assert_eq!(x("<x><y/></x>"), XddError::NoObjectList);
    assert!(
        matches!(x("<a><ObjectList/>\n<ObjectList/></a>"), XddError::SecondObjectList { at } if at.line == 2)
    );
    assert!(matches!(r(""), XddError::Structure { .. }));
    assert_eq!(r("<Foo/>"), XddError::UnexpectedElement { at: at(4, None, None), element: "Foo".to_owned() });

    // Missing or malformed attributes.
    assert_eq!(
        r("<Object name=\"X\" objectType=\"7\" dataType=\"0007\" accessType=\"rw\"/>"),
        XddError::MissingAttribute { at: at(4, None, None), attribute: "index" }
    );
    assert!(matches!(
        r("<Object index=\"12345\" name=\"X\" objectType=\"7\" dataType=\"0007\" accessType=\"rw\"/>"),
        XddError::InvalidAttribute { attribute: "index", .. }
    ));
    assert_eq!(
        r("<Object index=\"2000\" name=\"X\" objectType=\"7\" accessType=\"rw\"/>"),
        XddError::MissingAttribute { at: at(4, obj, None), attribute: "dataType" }
    );
    assert_eq!(
        r("<Object index=\"2000\" objectType=\"7\" dataType=\"0007\" accessType=\"rw\"/>"),
        XddError::MissingAttribute { at: at(4, obj, None), attribute: "name" }
    );
    assert_eq!(
        r("<Object index=\"2000\" name=\"X\" objectType=\"7\" dataType=\"0007\"/>"),
        XddError::MissingAttribute { at: at(4, obj, None), attribute: "accessType" }
    );
    // Without a value the entry would start at 0, which its limits refuse (found by
    // `mutated_reference_never_panics`).
    assert_eq!(
        r(&var("0006", "lowLimit=\"300\" highLimit=\"1500\"")),
        XddError::MissingAttribute { at: at(4, obj, None), attribute: "defaultValue" }
    );
    assert!(matches!(
        r("<Object index=\"2000\" name=\"X\" objectType=\"7\" dataType=\"0007\" accessType=\"rx\"/>"),
        XddError::InvalidAttribute { at: a, attribute: "accessType", .. } if a == at(4, obj, None)
    ));
    assert!(matches!(
        r(&var("0007", "PDOmapping=\"maybe\"")),
        XddError::InvalidAttribute { attribute: "PDOmapping", .. }
    ));
    assert!(matches!(r(&var("00G7", "")), XddError::InvalidAttribute { attribute: "dataType", .. }));

    // Unknown data type.
    assert_eq!(
        r(&var("0010", "")),
        XddError::UnknownDataType { at: at(4, obj, None), code: "0010".to_owned() }
    );

    // Values out of their type.
    for (data_type, text) in [
        ("0005", "256"),
        ("0005", "-1"),
        ("0002", "-129"),
        ("0002", "0x100"),
        ("0006", "0x10000"),
        ("0001", "2"),
        ("0007", "abc"),
        ("0007", "0x"),
        ("0007", "1.5"),
        ("001B", "18446744073709551616"),
        ("0008", "1e40"),
        ("0008", "0x123456789"),
        ("000A", "0x123"),
        ("000A", "zz"),
    ] {
        let e = value_of(data_type, text).unwrap_err();
        assert!(
            matches!(&e, XddError::InvalidValue { at: a, attribute: "defaultValue", value, .. }
                if *a == at(4, obj, None) && value == text),
            "{data_type} {text}: {e:?}"
        );
    }
    let e = value_of("0005", "256").unwrap_err();
    assert!(matches!(e, XddError::InvalidValue { data_type: DataType::Unsigned8, .. }));
    assert_eq!(
        e.to_string(),
        "line 4, object 0x2000: defaultValue=\"256\" is not a valid UNSIGNED8 value: out of range 0..=255"
    );

    // Limits.
    let e = r(&var("0006", "lowLimit=\"0\" highLimit=\"254\" defaultValue=\"1\" actualValue=\"500\""));
    assert!(
        matches!(&e, XddError::InvalidValue { attribute: "actualValue", reason, .. } if reason.contains("highLimit")),
        "{e:?}"
    );
    assert!(matches!(
        r(&var("0006", "lowLimit=\"36\" defaultValue=\"0\"")),
        XddError::InvalidValue { attribute: "defaultValue", .. }
    ));
    assert!(matches!(
        r(&var("0006", "lowLimit=\"9\" highLimit=\"8\"")),
        XddError::InvalidAttribute { attribute: "lowLimit", .. }
    ));
    assert!(matches!(
        r(&var("0006", "highLimit=\"70000\"")),
        XddError::InvalidValue { attribute: "highLimit", .. }
    ));
    assert!(matches!(r(&var("0009", "highLimit=\"1\"")), XddError::Unsupported { .. }));

    // Duplicates.
    let two = format!("{}\n{}", var("0005", ""), var("0006", ""));
    assert_eq!(r(&two), XddError::DuplicateObject { at: at(5, obj, None) });
    let record = |subs: &str| {
        format!(
            "<Object index=\"2000\" name=\"R\" objectType=\"8\">\n\
             <SubObject subIndex=\"00\" name=\"N\" objectType=\"7\" dataType=\"0005\" accessType=\"const\" defaultValue=\"2\"/>\n{subs}</Object>"
        )
    };
    let sub = |i: &str, t: &str| {
        format!("<SubObject subIndex=\"{i}\" name=\"E\" dataType=\"{t}\" accessType=\"ro\"/>\n")
    };
    assert_eq!(
        r(&record(&format!("{}{}", sub("01", "0007"), sub("01", "0007")))),
        XddError::DuplicateSubObject { at: at(7, obj, Some(1)) }
    );

    // Structure.
    assert!(matches!(
        r(&record(&format!("{}{}", sub("01", "0007"), sub("02", "0006")))),
        XddError::Structure { at: a, .. } if a == at(7, obj, Some(2))
    ));
    assert!(matches!(
        r("<Object index=\"2000\" name=\"R\" objectType=\"9\">\n<SubObject subIndex=\"01\" name=\"E\" dataType=\"0007\" accessType=\"ro\"/>\n</Object>"),
        XddError::Structure { at: a, .. } if a == at(4, obj, None)
    ));
    assert!(matches!(
        r("<Object index=\"2000\" name=\"R\" objectType=\"9\">\n<SubObject subIndex=\"00\" name=\"N\" dataType=\"0006\" accessType=\"ro\"/>\n</Object>"),
        XddError::Structure { at: a, .. } if a == at(5, obj, Some(0))
    ));
    assert!(matches!(
        r("<Object index=\"2000\" name=\"R\" objectType=\"9\">\n<SubObject subIndex=\"00\" name=\"N\" dataType=\"0005\" accessType=\"rw\" defaultValue=\"3\"/>\n</Object>"),
        XddError::Structure { at: a, .. } if a == at(5, obj, Some(0))
    ));
    assert!(matches!(
        r("<Object index=\"2000\" name=\"X\" objectType=\"7\" dataType=\"0007\" accessType=\"rw\">\n<SubObject/>\n</Object>"),
        XddError::UnexpectedElement { at: a, .. } if a == at(5, obj, None)
    ));
    assert!(matches!(r(&record("<Foo/>\n")), XddError::UnexpectedElement { .. }));
    assert!(matches!(
        r(&record("<SubObject subIndex=\"100\" name=\"E\" dataType=\"0007\" accessType=\"ro\"/>\n")),
        XddError::InvalidAttribute { attribute: "subIndex", .. }
    ));

    // Unsupported features.
    assert!(matches!(
        r(&var("0007", "uniqueIDRef=\"UID_PARAM_1\"")),
        XddError::Unsupported { at: a, what } if a == at(4, obj, None) && what.contains("uniqueIDRef")
    ));
    assert!(matches!(
        r("<Object index=\"2000\" name=\"D\" objectType=\"2\"/>"),
        XddError::Unsupported { at: a, .. } if a == at(4, obj, None)
    ));
    assert!(matches!(
        r("<Object index=\"2000\" name=\"D\" objectType=\"X\"/>"),
        XddError::InvalidAttribute { attribute: "objectType", .. }
    ));
    assert!(matches!(
        r(&record("<SubObject subIndex=\"01\" name=\"E\" objectType=\"8\" dataType=\"0007\" accessType=\"ro\"/>\n")),
        XddError::Unsupported { at: a, .. } if a == at(6, obj, Some(1))
    ));

    // An enabled PDO mapping of an object that is not mappable.
    let mapping = "<Object index=\"1A00\" name=\"M\" objectType=\"8\">\n\
        <SubObject subIndex=\"00\" name=\"N\" dataType=\"0005\" accessType=\"rw\" actualValue=\"1\"/>\n\
        <SubObject subIndex=\"01\" name=\"E\" dataType=\"001B\" accessType=\"rw\" actualValue=\"0x0008000000002000\"/>\n\
        </Object>";
    let e = r(&format!("{}\n{mapping}", var("0005", "")));
    assert!(
        matches!(e, XddError::PdoMapping(MappingError::NotMappable { mapping: 0x1A00, index: 0x2000, .. })),
        "{e:?}"
    );
    // ... and the same mapping of a mappable object is a PDO channel.
    let od = parse(&format!("{}\n{mapping}", var("0005", "PDOmapping=\"TPDO\" defaultValue=\"7\""))).unwrap();
    assert_eq!(od.pres_payload(), [7]);
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    /// Every entry of an accepted dictionary holds a value it would accept, which is its
    /// default, and the enabled mappings are valid.
    fn check_accepted(od: &ObjectDictionary) -> Result<(), TestCaseError> {
        for (index, object) in od.objects() {
            for (sub, entry) in object.entries() {
                prop_assert_eq!(entry.check(entry.value()), Ok(()), "0x{:04X}/{}", index, sub);
                prop_assert_eq!(entry.value(), entry.default_value());
            }
        }
        for m in [0x1600u16, 0x1601, 0x1602, 0x1A00] {
            prop_assert!(od.pdo_mapping(m).is_ok());
        }
        Ok(())
    }

    fn pick(items: &[&'static str]) -> impl Strategy<Value = &'static str> {
        prop::sample::select(items.to_vec())
    }

    /// An attribute `name="value"`: mostly a good value, sometimes a bad one or none.
    fn attr(
        name: &'static str,
        good: &[&'static str],
        bad: &[&'static str],
    ) -> impl Strategy<Value = String> {
        let some = move |v: &str| format!(" {name}=\"{v}\"");
        prop_oneof![
            20 => pick(good).prop_map(some),
            1 => pick(bad).prop_map(some),
            1 => Just(String::new()),
        ]
    }

    /// The attributes of an entry. "00" and "01" are values of every type.
    fn entry_attributes() -> impl Strategy<Value = String> {
        let bad_values = &[
            "-1",
            "2",
            "256",
            "0xFF",
            "0x",
            "true",
            "1.5",
            "-0x80",
            "0x0011",
            "abc",
            "",
            "18446744073709551615",
            "-9223372036854775809",
            "1e40",
            "NaN",
            "0x3FC00000",
            " 7 ",
            "0x0008000000002000",
        ];
        let types = &[
            "0001", "0002", "0003", "0004", "0005", "0006", "0007", "0008", "0009", "000A", "000F", "0011",
            "0015", "001B",
        ];
        let no_limit = || prop_oneof![12 => Just(""), 1 => Just("0"), 1 => pick(bad_values)];
        (
            attr("dataType", types, &["0010", "zz", "", "10000"]),
            attr("accessType", &["ro", "rw", "const", "wo", "rww", "rwr"], &["xx", ""]),
            attr("PDOmapping", &["no", "TPDO", "RPDO", "optional", "default"], &["bad"]),
            no_limit().prop_map(|v| if v.is_empty() { String::new() } else { format!(" lowLimit=\"{v}\"") }),
            no_limit().prop_map(|v| if v.is_empty() { String::new() } else { format!(" highLimit=\"{v}\"") }),
            attr("defaultValue", &["00", "01"], bad_values),
            prop_oneof![3 => Just(String::new()), 1 => attr("actualValue", &["00", "01"], bad_values)],
            attr("name", &["E"], &[""]),
        )
            .prop_map(|(a, b, c, d, e, f, g, h)| format!("{a}{b}{c}{d}{e}{f}{g}{h}"))
    }

    /// A VAR, ARRAY or RECORD object, mostly well-formed.
    fn object() -> impl Strategy<Value = String> {
        let index = || attr("index", &["2000", "2001", "0x2002", "1A00", "1600"], &["FFFFF", "zz", ""]);
        let var = (index(), attr("objectType", &["7"], &["8", "2", "x"]), entry_attributes())
            .prop_map(|(i, t, e)| format!("<Object{i}{t}{e}/>"));
        let sub = (attr("subIndex", &["01", "02", "03", "FF"], &["100", ""]), entry_attributes())
            .prop_map(|(s, e)| format!("<SubObject{s}{e}/>"));
        let sub0 = attr("defaultValue", &["0", "1", "2", "3"], &["300"]).prop_map(|d| {
            format!("<SubObject subIndex=\"00\" name=\"N\" dataType=\"0005\" accessType=\"rw\"{d}/>")
        });
        let complex = (
            index(),
            attr("objectType", &["8", "9"], &["7"]),
            prop::option::weighted(0.9, sub0),
            prop::collection::vec(sub, 0..4),
        )
            .prop_map(|(i, t, sub0, subs)| {
                format!("<Object{i}{t} name=\"R\">{}{}</Object>", sub0.unwrap_or_default(), subs.concat())
            });
        prop_oneof![var, complex]
    }

    /// A token that may break or bend the reference description.
    fn token() -> impl Strategy<Value = &'static str> {
        pick(&[
            "\"",
            "<",
            ">",
            "/",
            "=",
            "0x",
            "-",
            "&amp;",
            "&bad;",
            "<SubObject/>",
            "</Object>",
            "FF",
            " ",
            "9",
            "x",
            "<Object index=\"1000\"/>",
            "subIndex=\"00\" ",
            "<!--",
            "-->",
            "<![CDATA[",
            "]]>",
        ])
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        #[test]
        fn arbitrary_text_never_panics(text in "\\PC{0,300}") {
            if let Ok(od) = ObjectDictionary::from_xdd(&text) {
                check_accepted(&od)?;
            }
        }

        #[test]
        fn generated_descriptions_never_panic(objects in prop::collection::vec(object(), 1..5)) {
            if let Ok(od) = parse(&objects.join("\n")) {
                check_accepted(&od)?;
            }
        }

        /// The reference description with one span deleted or one token inserted, inside its
        /// ObjectList.
        #[test]
        fn mutated_reference_never_panics(place in 0.0f64..1.0, delete in 0usize..40, insert in token(), del in any::<bool>()) {
            let start = XDD.find("<ObjectList>").unwrap();
            let end = XDD.find("</ObjectList>").unwrap();
            let pos = start + ((end - start) as f64 * place) as usize;
            let mut text = XDD[..pos].to_owned();
            if del {
                text.push_str(XDD.get(pos + delete..).unwrap_or_default());
            } else {
                text.push_str(insert);
                text.push_str(&XDD[pos..]);
            }
            if let Ok(od) = ObjectDictionary::from_xdd(&text) {
                check_accepted(&od)?;
            }
        }
    }
}
