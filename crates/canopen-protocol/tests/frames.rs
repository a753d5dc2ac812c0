//! Frame vectors computed by hand from CiA 301 (§ cited per test; layouts as in
//! /work/shared/specs/canopen.md part 3, which follows the standard) and CiA 305 (LSS),
//! plus proptest round trips and never-panic checks.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use motus_canopen_protocol::{
    CanFrame, CanOpenMessage as M, EmcyClass, LssIdentityField, LssRequest, LssResponse, NmtCommand,
    NmtState, PdoKind, SdoAbortCode, SdoPayload, SdoRequest, SdoResponse,
};
use proptest::prelude::*;

fn dec(s: &str) -> M {
    let frame: CanFrame = s.parse().expect("candump");
    assert_eq!(frame.to_string(), s, "candump round trip");
    let msg = M::decode(&frame);
    assert_eq!(msg.encode().unwrap(), frame, "encode(decode(x)) == x");
    let json = serde_json::to_string(&msg).unwrap();
    let back: M = serde_json::from_str(&json).unwrap();
    assert_eq!(back, msg, "JSON round trip: {json}");
    msg
}

/// CiA 301 §7.2.8.3.1: NMT module control, COB-ID 0, byte 0 = cs, byte 1 = node (0 = all).
#[test]
fn nmt() {
    // 01 = start, 03 = node 3
    assert_eq!(dec("000#0103"), M::Nmt { command: NmtCommand::Start, node: 3 });
    // 82 = reset communication, 00 = all nodes
    let m = dec("000#8200");
    assert_eq!(m, M::Nmt { command: NmtCommand::ResetCommunication, node: 0 });
    assert_eq!(m.to_string(), "NMT reset communication (all nodes)");
    // unknown command specifier kept typed with its raw value
    assert_eq!(dec("000#1003"), M::Nmt { command: NmtCommand::Unknown(0x10), node: 3 });
    assert_eq!(dec("000#1003").to_string(), "NMT unknown (0x10) (node 3)");
    // wrong length: raw
    assert!(matches!(dec("000#01"), M::Raw { .. }));
}

/// CiA 301 §7.2.5: SYNC, COB-ID 0x080, DLC 0 or a 1-byte counter.
#[test]
fn sync() {
    assert_eq!(dec("080#"), M::Sync { counter: None });
    assert_eq!(dec("080#05"), M::Sync { counter: Some(5) });
}

/// CiA 301 §7.2.7: EMCY 0x080 + node; bytes 0–1 code LE, 2 error register, 3–7 manufacturer.
#[test]
fn emcy() {
    // 10 81 = 0x8110 CAN overrun, 11 = register (generic + communication), 01..05 manufacturer
    let m = dec("083#1081110102030405");
    assert_eq!(m, M::Emcy { node: 3, code: 0x8110, register: 0x11, manufacturer: [1, 2, 3, 4, 5] });
    assert_eq!(EmcyClass::of(0x8110), EmcyClass::Communication);
    assert_eq!(EmcyClass::of(0x2310), EmcyClass::Current);
    assert_eq!(EmcyClass::of(0xA000), EmcyClass::Unknown);
    assert_eq!(m.to_string(), "EMCY 0x8110 (communication) register 0x11 data 01 02 03 04 05 (node 3)");
    assert!(matches!(dec("083#1081"), M::Raw { .. })); // EMCY must be 8 bytes
}

/// CiA 301 §7.3.3 predefined connection set: TPDO1 0x180 + node, RPDO4 0x500 + node.
#[test]
fn pdo() {
    assert_eq!(
        dec("183#2706E8030000"),
        M::Pdo { kind: PdoKind::Tpdo, number: 1, node: 3, data: vec![0x27, 0x06, 0xE8, 0x03, 0, 0] }
    );
    assert_eq!(dec("57F#"), M::Pdo { kind: PdoKind::Rpdo, number: 4, node: 127, data: vec![] });
}

