#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use super::*;

/// Mapping entry: object `index`/`sub`, `bits` long at bit `offset`.
fn map(index: u16, sub: u8, offset: u16, bits: u16) -> u64 {
    MappingEntry { index, subindex: sub, reserved: 0, bit_offset: offset, bit_length: bits }.to_raw()
}

fn cn() -> ObjectDictionary {
    ObjectDictionary::controlled_node(1, &DeviceIdentity::default())
}

fn w(od: &mut ObjectDictionary, index: u16, sub: u8, value: &[u8]) -> Result<(), SdoAbortCode> {
    od.write(index, sub, value)
}

/// The demo MN's configuration of node 1 (`demo_3cn_1ms.txt`, 0x1F22/1): PReq byte 0 ->
/// 0x6200/1, 0x6000/1 -> PRes byte 0.
fn configure_demo_mapping(od: &mut ObjectDictionary) {
    w(od, 0x1600, 0, &[0]).unwrap();
    w(od, 0x1A00, 0, &[0]).unwrap();
    w(od, 0x1600, 1, &0x0008_0000_0001_6200u64.to_le_bytes()).unwrap();
    w(od, 0x1A00, 1, &0x0008_0000_0001_6000u64.to_le_bytes()).unwrap();
    w(od, 0x1600, 0, &[1]).unwrap();
    w(od, 0x1A00, 0, &[1]).unwrap();
}

#[test]
fn controlled_node_holds_every_xdd_object() {
    let od = cn();
    // Every object index of 00000000_POWERLINK_CiA401_CN.xdd.
    let xdd = [
        0x1000, 0x1001, 0x1006, 0x1008, 0x1009, 0x100A, 0x1018, 0x1020, 0x1030, 0x1050, 0x1300, 0x1400,
        0x1401, 0x1402, 0x1600, 0x1601, 0x1602, 0x1800, 0x1A00, 0x1C0B, 0x1C0D, 0x1C0F, 0x1C14, 0x1F81,
        0x1F82, 0x1F83, 0x1F8C, 0x1F8D, 0x1F93, 0x1F98, 0x1F99, 0x1F9B, 0x1F9E, 0x6000, 0x6200, 0x6400,
        0x6401, 0x6402, 0x6410, 0x6411, 0x6412,
    ];
    let ours: Vec<u16> = od.objects().map(|(i, _)| i).collect();
    assert_eq!(ours, xdd);
    assert_eq!(od.u32(0x1000, 0), Some(0x000F_0191));
    assert_eq!(od.u32(0x1006, 0), Some(1000));
    assert_eq!(od.u8(0x1018, 0), Some(4));
    assert_eq!(od.u32(0x1018, 3), Some(0x0002_0007));
    assert_eq!(od.u8(0x1030, 0), Some(9));
    assert_eq!(od.value(0x1030, 5), Some(&[0u8; 6][..]));
    assert_eq!(od.bool(0x1030, 9), Some(true));
    assert_eq!(od.u8(0x1050, 0), Some(254));
    assert_eq!(od.u32(0x1300, 0), Some(15000));
    assert_eq!(od.u8(0x1600, 0), Some(0));
    assert_eq!(od.object(0x1600).unwrap().entries().count(), 26);
    assert_eq!(od.u32(0x1C0B, 3), Some(15));
    assert_eq!(od.u32(0x1C14, 0), Some(100_000));
    assert_eq!(od.u8(0x1F81, 0), Some(254));
    assert_eq!(od.u32(0x1F82, 0), Some(MOTUS_CN_FEATURE_FLAGS));
    assert_eq!(od.u8(0x1F83, 0), Some(0x20));
    assert_eq!(od.u8(0x1F8C, 0), Some(0x19));
    assert_eq!(od.u16(0x1F8D, 254), Some(36));
    assert_eq!(od.u8(0x1F93, 1), Some(1));
    assert_eq!(od.u8(0x1F98, 0), Some(14));
    assert_eq!(od.u16(0x1F98, 1), Some(1490));
    assert_eq!(od.u16(0x1F98, 5), Some(36));
    assert_eq!(od.u16(0x1F98, 9), Some(2));
    assert_eq!(od.u32(0x1F99, 0), Some(5_000_000));
    assert_eq!(od.u8(0x1F9E, 0), Some(255));
    assert_eq!(od.u8(0x6000, 0), Some(4));
    assert_eq!(od.u8(0x6402, 0), Some(1));
    assert_eq!(od.visible_string(0x1030, 2), Some("Interface 1"));
    let e = od.entry(0x6000, 1).unwrap();
    assert_eq!(
        (e.name(), e.data_type(), e.access(), e.pdo_mappable()),
        ("DigitalInput", DataType::Unsigned8, Access::ReadOnly, PdoMappable::Tpdo)
    );
    assert_eq!(od.entry(0x6200, 4).unwrap().pdo_mappable(), PdoMappable::Rpdo);
    assert_eq!(od.object(0x1F98).unwrap().kind(), ObjectKind::Record);
    assert_eq!(od.object(0x1F98).unwrap().name(), "NMT_CycleTiming_REC");
}

