//! Property tests: typed round trips `decode(encode(f)) == f` for every frame type, lossless
//! `encode(decode(x)) == x` on structured random bytes, JSON round trips, and a decoder that
//! never panics on arbitrary bytes.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_epl_protocol::*;
use proptest::prelude::*;

fn mac() -> impl Strategy<Value = MacAddr> {
    any::<[u8; 6]>().prop_map(MacAddr)
}
fn flags() -> impl Strategy<Value = Flags> {
    any::<u8>().prop_map(Flags::from_bits_retain)
}
fn pr_rs() -> impl Strategy<Value = PrRs> {
    any::<u8>().prop_map(PrRs::from_raw)
}
fn state() -> impl Strategy<Value = NmtState> {
    any::<u8>().prop_map(NmtState::from_raw)
}
/// Bytes without trailing zeros (fields whose end is implied by the last non-zero byte).
fn trimmed(max: usize) -> impl Strategy<Value = Vec<u8>> {
    proptest::collection::vec(any::<u8>(), 0..=max).prop_map(|mut v| {
        while v.last() == Some(&0) {
            v.pop();
        }
        v
    })
}
fn net_time() -> impl Strategy<Value = NetTime> {
    (any::<u32>(), any::<u32>()).prop_map(|(seconds, nanoseconds)| NetTime { seconds, nanoseconds })
}