/// CiA 301 §7.2.4.3: SDO. Seed correction: the read reply comes on 0x580 + id with 0x43
/// (expedited, size indicated, n = 0 → 4 bytes).
#[test]
fn sdo_expedited() {
    // 40 = initiate upload, 64 60 = index 0x6064 LE, 00 = sub
    let m = dec("603#4064600000000000");
    assert_eq!(m, M::SdoRequest { node: 3, sdo: SdoRequest::InitiateUpload { index: 0x6064, subindex: 0 } });
    assert_eq!(m.to_string(), "SDO upload request 0x6064:00 (node 3)");
    // 43 = upload response e=1 s=1 n=0; E8 03 00 00 = 1000 LE
    let m = dec("583#43646000E8030000");
    assert_eq!(
        m,
        M::SdoResponse {
            node: 3,
            sdo: SdoResponse::InitiateUpload {
                index: 0x6064,
                subindex: 0,
                payload: SdoPayload::Expedited { data: vec![0xE8, 0x03, 0, 0] }
            }
        }
    );
    assert_eq!(m.to_string(), "SDO upload response 0x6064:00 = 1000 (node 3)");
    // 2B = download request e=1 s=1 n=2 (2 bytes); 40 60 = 0x6040; 06 00 = shutdown
    let m = dec("602#2B40600006000000");
    assert_eq!(
        m,
        M::SdoRequest {
            node: 2,
            sdo: SdoRequest::InitiateDownload {
                index: 0x6040,
                subindex: 0,
                payload: SdoPayload::Expedited { data: vec![6, 0] }
            }
        }
    );
    assert_eq!(m.to_string(), "SDO download request 0x6040:00 = 6 (node 2)");
    // 60 = initiate download response
    assert_eq!(
        dec("582#6040600000000000"),
        M::SdoResponse { node: 2, sdo: SdoResponse::InitiateDownload { index: 0x6040, subindex: 0 } }
    );
    // 4F = 1 byte expedited but byte 5 non-zero: not a canonical frame, kept raw
    assert!(matches!(dec("583#4F646000E8FF0000"), M::Raw { .. }));
}

/// CiA 301 §7.2.4.3: segmented transfer and abort.
#[test]
fn sdo_segmented_and_abort() {
    // 41 = upload response, segmented, size indicated; 0A 00 00 00 = 10 bytes
    assert_eq!(
        dec("581#410810000A000000"),
        M::SdoResponse {
            node: 1,
            sdo: SdoResponse::InitiateUpload {
                index: 0x1008,
                subindex: 0,
                payload: SdoPayload::Segmented { size: Some(10) }
            }
        }
    );
    // 60 = upload segment request t=0; 70 = t=1
    assert_eq!(
        dec("601#7000000000000000"),
        M::SdoRequest { node: 1, sdo: SdoRequest::UploadSegment { toggle: true } }
    );
    // 1B = 000 1 101 1: t=1, n=5 (2 data bytes), c=1 last
    assert_eq!(
        dec("581#1B41420000000000"),
        M::SdoResponse {
            node: 1,
            sdo: SdoResponse::UploadSegment { toggle: true, last: true, data: vec![0x41, 0x42] }
        }
    );
    // 80 = abort; 02 00 01 06 = 0x06010002 attempt to write a read-only object
    let m = dec("583#8041600002000106");
    assert_eq!(
        m,
        M::SdoResponse {
            node: 3,
            sdo: SdoResponse::Abort { index: 0x6041, subindex: 0, code: SdoAbortCode::ReadOnly }
        }
    );
    assert_eq!(m.to_string(), "SDO abort 0x6041:00 0x06010002 attempt to write a read-only object (node 3)");
    assert_eq!(SdoAbortCode::from_raw(0x1234_5678), SdoAbortCode::Unknown(0x1234_5678));
    // an abort code outside the table: the raw value is printed once
    assert_eq!(dec("583#8041600078563412").to_string(), "SDO abort 0x6041:00 0x12345678 unknown (node 3)");
    // block download (ccs 6) is not decoded
    assert!(matches!(dec("601#C600100000000000"), M::Raw { .. }));
}

/// CiA 301 §7.2.8.3.2: heartbeat / boot-up, 0x700 + node, 1 byte state.
#[test]
fn heartbeat() {
    let m = dec("702#00");
    assert_eq!(m, M::Heartbeat { node: 2, state: NmtState::BootUp });
    assert_eq!(m.to_string(), "boot-up (node 2)");
    assert_eq!(dec("703#05").to_string(), "heartbeat operational (node 3)");
    assert_eq!(dec("703#7F"), M::Heartbeat { node: 3, state: NmtState::PreOperational });
    assert_eq!(dec("703#04"), M::Heartbeat { node: 3, state: NmtState::Stopped });
    // RTR node guarding request stays raw
    assert!(matches!(dec("701#R"), M::Raw { .. }));
}