#[test]
fn identity_goes_where_the_xdd_says() {
    let id = DeviceIdentity {
        vendor_id: 0x1234,
        product_code: 7,
        serial_number: 99,
        device_name: "safety node".into(),
        mac_address: [2, 0, 0, 0, 0, 9],
        ..DeviceIdentity::default()
    };
    let mut od = ObjectDictionary::controlled_node(17, &id);
    assert_eq!(od.u32(0x1018, 1), Some(0x1234));
    assert_eq!(od.u32(0x1018, 2), Some(7));
    assert_eq!(od.u32(0x1018, 4), Some(99));
    assert_eq!(od.read(0x1008, 0).unwrap(), b"safety node");
    assert_eq!(od.read(0x1030, 5).unwrap(), [2, 0, 0, 0, 0, 9]);
    assert_eq!(od.u8(0x1F93, 1), Some(17));
    assert!(od.visible_string(0x100A, 0).unwrap().starts_with("Motus "));
}

#[test]
fn refusals_carry_the_sdo_abort_code() {
    let mut od = cn();
    // openPOWERLINK's CN has no 0x1011/0x1010 either (oplk_mn_cn_bridge_monitor.pcapng 938).
    assert_eq!(od.write(0x1011, 1, b"load"), Err(SdoAbortCode::ObjectDoesNotExist));
    assert_eq!(od.read(0x1010, 1), Err(SdoAbortCode::ObjectDoesNotExist));
    assert_eq!(od.read(0x1018, 5), Err(SdoAbortCode::SubIndexDoesNotExist));
    assert_eq!(od.read(0x1006, 1), Err(SdoAbortCode::SubIndexDoesNotExist));
    assert_eq!(od.write(0x1000, 0, &[0; 4]), Err(SdoAbortCode::ReadOnly));
    assert_eq!(od.write(0x1018, 1, &[0; 4]), Err(SdoAbortCode::ReadOnly));
    assert_eq!(od.write(0x1018, 0, &[4]), Err(SdoAbortCode::ReadOnly));
    assert_eq!(od.write(0x1F8C, 0, &[0xFD]), Err(SdoAbortCode::ReadOnly));
    assert_eq!(od.write(0x6000, 1, &[1]), Err(SdoAbortCode::ReadOnly));
    assert_eq!(od.write(0x1006, 0, &[0xE8, 3]), Err(SdoAbortCode::TypeLengthTooLow));
    assert_eq!(od.write(0x1006, 0, &[0xE8, 3, 0, 0, 0]), Err(SdoAbortCode::TypeLengthTooHigh));
    assert_eq!(od.write(0x1F98, 4, &35u16.to_le_bytes()), Err(SdoAbortCode::ValueTooLow));
    assert_eq!(od.write(0x1F98, 5, &1491u16.to_le_bytes()), Err(SdoAbortCode::ValueTooHigh));
    assert_eq!(od.write(0x1300, 0, &99u32.to_le_bytes()), Err(SdoAbortCode::ValueTooLow));
    assert_eq!(od.write(0x1400, 1, &[255]), Err(SdoAbortCode::ValueTooHigh));
    assert_eq!(od.write(0x1030, 8, &[2]), Err(SdoAbortCode::ValueTooHigh));
    assert_eq!(od.write(0x1600, 0, &[26]), Err(SdoAbortCode::ValueTooHigh));
    assert_eq!(od.write(0x1F81, 0, &[255]), Err(SdoAbortCode::ValueTooHigh));
    // Nothing refused was stored.
    assert_eq!(od.u32(0x1006, 0), Some(1000));
    assert_eq!(od.u16(0x1F98, 4), Some(36));
    assert!(od.take_remote_writes().is_empty());
    // Accepted writes are.
    od.write(0x1006, 0, &50_000u32.to_le_bytes()).unwrap();
    assert_eq!(od.read(0x1006, 0).unwrap(), 50_000u32.to_le_bytes());
    od.write(0x1F98, 5, &1490u16.to_le_bytes()).unwrap();
    assert_eq!(od.u16(0x1F98, 5), Some(1490));
}

