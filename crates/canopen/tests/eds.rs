//! EDS loading on the shared interop fixture (tests/data/drive402.eds, a copy of
//! /work/shared/fixtures/canopen/drive402.eds); expected values read off the file by hand.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_canopen::eds::EdsError;
use motus_canopen::{Access, DataType, ObjectDictionary, Value};

fn od() -> ObjectDictionary {
    ObjectDictionary::load(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/drive402.eds").as_ref()).unwrap()
}

#[test]
fn objects_of_drive402() {
    let od = od();
    // VARs: 1000 1001 1008 1017 603F 6040 6041 6060 6061 6064 607A 6081 6083 6084 6502 = 15;
    // subs: 1018 (5) + 1400/1401 (3+3) + 1600 (3) + 1601 (2) + 1800/1801 (5+5) + 1A00 (3) + 1A01 (2) = 31.
    assert_eq!(od.len(), 46);
    let sw = od.lookup(0x6041, 0).unwrap();
    assert_eq!(
        (sw.name.as_str(), sw.data_type, sw.access, sw.pdo_mappable),
        ("Statusword", DataType::Unsigned16, Access::ReadOnly, true)
    );
    let mode = od.find("Modes of operation").unwrap();
    assert_eq!((mode.index, mode.data_type), (0x6060, DataType::Integer8));
    let vendor = od.find("Identity object.Vendor-ID").unwrap();
    assert_eq!((vendor.index, vendor.sub), (0x1018, 1));
    assert_eq!(vendor.default_value(5), Some(Ok(Value::Uint(0x123))));
    // $NODEID+0x180 for node 5 = 0x185.
    assert_eq!(od.lookup(0x1800, 1).unwrap().default_value(5), Some(Ok(Value::Uint(0x185))));
    assert_eq!(od.lookup(0x1A00, 1).unwrap().default_value(1), Some(Ok(Value::Uint(0x6041_0010))));
    assert_eq!(
        od.lookup(0x1008, 0).unwrap().default_value(1),
        Some(Ok(Value::Text("SimDrive402 example".into())))
    );
    assert_eq!(od.lookup(0x1008, 0).unwrap().access, Access::Const);
    assert!(od.lookup(0x1800, 4).is_none());
    assert_eq!(od.device_info.get("productname").map(String::as_str), Some("SimDrive402"));
    // Typed decode through the dictionary: position actual value INTEGER32.
    let pos = od.lookup(0x6064, 0).unwrap();
    assert_eq!(pos.data_type.decode(&[0x18, 0xFC, 0xFF, 0xFF]).unwrap(), Value::Int(-1000));
}

#[test]
fn compact_sub_objects_and_errors() {
    let text = "[1016]\nParameterName=Consumer heartbeat time\nObjectType=0x8\nDataType=0x0007\nAccessType=rw\nCompactSubObj=3\nDefaultValue=0\n";
    let od = ObjectDictionary::parse(text).unwrap();
    assert_eq!(od.len(), 4);
    assert_eq!(od.lookup(0x1016, 3).unwrap().data_type, DataType::Unsigned32);
    assert!(matches!(ObjectDictionary::parse("[1000]\nnonsense\n"), Err(EdsError::Syntax { line: 2, .. })));
    assert!(matches!(
        ObjectDictionary::parse("[1000]\nDataType=zz\n"),
        Err(EdsError::BadField { key: "DataType", .. })
    ));
}