/// CiA 305 LSS (8-byte frames, unused bytes 0); the seed's IclA set-node-id sequence.
#[test]
fn lss() {
    assert_eq!(
        dec("7E5#0401000000000000"),
        M::LssRequest { lss: LssRequest::SwitchStateGlobal { configuration: true } }
    );
    assert_eq!(
        dec("7E5#1102000000000000"),
        M::LssRequest { lss: LssRequest::ConfigureNodeId { node_id: 2 } }
    );
    assert_eq!(
        dec("7E5#1300070000000000"),
        M::LssRequest { lss: LssRequest::ConfigureBitTiming { table: 0, index: 7 } }
    );
    // E8 03 = 1000 ms LE
    assert_eq!(
        dec("7E5#15E8030000000000"),
        M::LssRequest { lss: LssRequest::ActivateBitTiming { delay_ms: 1000 } }
    );
    assert_eq!(dec("7E5#1700000000000000"), M::LssRequest { lss: LssRequest::StoreConfiguration });
    assert_eq!(
        dec("7E4#1700000000000000"),
        M::LssResponse { lss: LssResponse::StoreConfiguration { error: 0, spec_error: 0 } }
    );
    // 40 = switch selective vendor, 78 56 34 12 = 0x12345678
    assert_eq!(
        dec("7E5#4078563412000000"),
        M::LssRequest {
            lss: LssRequest::SwitchStateSelective { field: LssIdentityField::Vendor, value: 0x1234_5678 }
        }
    );
    assert_eq!(
        dec("7E4#5E02000000000000"),
        M::LssResponse { lss: LssResponse::InquireNodeId { node_id: 2 } }
    );
    assert_eq!(
        dec("7E5#5100000000801F00"),
        M::LssRequest {
            lss: LssRequest::Fastscan { id_number: 0, bit_check: 0x80, lss_sub: 0x1F, lss_next: 0 }
        }
    );
    assert_eq!(dec("7E5#1102000000000000").to_string(), "LSS request: configure node-ID 2");
    // the seed prints short frames ("04 01"); CiA 305 frames are 8 bytes, so keep raw
    assert!(matches!(dec("7E5#0401"), M::Raw { .. }));
}

#[test]
fn raw_and_json() {
    assert!(matches!(dec("100#0102030405"), M::Raw { .. })); // TIME not decoded
    assert!(matches!(dec("12345678#00"), M::Raw { .. }));
    let json = serde_json::to_string(&dec("583#43646000E8030000")).unwrap();
    assert_eq!(
        json,
        r#"{"type":"sdo_response","node":3,"sdo":{"command":"initiate_upload","index":24676,"subindex":0,"payload":{"transfer":"expedited","data":[232,3,0,0]}}}"#
    );
    let m: M = serde_json::from_str(r#"{"type":"nmt","command":1,"node":0}"#).unwrap();
    assert_eq!(m.encode().unwrap().to_string(), "000#0100");
    let raw: M = serde_json::from_str(r#"{"type":"raw","frame":{"id":1793,"rtr":true}}"#).unwrap();
    assert_eq!(raw.encode().unwrap().to_string(), "701#R");
    // our own misuse is an encode error
    assert!(M::Heartbeat { node: 0, state: NmtState::BootUp }.encode().is_err());
    assert!(M::Pdo { kind: PdoKind::Tpdo, number: 5, node: 1, data: vec![] }.encode().is_err());
}

fn frame_strategy() -> impl Strategy<Value = CanFrame> {
    prop_oneof![
        (0u32..=0x7FF, proptest::collection::vec(any::<u8>(), 0..=8))
            .prop_map(|(id, d)| CanFrame::new(id, &d).unwrap()),
        // bias towards the SDO/LSS ids with full 8-byte frames
        (prop_oneof![0x581u32..=0x5FF, 0x601u32..=0x67F, 0x7E4u32..=0x7E5], any::<[u8; 8]>())
            .prop_map(|(id, d)| CanFrame::new(id, &d).unwrap()),
        (0u32..=0x1FFF_FFFF, any::<bool>(), 0u8..=8).prop_map(|(id, ext, dlc)| CanFrame::remote(
            id & if ext { 0x1FFF_FFFF } else { 0x7FF },
            ext,
            dlc
        )
        .unwrap()),
    ]
}

proptest! {
    #[test]
    fn decode_encode_round_trip(frame in frame_strategy()) {
        let msg = M::decode(&frame);
        prop_assert_eq!(msg.encode().unwrap(), frame.clone());
        let _ = msg.to_string();
        let json = serde_json::to_string(&msg).unwrap();
        let back: M = serde_json::from_str(&json).unwrap();
        prop_assert_eq!(&back, &msg);
        prop_assert_eq!(frame.to_string().parse::<CanFrame>().unwrap(), frame);
    }

    #[test]
    fn expedited_encode_decode(node in 1u8..=127, index: u16, subindex: u8, data in proptest::collection::vec(any::<u8>(), 1..=4)) {
        let msg = M::SdoRequest { node, sdo: SdoRequest::InitiateDownload { index, subindex, payload: SdoPayload::Expedited { data } } };
        prop_assert_eq!(M::decode(&msg.encode().unwrap()), msg);
    }

    #[test]
    fn segment_encode_decode(node in 1u8..=127, toggle: bool, last: bool, data in proptest::collection::vec(any::<u8>(), 0..=7)) {
        let msg = M::SdoResponse { node, sdo: SdoResponse::UploadSegment { toggle, last, data } };
        prop_assert_eq!(M::decode(&msg.encode().unwrap()), msg);
    }
}
