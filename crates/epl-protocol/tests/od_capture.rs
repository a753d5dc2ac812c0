//! The object dictionary of a Motus CN against the real openPOWERLINK traffic of
//! `shared/fixtures/powerlink/` (copied into tests/data/): every SDO write the openPOWERLINK
//! MN sends to node 1 while configuring it gets the answer the openPOWERLINK CN gave
//! (accepted, or the same abort code), and once configured the dictionary builds the PRes
//! payload and takes the PReq payload as the captured frames carry them.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::collections::BTreeMap;
use std::fs::File;

use motus_epl_protocol::{
    Asnd, DeviceIdentity, EplFrame, Message, NmtState, ObjectAccess, ObjectDictionary, SdoAbortCode,
    SdoCommandId, ETHERTYPE_EPL,
};
use pcap_file::pcapng::{Block, PcapNgReader};

/// The decoded POWERLINK frames of a capture, with their 1-based frame numbers (as tshark
/// counts them).
fn frames(name: &str) -> Vec<(usize, EplFrame)> {
    let path = format!("{}/tests/data/{name}", env!("CARGO_MANIFEST_DIR"));
    let mut reader = PcapNgReader::new(File::open(&path).unwrap()).unwrap();
    let mut out = Vec::new();
    let mut number = 0;
    while let Some(block) = reader.next_block() {
        if let Block::EnhancedPacket(epb) = block.unwrap() {
            number += 1;
            let data = &epb.data;
            if data.len() >= 14 && u16::from_be_bytes([data[12], data[13]]) == ETHERTYPE_EPL {
                out.push((number, EplFrame::decode(data).unwrap()));
            }
        }
    }
    out
}

/// What the replay saw: (request frame, index, subindex, our answer, the CN's answer).
type Outcome = (usize, u16, u8, Result<(), SdoAbortCode>, Result<(), u32>);

/// Applies every SDO WriteByIndex from the MN to node 1 to `od`, pairing it with the CN's
/// response (same transaction ID; the CN's sequence-layer repeats of a response are skipped).
fn replay_sdo(name: &str, od: &mut ObjectDictionary) -> Vec<Outcome> {
    let mut pending: BTreeMap<u8, (usize, u16, u8, Result<(), SdoAbortCode>)> = BTreeMap::new();
    let mut outcomes = Vec::new();
    for (number, frame) in frames(name) {
        let Message::Asnd(Asnd::Sdo(sdo)) = &frame.message else { continue };
        let Some(cmd) = &sdo.command else { continue };
        if frame.src_node == 240 && frame.dst_node == 1 {
            if let Some((index, sub, value)) = cmd.by_index() {
                assert_eq!(cmd.command_id, SdoCommandId::WriteByIndex, "frame {number}");
                let ours = od.write(index, sub, value);
                pending.insert(cmd.transaction_id, (number, index, sub, ours));
            }
        } else if frame.src_node == 1 && frame.dst_node == 240 && cmd.response {
            if let Some((number, index, sub, ours)) = pending.remove(&cmd.transaction_id) {
                let theirs = cmd.abort_code().map_or(Ok(()), Err);
                outcomes.push((number, index, sub, ours, theirs));
            }
        }
    }
    assert!(pending.is_empty(), "{name}: requests without a response: {pending:?}");
    outcomes
}

fn check_capture(name: &str, first_write: usize) {
    let mut od = ObjectDictionary::controlled_node(1, &DeviceIdentity::default());
    let outcomes = replay_sdo(name, &mut od);
    // The MN's configuration of node 1: 0x1011/1 "load" (refused), the 14 entries of
    // demo_3cn_50ms.txt's 0x1F22/1, 0x1010/1 "save" (refused), 0x1006 again.
    assert_eq!(outcomes.len(), 17, "{name}: {outcomes:#?}");
    assert_eq!(outcomes[0].0, first_write, "{name}");
    for (number, index, sub, ours, theirs) in &outcomes {
        assert_eq!(
            ours.map_err(SdoAbortCode::raw),
            *theirs,
            "{name} frame {number}: write {index:#06x}/{sub}: ours {ours:?}, openPOWERLINK CN {theirs:x?}"
        );
    }
    let refused: Vec<_> = outcomes.iter().filter(|o| o.4.is_err()).map(|o| (o.1, o.2, o.4)).collect();
    assert_eq!(refused, [(0x1011, 1, Err(0x0602_0000)), (0x1010, 1, Err(0x0602_0000))], "{name}");

    assert_eq!(od.u32(0x1006, 0), Some(50_000), "{name}");
    assert_eq!(od.u32(0x1C14, 0), Some(50_000_000), "{name}");
    assert_eq!(od.tpdo(0).unwrap().objects.len(), 1);
    assert_eq!(od.rpdo(0).unwrap().objects.len(), 1);

    // Process data: every PRes of node 1 in OPERATIONAL carries what our dictionary builds
    // from the same input value, and every PReq to node 1 lands in 0x6200/1.
    let (mut pres_seen, mut preq_seen) = (0, 0);
    for (number, frame) in frames(name) {
        match &frame.message {
            Message::PRes(pres) if frame.src_node == 1 && pres.nmt_state == NmtState::Operational => {
                od.set_u8(0x6000, 1, pres.payload[0]).unwrap();
                assert_eq!(od.pres_payload(), pres.payload, "{name} frame {number}");
                pres_seen += 1;
            }
            Message::PReq(preq) if frame.dst_node == 1 && !preq.payload.is_empty() => {
                assert_eq!(od.apply_preq_payload(&preq.payload), Ok(1), "{name} frame {number}");
                assert_eq!(od.u8(0x6200, 1), Some(preq.payload[0]), "{name} frame {number}");
                preq_seen += 1;
            }
            _ => {}
        }
    }
    assert!(pres_seen > 100 && preq_seen > 100, "{name}: {pres_seen} PRes, {preq_seen} PReq");
}

#[test]
fn monitor_capture_configuration_is_accepted_like_openpowerlink() {
    check_capture("oplk_mn_cn_bridge_monitor.pcapng", 929);
}

#[test]
fn veth_capture_configuration_is_accepted_like_openpowerlink() {
    check_capture("oplk_mn_cn_veth_merged.pcapng", 936);
}