#[test]
fn write_only_entries_cannot_be_read() {
    let mut od = ObjectDictionary::new();
    od.insert(0x2000, Object::var(Entry::unsigned32("Command", Access::WriteOnly, 0)));
    od.write(0x2000, 0, &7u32.to_le_bytes()).unwrap();
    assert_eq!(od.read(0x2000, 0), Err(SdoAbortCode::WriteOnly));
    assert_eq!(od.u32(0x2000, 0), Some(7));
    assert_eq!(od.take_remote_writes().into_iter().collect::<Vec<_>>(), [(0x2000, 0)]);
}

#[test]
fn local_set_bypasses_access_but_not_size_or_range() {
    let mut od = cn();
    od.set_u8(0x1F8C, 0, 0xFD).unwrap();
    assert_eq!(od.u8(0x1F8C, 0), Some(0xFD));
    od.set_u8(0x6000, 2, 0xA5).unwrap();
    assert_eq!(od.set_u16(0x1F8C, 0, 1), Err(SdoAbortCode::TypeLengthTooHigh));
    assert_eq!(od.set_u16(0x1F98, 4, 10), Err(SdoAbortCode::ValueTooLow));
    assert_eq!(od.set_u8(0x7000, 0, 1), Err(SdoAbortCode::ObjectDoesNotExist));
    assert!(od.take_remote_writes().is_empty(), "local sets are not remote writes");
    od.write(0x1006, 0, &2000u32.to_le_bytes()).unwrap();
    od.write(0x1F9E, 0, &[0x28]).unwrap();
    let writes: Vec<_> = od.take_remote_writes().into_iter().collect();
    assert_eq!(writes, [(0x1006, 0), (0x1F9E, 0)]);
    assert!(od.take_remote_writes().is_empty());
}

#[test]
fn demo_mapping_builds_pres_and_applies_preq() {
    let mut od = cn();
    assert!(od.pres_payload().is_empty(), "no TPDO before configuration");
    assert_eq!(od.apply_preq_payload(&[1, 2, 3]), Ok(0));
    configure_demo_mapping(&mut od);
    let tpdo = od.tpdo(0).unwrap();
    assert_eq!(tpdo.mapping_index, 0x1A00);
    assert_eq!(tpdo.comm_index, 0x1800);
    assert_eq!(tpdo.version, 0);
    assert_eq!(
        tpdo.objects,
        [MappedObject {
            index: 0x6000,
            subindex: 1,
            data_type: DataType::Unsigned8,
            bit_offset: 0,
            bit_length: 8
        }]
    );
    od.set_u8(0x6000, 1, 0x5A).unwrap();
    od.set_u8(0x6000, 2, 0x77).unwrap();
    assert_eq!(od.pres_payload(), [0x5A]);
    // A 36-byte PReq payload (the payload limit) with the output byte first.
    let mut preq = [0u8; 36];
    preq[0] = 0x11;
    assert_eq!(od.apply_preq_payload(&preq), Ok(1));
    assert_eq!(od.u8(0x6200, 1), Some(0x11));
    assert_eq!(od.u8(0x6200, 2), Some(0));
    assert_eq!(od.rpdo(0).unwrap().byte_len(), 1);
    assert!(od.rpdo(5).is_none());
}