fn soc() -> impl Strategy<Value = Message> {
    (flags(), net_time(), any::<u64>(), any::<u8>(), any::<u8>()).prop_map(
        |(flags, net_time, relative_time, reserved1, reserved2)| {
            Message::Soc(Soc { flags, net_time, relative_time, reserved1, reserved2 })
        },
    )
}
fn preq() -> impl Strategy<Value = Message> {
    (
        flags(),
        any::<u8>(),
        proptest::collection::vec(any::<u8>(), 0..80),
        any::<u8>(),
        any::<u8>(),
        any::<u8>(),
    )
        .prop_map(|(flags, pdo_version, payload, flags2, reserved1, reserved2)| {
            Message::PReq(PReq { flags, pdo_version, payload, flags2, reserved1, reserved2 })
        })
}
fn pres() -> impl Strategy<Value = Message> {
    (state(), flags(), pr_rs(), any::<u8>(), proptest::collection::vec(any::<u8>(), 0..80), any::<u8>())
        .prop_map(|(nmt_state, flags, pr_rs, pdo_version, payload, reserved)| {
            Message::PRes(PRes { nmt_state, flags, pr_rs, pdo_version, payload, reserved })
        })
}
fn soa() -> impl Strategy<Value = Message> {
    let sync = (any::<[u32; 6]>(), mac()).prop_map(|(v, dest_mac)| SyncRequest {
        sync_control: v[0],
        pres_time_first: v[1],
        pres_time_second: v[2],
        sync_mn_delay_first: v[3],
        sync_mn_delay_second: v[4],
        pres_fallback_timeout: v[5],
        dest_mac,
    });
    (state(), flags(), any::<u8>(), any::<u8>(), any::<u8>(), any::<u8>(), any::<u8>(), sync).prop_map(
        |(nmt_state, flags, svid, target, epl_version, flags3, reserved, sync)| {
            let requested_service = RequestedService::from_raw(svid);
            // The sync area is decoded for SyncRequest or when it is not all zero.
            let keep = requested_service == RequestedService::SyncRequest || sync != SyncRequest::default();
            Message::Soa(Soa {
                nmt_state,
                flags,
                requested_service,
                target,
                epl_version,
                flags3,
                sync_request: keep.then_some(sync),
                reserved,
            })
        },
    )
}
fn ident() -> impl Strategy<Value = Asnd> {
    (
        (flags(), pr_rs(), state(), any::<u8>(), any::<u32>(), any::<[u16; 3]>(), any::<u32>()),
        (any::<[u32; 5]>(), any::<[u8; 8]>(), any::<[u32; 4]>(), any::<[u32; 3]>()),
        ("[a-z0-9-]{0,32}", trimmed(48), any::<u8>(), any::<u8>(), any::<u16>()),
    )
        .prop_map(
            |(
                (flags, pr_rs, nmt_state, epl_version, feature_flags, sizes, response_time),
                (ids, vendor_ext1, dates, ips),
                (host, vendor_ext2, r1, r2, r3),
            )| {
                Asnd::IdentResponse(IdentResponse {
                    flags,
                    pr_rs,
                    nmt_state,
                    epl_version,
                    feature_flags,
                    mtu: sizes[0],
                    poll_in_size: sizes[1],
                    poll_out_size: sizes[2],
                    response_time,
                    device_type: ids[0],
                    vendor_id: ids[1],
                    product_code: ids[2],
                    revision_number: ids[3],
                    serial_number: ids[4],
                    vendor_ext1,
                    verify_conf_date: dates[0],
                    verify_conf_time: dates[1],
                    app_sw_date: dates[2],
                    app_sw_time: dates[3],
                    ip_address: ips[0].into(),
                    subnet_mask: ips[1].into(),
                    default_gateway: ips[2].into(),
                    host_name: FixedText::Text(host),
                    vendor_ext2,
                    reserved1: r1,
                    reserved2: r2,
                    reserved3: r3,
                })
            },
        )
}
fn status() -> impl Strategy<Value = Asnd> {
    let entry = (any::<u16>(), any::<u16>(), net_time(), any::<u64>())
        .prop_map(|(entry_type, code, time, info)| StatusEntry { entry_type, code, time, info });
    (flags(), pr_rs(), state(), any::<[u8; 8]>(), proptest::collection::vec(entry, 0..4), any::<[u8; 3]>())
        .prop_map(|(flags, pr_rs, nmt_state, static_errors, mut entries, reserved)| {
            while entries.last() == Some(&StatusEntry::default()) {
                entries.pop();
            }
            Asnd::StatusResponse(StatusResponse { flags, pr_rs, nmt_state, static_errors, entries, reserved })
        })
}
fn sdo() -> impl Strategy<Value = Asnd> {
    (
        any::<[u8; 4]>(),
        any::<u16>(),
        any::<[u8; 5]>(),
        proptest::collection::vec(any::<u8>(), 0..60),
        any::<u16>(),
    )
        .prop_map(|(s, reserved, c, data, reserved2)| {
            Asnd::Sdo(SdoFrame {
                receive_sequence: s[0] & 0x3f,
                receive_con: s[1] & 3,
                send_sequence: s[2] & 0x3f,
                send_con: s[3] & 3,
                reserved,
                command: Some(SdoCommand {
                    transaction_id: c[0],
                    response: c[1] & 0x80 != 0,
                    abort: c[1] & 0x40 != 0,
                    segmentation: (c[1] >> 4) & 3,
                    flags_reserved: (c[1] >> 2) & 3,
                    pad_size: c[1] & 3,
                    command_id: SdoCommandId::from_raw(c[2]),
                    segment_size: u16::try_from(data.len()).unwrap(),
                    data,
                    reserved1: c[3],
                    reserved2,
                }),
            })
        })
}
fn asnd() -> impl Strategy<Value = Message> {
    prop_oneof![
        ident(),
        status(),
        sdo(),
        (any::<u8>(), any::<u8>(), trimmed(32)).prop_map(|(c, target, data)| Asnd::NmtRequest(NmtRequest {
            command: NmtCommandId::from_raw(c),
            target,
            data
        })),
        (any::<u8>(), any::<u8>(), trimmed(32)).prop_map(|(c, reserved, data)| Asnd::NmtCommand(
            NmtCommand { command: NmtCommandId::from_raw(c), data, reserved }
        )),
        (6u8..=255, trimmed(100)).prop_map(|(service_id, data)| Asnd::Other { service_id, data }),
    ]
    .prop_map(Message::Asnd)
}
fn message() -> impl Strategy<Value = Message> {
    prop_oneof![
        soc(),
        preq(),
        pres(),
        soa(),
        asnd(),
        trimmed(40).prop_map(|data| Message::Amni { data }),
        trimmed(40).prop_map(|data| Message::Ainv { data })
    ]
}
fn epl_frame() -> impl Strategy<Value = EplFrame> {
    (mac(), mac(), proptest::option::of(any::<u16>()), any::<u8>(), any::<u8>(), message(), 0u8..=1).prop_map(
        |(dst, src, vlan_tci, dst_node, src_node, message, bit7)| EplFrame {
            ethernet: EthernetHeader { dst, src, vlan_tci },
            dst_node,
            src_node,
            message,
            padding: Padding::Auto,
            message_type_bit7: bit7,
        },
    )
}

