//! Process-value extraction from PRes payloads ([`ValueMap`]), with the example Acopos map.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_epl_protocol::*;

#[test]
fn acopos_example_map() {
    let map = ValueMap::from_toml(include_str!("../examples/acopos-map.toml")).unwrap();
    assert_eq!(map.nodes.len(), 2);
    // Payload: 16 filler bytes, position -100000 (0xFFFE7960 LE: 60 79 fe ff), speed 2500 (c4 09 00 00).
    let mut payload = vec![0xee; 16];
    payload.extend_from_slice(&[0x60, 0x79, 0xfe, 0xff, 0xc4, 0x09, 0x00, 0x00]);
    let s = map.extract(2, &payload).unwrap();
    assert_eq!(
        s,
        [
            Sample { name: "position", value: Value::I32(-100_000) },
            Sample { name: "speed", value: Value::I32(2500) }
        ]
    );
    assert_eq!(s[0].value.as_f64(), -100_000.0);
    assert_eq!(
        serde_json::to_string(&s).unwrap(),
        r#"[{"name":"position","value":-100000},{"name":"speed","value":2500}]"#
    );
    // 22 bytes: speed (20..24) does not fit.
    let err = map.extract(1, &payload[..22]).unwrap_err();
    assert_eq!(
        err,
        ExtractError::OutOfRange { node: 1, name: "speed".into(), offset: 20, width: 4, payload_len: 22 }
    );
    assert_eq!(err.to_string(), "node 1 value \"speed\": bytes 20..24 beyond the 22-byte PRes payload");
    assert_eq!(map.extract(9, &payload), Err(ExtractError::NodeNotMapped(9)));
}

#[test]
fn every_type_little_endian() {
    let toml = r#"
        [[node]]
        node = 7
        values = [
          { name = "a", offset = 0, type = "i8" },
          { name = "b", offset = 0, type = "u8" },
          { name = "c", offset = 1, type = "i16" },
          { name = "d", offset = 1, type = "u16" },
          { name = "e", offset = 3, type = "u32" },
          { name = "f", offset = 7, type = "f32" },
        ]
    "#;
    let map = ValueMap::from_toml(toml).unwrap();
    // 0xff = -1 / 255; 0x8001 LE (01 80) = -32767 / 32769; 0x12345678 LE; 1.5f32 = 0x3fc00000 LE.
    let payload = [0xff, 0x01, 0x80, 0x78, 0x56, 0x34, 0x12, 0x00, 0x00, 0xc0, 0x3f];
    let v: Vec<Value> = map.extract(7, &payload).unwrap().into_iter().map(|s| s.value).collect();
    assert_eq!(
        v,
        [
            Value::I8(-1),
            Value::U8(255),
            Value::I16(-32767),
            Value::U16(32769),
            Value::U32(0x1234_5678),
            Value::F32(1.5)
        ]
    );
}

#[test]
fn bad_maps_are_rejected() {
    assert!(matches!(
        ValueMap::from_toml("[[node]]\nnode = 1\nvalues = [{ name = \"x\", offset = 0, type = \"i64\" }]"),
        Err(ValueMapError::Toml(_))
    ));
    assert!(matches!(ValueMap::from_toml("[[node]]\nnode = 300\nvalues = []"), Err(ValueMapError::Toml(_))));
    assert_eq!(
        ValueMap::from_toml("[[node]]\nnode = 1\nvalues = []\n[[node]]\nnode = 1\nvalues = []"),
        Err(ValueMapError::DuplicateNode(1))
    );
    assert_eq!(
        ValueMap::from_toml("[[node]]\nnode = 1\nvalues = [{ name = \"x\", offset = 0, type = \"u8\" }, { name = \"x\", offset = 1, type = \"u8\" }]"),
        Err(ValueMapError::DuplicateName { node: 1, name: "x".into() })
    );
    // Offsets near usize::MAX do not overflow.
    let map = ValueMap {
        nodes: vec![NodeValues {
            node: 1,
            label: None,
            values: vec![ValueSpec { name: "x".into(), offset: usize::MAX, ty: ValueType::U32 }],
        }],
    };
    assert!(matches!(map.extract(1, &[0; 8]), Err(ExtractError::OutOfRange { .. })));
}

#[test]
fn extract_from_decoded_frame() {
    // PRes of node 1 carrying 24 payload bytes; position at 16, speed at 20.
    let mut payload = vec![0u8; 16];
    payload.extend_from_slice(&1234i32.to_le_bytes());
    payload.extend_from_slice(&(-5i32).to_le_bytes());
    let pres = PRes {
        nmt_state: NmtState::Operational,
        flags: Flags::RD,
        pr_rs: PrRs::default(),
        pdo_version: 0,
        payload,
        reserved: 0,
    };
    let bytes = EplFrame::new(MacAddr([2, 0, 0, 0, 0, 1]), MacAddr::PRES, 255, 1, Message::PRes(pres))
        .encode()
        .unwrap();
    let frame = EplFrame::decode(&bytes).unwrap();
    let map = ValueMap::from_toml(include_str!("../examples/acopos-map.toml")).unwrap();
    let s = map.extract_frame(&frame).unwrap().unwrap();
    assert_eq!(s[0].value, Value::I32(1234));
    assert_eq!(s[1].value, Value::I32(-5));
}