#[test]
fn mapping_entries_change_only_while_disabled() {
    let mut od = cn();
    configure_demo_mapping(&mut od);
    let v = map(0x6000, 2, 0, 8).to_le_bytes();
    assert_eq!(od.write(0x1A00, 1, &v), Err(SdoAbortCode::UnsupportedAccess));
    assert_eq!(od.write(0x1A00, 2, &v), Err(SdoAbortCode::UnsupportedAccess));
    od.write(0x1A00, 0, &[0]).unwrap();
    assert!(od.pres_payload().is_empty());
    od.write(0x1A00, 1, &v).unwrap();
    od.write(0x1A00, 0, &[1]).unwrap();
    od.set_u8(0x6000, 2, 9).unwrap();
    assert_eq!(od.pres_payload(), [9]);
}

/// Writes `entries` to TPDO or RPDO mapping `mapping` and enables them: the abort code of the
/// enabling write, if refused; a refusal leaves the mapping disabled.
fn enable(od: &mut ObjectDictionary, mapping: u16, entries: &[u64]) -> Result<(), SdoAbortCode> {
    od.write(mapping, 0, &[0]).unwrap();
    for (sub, e) in (1u8..).zip(entries) {
        od.write(mapping, sub, &e.to_le_bytes()).unwrap();
    }
    let n = u8::try_from(entries.len()).unwrap();
    let r = od.write(mapping, 0, &[n]);
    if r.is_err() {
        assert_eq!(od.u8(mapping, 0), Some(0), "a refused enable changes nothing");
        assert!(od.pdo_mapping(mapping).unwrap().is_none());
    }
    r
}