/// Structured random frames: a valid header and message type, random body.
fn structured_bytes() -> impl Strategy<Value = Vec<u8>> {
    (
        any::<bool>(),
        prop::sample::select(vec![1u8, 3, 4, 5, 6, 7, 0x0d, 0x86, 0x84]),
        prop::sample::select(vec![1u8, 2, 3, 4, 5, 6, 0xa0]),
        proptest::collection::vec(any::<u8>(), 0..220),
        any::<u8>(),
    )
        .prop_map(|(vlan, mtyp, svid, mut body, size)| {
            let mut v = vec![1, 0x11, 0x1e, 0, 0, 2, 2, 0, 0, 0, 0, 1];
            if vlan {
                v.extend_from_slice(&[0x81, 0x00, 0x00, 0x07]);
            }
            v.extend_from_slice(&[0x88, 0xab, mtyp, 0xff, 0x01]);
            if mtyp & 0x7f == 6 {
                body.insert(0, svid);
            }
            if matches!(mtyp & 0x7f, 3 | 4) && body.len() >= 7 {
                // a payload size that fits the body
                let max = body.len() - 7;
                let s = usize::from(size) % (max + 1);
                body[5..7].copy_from_slice(&u16::try_from(s).unwrap().to_le_bytes());
            }
            v.extend_from_slice(&body);
            v
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn typed_round_trip(f in epl_frame()) {
        let bytes = f.encode().unwrap();
        prop_assert!(bytes.len() >= 60);
        let back = EplFrame::decode(&bytes).unwrap();
        prop_assert_eq!(&back, &f);
        let json = serde_json::to_string(&f).unwrap();
        let from_json: EplFrame = serde_json::from_str(&json).unwrap();
        prop_assert_eq!(from_json, f);
    }

    #[test]
    fn bytes_round_trip(bytes in structured_bytes()) {
        if let Ok(f) = EplFrame::decode(&bytes) {
            prop_assert_eq!(f.encode().unwrap(), bytes.clone());
            let json = serde_json::to_string(&f).unwrap();
            let from_json: EplFrame = serde_json::from_str(&json).unwrap();
            prop_assert_eq!(from_json.encode().unwrap(), bytes);
        }
    }

    #[test]
    fn long_enough_frames_decode(bytes in structured_bytes()) {
        // Every frame type decodes once the frame holds its minimum (176 bytes covers all).
        let epl_len = bytes.len() - if bytes[12] == 0x81 { 18 } else { 14 };
        if epl_len >= 162 {
            prop_assert!(EplFrame::decode(&bytes).is_ok(), "{:02x?}", bytes);
        }
    }

    #[test]
    fn decode_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
        if let Ok(f) = EplFrame::decode(&bytes) {
            prop_assert_eq!(f.encode().unwrap(), bytes);
        }
    }

    #[test]
    fn decode_never_panics_epl_prefix(body in proptest::collection::vec(any::<u8>(), 0..200)) {
        let mut bytes = vec![0u8; 12];
        bytes.extend_from_slice(&[0x88, 0xab]);
        bytes.extend_from_slice(&body);
        if let Ok(f) = EplFrame::decode(&bytes) {
            prop_assert_eq!(f.encode().unwrap(), bytes);
        }
    }
}