#[test]
fn invalid_mappings_are_refused_when_enabled() {
    let mut od = cn();
    use SdoAbortCode::{NotMappable, ParameterIncompatibility, PdoLengthExceeded};
    // Wrong direction, not mappable, missing, empty entry.
    assert_eq!(enable(&mut od, 0x1A00, &[map(0x6200, 1, 0, 8)]), Err(NotMappable));
    assert_eq!(enable(&mut od, 0x1600, &[map(0x6000, 1, 0, 8)]), Err(NotMappable));
    assert_eq!(enable(&mut od, 0x1A00, &[map(0x1006, 0, 0, 32)]), Err(NotMappable));
    assert_eq!(enable(&mut od, 0x1A00, &[map(0x2000, 1, 0, 8)]), Err(NotMappable));
    assert_eq!(enable(&mut od, 0x1A00, &[map(0x6000, 9, 0, 8)]), Err(NotMappable));
    assert_eq!(enable(&mut od, 0x1A00, &[map(0x6000, 1, 0, 8), 0]), Err(NotMappable));
    // Layout: length against the type, byte alignment, overlap.
    assert_eq!(enable(&mut od, 0x1A00, &[map(0x6000, 1, 0, 16)]), Err(ParameterIncompatibility));
    assert_eq!(enable(&mut od, 0x1A00, &[map(0x6000, 1, 0, 1)]), Err(ParameterIncompatibility));
    assert_eq!(enable(&mut od, 0x1A00, &[map(0x6000, 1, 4, 8)]), Err(ParameterIncompatibility));
    assert_eq!(
        enable(&mut od, 0x1A00, &[map(0x6401, 1, 0, 16), map(0x6000, 1, 8, 8)]),
        Err(ParameterIncompatibility)
    );
    // The payload limit: 0x1F98/5 (PRes) and /4 (PReq) are 36 bytes.
    assert_eq!(enable(&mut od, 0x1A00, &[map(0x6000, 1, 35 * 8, 8)]), Ok(()));
    assert_eq!(enable(&mut od, 0x1A00, &[map(0x6000, 1, 36 * 8, 8)]), Err(PdoLengthExceeded));
    assert_eq!(enable(&mut od, 0x1600, &[map(0x6412, 1, 33 * 8, 32)]), Err(PdoLengthExceeded));
    od.write(0x1F98, 4, &40u16.to_le_bytes()).unwrap();
    assert_eq!(enable(&mut od, 0x1600, &[map(0x6412, 1, 33 * 8, 32)]), Ok(()));
    // Lowering the limit under an enabled mapping is refused and changes nothing.
    assert_eq!(od.write(0x1F98, 4, &36u16.to_le_bytes()), Err(PdoLengthExceeded));
    assert_eq!(od.u16(0x1F98, 4), Some(40));
    assert_eq!(od.rpdo(0).unwrap().byte_len(), 37);
    // Only subindex 0's count of entries counts: entry 2 is ignored while the count is 1.
    od.write(0x1A00, 0, &[0]).unwrap();
    od.write(0x1A00, 1, &map(0x6000, 1, 0, 8).to_le_bytes()).unwrap();
    od.write(0x1A00, 2, &map(0x7777, 1, 0, 8).to_le_bytes()).unwrap();
    od.write(0x1A00, 0, &[1]).unwrap();
    assert_eq!(od.tpdo(0).unwrap().objects.len(), 1);
}

#[test]
fn gaps_types_and_mapping_errors() {
    let mut od = cn();
    enable(&mut od, 0x1A00, &[map(0x6401, 2, 16, 16), map(0x6000, 3, 0, 8), map(0x6402, 1, 40, 32)]).unwrap();
    od.set_i16(0x6401, 2, -2).unwrap();
    od.set_u8(0x6000, 3, 0xC3).unwrap();
    od.set_i32(0x6402, 1, 0x0102_0304).unwrap();
    assert_eq!(od.pres_payload(), [0xC3, 0, 0xFE, 0xFF, 0, 4, 3, 2, 1]);
    assert_eq!(od.i16(0x6401, 2), Some(-2));
    let err = {
        let mut od = cn();
        od.write(0x1A00, 1, &map(0x6000, 1, 0, 16).to_le_bytes()).unwrap();
        od.write(0x1A00, 0, &[1]).unwrap_err();
        od.set_u8(0x1A00, 0, 1).unwrap_err();
        // The typed error behind the abort code.
        let mut probe = od.clone();
        probe.objects.get_mut(&0x1A00).unwrap().entry_mut(0).unwrap().store(&[1]);
        probe.pdo_mapping(0x1A00).unwrap_err()
    };
    assert_eq!(
        err,
        MappingError::BadLayout {
            mapping: 0x1A00,
            subindex: 1,
            index: 0x6000,
            object_subindex: 1,
            bit_offset: 0,
            bit_length: 16
        }
    );
    assert_eq!(err.abort_code(), SdoAbortCode::ParameterIncompatibility);
    assert!(err.to_string().contains("0x6000/1"), "{err}");
}

#[test]
fn short_payload_is_refused_whole() {
    let mut od = cn();
    enable(&mut od, 0x1600, &[map(0x6200, 1, 0, 8), map(0x6200, 2, 8, 8), map(0x6411, 1, 16, 16)]).unwrap();
    assert_eq!(
        od.apply_preq_payload(&[1, 2, 3]),
        Err(PdoError::PayloadTooShort { node_id: 0, mapping: 0x1600, needed: 4, got: 3 })
    );
    assert_eq!(od.u8(0x6200, 1), Some(0), "nothing written");
    assert_eq!(od.apply_preq_payload(&[1, 2, 0x34, 0x12, 99]), Ok(3));
    assert_eq!((od.u8(0x6200, 1), od.u8(0x6200, 2), od.i16(0x6411, 1)), (Some(1), Some(2), Some(0x1234)));
}

#[test]
fn cross_traffic_and_one_channel_per_frame() {
    let mut od = cn();
    // RPDO 1 consumes node 5's PRes; its limit is 0x1F8D/5.
    od.write(0x1401, 1, &[5]).unwrap();
    od.write(0x1401, 2, &[0x10]).unwrap();
    enable(&mut od, 0x1601, &[map(0x6200, 3, 8, 8)]).unwrap();
    assert_eq!(od.rpdo(5).unwrap().version, 0x10);
    assert_eq!(od.apply_preq_payload(&[7, 7]), Ok(0));
    assert_eq!(od.apply_rpdo_payload(5, &[7, 8]), Ok(1));
    assert_eq!(od.u8(0x6200, 3), Some(8));
    assert_eq!(enable(&mut od, 0x1602, &[map(0x6411, 1, 35 * 8, 16)]), Err(SdoAbortCode::PdoLengthExceeded));
    // Two enabled channels for the same frame: the second is refused.
    enable(&mut od, 0x1600, &[map(0x6200, 1, 0, 8)]).unwrap();
    assert_eq!(enable(&mut od, 0x1602, &[map(0x6200, 2, 8, 8)]), Err(SdoAbortCode::ParameterIncompatibility));
    // Moving channel 1 onto the PReq while channel 0 has it is refused too.
    assert_eq!(od.write(0x1401, 1, &[0]), Err(SdoAbortCode::ParameterIncompatibility));
    assert_eq!(od.u8(0x1401, 1), Some(5));
}

#[test]
fn one_bit_booleans() {
    let mut od = ObjectDictionary::new();
    od.insert(
        0x2000,
        Object::var(Entry::boolean("SafeToRun", Access::ReadOnly, false).pdo(PdoMappable::Both)),
    );
    od.insert(0x2001, Object::var(Entry::boolean("Enable", Access::ReadWrite, false).pdo(PdoMappable::Both)));
    od.insert(0x1800, Object::record("TPDO", [Entry::unsigned8("NodeID_U8", Access::ReadWrite, 0)]));
    od.insert(0x1400, Object::record("RPDO", [Entry::unsigned8("NodeID_U8", Access::ReadWrite, 0)]));
    for i in [0x1600, 0x1A00] {
        od.insert(
            i,
            Object::array("M", 2, Entry::unsigned64("ObjectMapping", Access::ReadWrite, 0))
                .number_of_entries(Access::ReadWrite, 0),
        );
    }
    enable(&mut od, 0x1A00, &[map(0x2000, 0, 3, 1)]).unwrap();
    enable(&mut od, 0x1600, &[map(0x2001, 0, 9, 1)]).unwrap();
    assert_eq!(od.pres_payload(), [0]);
    od.set_bool(0x2000, 0, true).unwrap();
    assert_eq!(od.pres_payload(), [0b1000]);
    assert_eq!(od.apply_preq_payload(&[0xFF, 0b10]), Ok(1));
    assert_eq!(od.bool(0x2001, 0), Some(true));
    assert_eq!(od.apply_preq_payload(&[0xFF, 0b01]), Ok(1));
    assert_eq!(od.bool(0x2001, 0), Some(false));
}

#[test]
fn restoring_defaults_resets_the_configuration() {
    let mut od = cn();
    configure_demo_mapping(&mut od);
    od.write(0x1006, 0, &50_000u32.to_le_bytes()).unwrap();
    od.apply_preq_payload(&[0x42]).unwrap();
    od.restore_defaults(0x1000..=0x1FFF);
    assert_eq!(od.u32(0x1006, 0), Some(1000));
    assert_eq!(od.u8(0x1600, 0), Some(0));
    assert_eq!(od.u64(0x1600, 1), Some(0));
    assert!(od.tpdo(0).is_none() && od.rpdo(0).is_none());
    assert_eq!(od.u8(0x6200, 1), Some(0x42), "the device profile area is kept");
    od.restore_defaults(0x0000..=0xFFFF);
    assert_eq!(od.u8(0x6200, 1), Some(0));
    assert_eq!(od.u8(0x1F93, 1), Some(1));
}

#[test]
fn typed_getters_check_the_size() {
    let od = cn();
    assert_eq!(od.u16(0x1006, 0), None);
    assert_eq!(od.u32(0x1F98, 4), None);
    assert_eq!(od.u8(0x9999, 0), None);
    assert_eq!(od.i32(0x6402, 1), Some(0));
    assert_eq!(od.f32(0x1006, 0), Some(f32::from_le_bytes(1000u32.to_le_bytes())));
    assert_eq!(od.i64(0x1600, 1), Some(0));
    assert_eq!(od.i8(0x6400, 1), Some(0));
    assert_eq!(od.visible_string(0x1008, 0), Some("Motus POWERLINK CN"));
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    /// A write to one of the objects that PDO mapping depends on, with a value that is often
    /// a plausible mapping entry.
    fn write() -> impl Strategy<Value = (u16, u8, Vec<u8>)> {
        let index = prop::sample::select(vec![
            0x1600u16, 0x1600, 0x1A00, 0x1A00, 0x1601, 0x1401, 0x1800, 0x1F98, 0x1F8D, 0x6000, 0x6200,
        ]);
        // (object, length): mostly the right length for the type, some wrong ones.
        let mapped = prop::sample::select(vec![
            (0x6000u16, 8u16),
            (0x6000, 8),
            (0x6200, 8),
            (0x6401, 16),
            (0x6411, 16),
            (0x6402, 32),
            (0x1006, 32),
            (0x6000, 16),
            (0x6200, 1),
        ]);
        let entry =
            (mapped, 1u8..=2, 0u16..=40, prop::bool::weighted(0.1)).prop_map(|((i, bits), s, byte, odd)| {
                map(i, s, byte * 8 + u16::from(odd), bits).to_le_bytes().to_vec()
            });
        let value = prop_oneof![
            3 => (0u8..=2).prop_map(|v| vec![v]),
            3 => entry,
            1 => (30u16..=60).prop_map(|v| v.to_le_bytes().to_vec()),
            1 => prop::collection::vec(any::<u8>(), 0..9),
        ];
        (index, 0u8..=2, value)
    }

    proptest! {
        #[test]
        fn enabled_mappings_stay_valid(writes in prop::collection::vec(write(), 1..80),
                                       preq in prop::collection::vec(any::<u8>(), 0..40)) {
            let mut od = cn();
            for (index, sub, value) in writes {
                let before = od.value(index, sub).map(<[u8]>::to_vec);
                match od.write(index, sub, &value) {
                    Ok(()) => prop_assert_eq!(od.value(index, sub), Some(&value[..])),
                    Err(_) => prop_assert_eq!(od.value(index, sub).map(<[u8]>::to_vec), before),
                }
                for m in [0x1600, 0x1601, 0x1602, 0x1A00] {
                    prop_assert!(od.pdo_mapping(m).is_ok(), "{:#06x}: {:?}", m, od.pdo_mapping(m));
                }
                let pres = od.pres_payload();
                prop_assert!(pres.len() <= usize::from(od.u16(0x1F98, 5).unwrap()));
                prop_assert_eq!(pres.len(), od.tpdo(0).map_or(0, PdoMapping::byte_len));
                let _ = od.apply_preq_payload(&preq);
            }
        }
    }
}
