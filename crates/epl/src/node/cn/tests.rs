//! Tests of the Controlled Node: the openPOWERLINK MN's frames of the real capture replayed
//! on virtual time, and every NMT command, loss, error-signalling and async-slot rule.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use std::time::{Duration, Instant};

use motus_epl_protocol::{
    Asnd, DeviceIdentity, EplFrame, Flags, MacAddr, Message, NmtCommand, NmtCommandId, NmtState,
    ObjectDictionary, PReq, RequestedService, SdoCommand, SdoCommandId, SdoFrame, Soa, Soc, StatusEntry,
    BROADCAST_NODE_ID, MN_NODE_ID,
};

use super::*;
use crate::replay::read_capture;

const MN_MAC: MacAddr = MacAddr([0xda, 0x6e, 0x4c, 0xfb, 0xb5, 0x19]);
/// The openPOWERLINK CN's MAC in the captures.
const CN_MAC: MacAddr = MacAddr([0x6a, 0x50, 0x39, 0x19, 0xf3, 0x9d]);

fn fixture(name: &str) -> String {
    format!("{}/../epl-protocol/tests/data/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn node(id: u8, now: Instant) -> ControlledNode {
    let identity = DeviceIdentity { mac_address: CN_MAC.0, ..DeviceIdentity::default() };
    ControlledNode::new(id, CN_MAC, ObjectDictionary::controlled_node(id, &identity), now).unwrap()
}

fn enc(dst_mac: MacAddr, dst: u8, m: Message) -> Vec<u8> {
    EplFrame::new(MN_MAC, dst_mac, dst, MN_NODE_ID, m).encode().unwrap()
}

fn soc() -> Vec<u8> {
    enc(MacAddr::SOC, BROADCAST_NODE_ID, Message::Soc(Soc::default()))
}

fn soa(service: RequestedService, target: u8, flags: Flags) -> Vec<u8> {
    let mut s = Soa::new(NmtState::Operational, service, target);
    s.flags = flags;
    enc(MacAddr::SOA, BROADCAST_NODE_ID, Message::Soa(s))
}

fn preq(node: u8, flags: Flags, payload: &[u8]) -> Vec<u8> {
    let p = PReq { flags, payload: payload.to_vec(), ..PReq::default() };
    enc(CN_MAC, node, Message::PReq(p))
}

fn nmt(dst: u8, command: NmtCommandId, data: &[u8]) -> Vec<u8> {
    let c = NmtCommand { command, reserved: 0, data: data.to_vec() };
    enc(MacAddr::ASND, dst, Message::Asnd(Asnd::NmtCommand(c)))
}

fn sdo(dst: u8, f: SdoFrame) -> Vec<u8> {
    enc(MacAddr::ASND, dst, Message::Asnd(Asnd::Sdo(f)))
}

fn decode(f: &[u8]) -> EplFrame {
    EplFrame::decode(f).unwrap()
}

/// Drives a node from power-on to `target` (PRE_OPERATIONAL_2 or later) with SoA, SoC and
/// NMT commands.
fn boot(cn: &mut ControlledNode, now: Instant, target: NmtState) {
    cn.on_frame(now, &soa(RequestedService::NoService, 0, Flags::empty()));
    assert_eq!(cn.state(), NmtState::PreOperational1);
    cn.on_frame(now, &soc());
    assert_eq!(cn.state(), NmtState::PreOperational2);
    if target == NmtState::PreOperational2 {
        return;
    }
    cn.on_frame(now, &nmt(cn.node_id(), NmtCommandId::EnableReadyToOperate, &[]));
    assert_eq!(cn.state(), NmtState::ReadyToOperate);
    if target == NmtState::ReadyToOperate {
        return;
    }
    cn.on_frame(now, &nmt(cn.node_id(), NmtCommandId::StartNode, &[]));
    assert_eq!(cn.state(), NmtState::Operational);
}

/// What to compare of a frame: everything but the host name and the fields of the
/// IdentResponse that describe the device itself (feature flags, MTU, names).
fn comparable(raw: &[u8]) -> EplFrame {
    let mut f = decode(raw);
    if let Message::Asnd(Asnd::IdentResponse(r)) = &mut f.message {
        r.host_name = Default::default();
        r.feature_flags = 0;
        r.mtu = 0;
        r.vendor_ext2.clear();
    }
    f
}

/// Clears the payload of a PRes when `mask` is set.
fn mask_payload(mut f: EplFrame, mask: bool) -> EplFrame {
    if let (true, Message::PRes(p)) = (mask, &mut f.message) {
        p.payload.clear();
    }
    f
}

/// The openPOWERLINK MN's frames of the merged veth capture, replayed on virtual time (the
/// capture's time stamps) into a Motus CN 1 started just before the real CN's first frame
/// (866): after every frame of the MN, the frames the Motus CN sends are those the real CN
/// sent before the MN's next frame, byte for byte (IdentResponse: apart from the fields that
/// describe the device). That covers the boot-up (IdentRequest 865 -> IdentResponse 866 in
/// PRE_OPERATIONAL_1, SoC 867 -> PRE_OPERATIONAL_2), error signalling (StatusRequest with
/// ER 881/888 -> EC=1 in 882/889; without ER 902 -> EC=1 once more in 903, then EC=0 in
/// 917), the async slot (SDO InitReq 871 queued: RS=1 PR=3 in 882 and PRes 887, sent on the
/// UnspecifiedInvite 893 as 894), the whole SDO configuration (frames 871-1409: 0x1600,
/// 0x1A00, 0x1006, 0x1020, 0x1C0B/0D/14, 0x1F98, the mappings; 0x1010/0x1011 refused with
/// "object does not exist" as 945 and 1382), and, after NMTResetConfiguration (1416) and the
/// re-identification (1451), NMTEnableReadyToOperate (1463 -> PRes 1466 READY_TO_OPERATE),
/// NMTStartNode (1496 -> PRes 1499 OPERATIONAL, RD=1, the mapped input byte).
/// PRes payloads are not compared in 1346-1415 (the Motus CN's TPDO mapping takes effect
/// when it is enabled, the real CN's at NMTResetConfiguration).
/// Window 1416-1451: the real CN took 0.8 s to reset and ignored the IdentRequest 1434 that
/// the Motus CN answers; the comparison starts again at 1452. (Later, from 1776, the real CN
/// sends again an SDO response (1409) that the MN acknowledged in 1421; the Motus CN does not.)
#[test]
fn replays_the_openpowerlink_boot_and_configuration() {
    let frames = read_capture(fixture("oplk_mn_cn_veth_merged.pcapng")).unwrap();
    let base = Instant::now();
    let at = |i: usize| base + Duration::from_nanos(frames[i].at_ns - frames[0].at_ns);
    // Frame numbers are 1-based, as tshark shows them.
    let start = 864;
    let mut cn = node(1, at(start - 1));
    let mut compared = 0;
    let mut states = vec![cn.state()];
    let mut i = start - 1;
    while i < frames.len() {
        let number = i + 1;
        let raw = &frames[i].data;
        let Ok(f) = EplFrame::decode(raw) else {
            i += 1;
            continue;
        };
        if f.src_node != MN_NODE_ID {
            i += 1;
            continue;
        }
        // The real CN's answers: its frames before the MN's next one.
        let mut real = Vec::new();
        let mut j = i + 1;
        while j < frames.len() {
            match EplFrame::decode(&frames[j].data) {
                Ok(g) if g.src_node == MN_NODE_ID => break,
                Ok(g) if g.src_node == 1 => real.push(frames[j].data.clone()),
                _ => {}
            }
            j += 1;
        }
        // The application's input follows the real CN's (its PRes payload).
        if let Some(Message::PRes(p)) = real.first().map(|r| decode(r).message) {
            if let Some(&v) = p.payload.first() {
                cn.od_mut().set_u8(0x6000, 1, v).unwrap();
            }
        }
        cn.poll(at(i));
        let ours = cn.on_frame(at(i), raw);
        // A PReq without the real CN's PRes in the capture (frame 1739): not compared.
        let unanswered_preq = real.is_empty() && matches!(f.message, Message::PReq(_));
        let compare = ((864..=1415).contains(&number) || (1452..=1737).contains(&number)) && !unanswered_preq;
        // The Motus CN's TPDO mapping is live as soon as 0x1A00/0 is written (1346), the real
        // CN's from NMTResetConfiguration on (1416): PRes payloads differ in between.
        let live_mapping = (1346..=1415).contains(&number);
        if compare {
            let ours_c: Vec<_> =
                ours.iter().map(|o| comparable(o)).map(|f| mask_payload(f, live_mapping)).collect();
            let real_c: Vec<_> =
                real.iter().map(|r| comparable(r)).map(|f| mask_payload(f, live_mapping)).collect();
            assert_eq!(ours_c, real_c, "answers to MN frame {number} ({f})");
            for (o, r) in ours.iter().zip(&real) {
                if !live_mapping && !matches!(decode(r).message, Message::Asnd(Asnd::IdentResponse(_))) {
                    assert_eq!(o, r, "bytes of the answer to MN frame {number}");
                }
            }
            compared += real.len();
        }
        if states.last() != Some(&cn.state()) {
            states.push(cn.state());
        }
        i = j;
    }
    assert!(compared >= 200, "only {compared} frames compared");
    assert_eq!(cn.state(), NmtState::Operational);
    assert_eq!(cn.od().u32(0x1006, 0), Some(50_000), "cycle length written by SDO");
    assert_eq!(cn.od().u32(0x1C14, 0), Some(50_000_000));
    assert_eq!(cn.od().u8(0x1F8C, 0), Some(NmtState::Operational.raw()));
    assert_eq!(cn.od().tpdo(0).map(|m| m.objects.len()), Some(1));
    assert_eq!(cn.counters().cycle_errors, 0);
    assert_eq!(cn.counters().loss_of_soc, 0);
    assert_eq!(
        states,
        [
            NmtState::NotActive,
            NmtState::PreOperational1,
            NmtState::PreOperational2,
            NmtState::NotActive,
            NmtState::PreOperational1,
            NmtState::PreOperational2,
            NmtState::ReadyToOperate,
            NmtState::Operational,
        ]
    );
    // The SDO writes were reported.
    let writes: Vec<(u16, u8)> = cn
        .take_events()
        .into_iter()
        .filter_map(|e| match e {
            CnEvent::SdoWrite { index, subindex, .. } => Some((index, subindex)),
            _ => None,
        })
        .collect();
    assert!(writes.contains(&(0x1006, 0)) && writes.contains(&(0x1A00, 1)), "{writes:x?}");
}

#[test]
fn power_on_runs_through_the_reset_states() {
    let now = Instant::now();
    let mut cn = node(7, now);
    assert_eq!(cn.state(), NmtState::NotActive);
    let states: Vec<NmtState> = cn
        .take_events()
        .into_iter()
        .filter_map(|e| match e {
            CnEvent::State { to, .. } => Some(to),
            _ => None,
        })
        .collect();
    assert_eq!(
        states,
        [
            NmtState::ResetApplication,
            NmtState::ResetCommunication,
            NmtState::ResetConfiguration,
            NmtState::NotActive
        ]
    );
    assert_eq!(cn.od().u8(0x1F8C, 0), Some(NmtState::NotActive.raw()));
    assert!(ControlledNode::new(0, CN_MAC, ObjectDictionary::new(), now).is_err());
    assert!(ControlledNode::new(240, CN_MAC, ObjectDictionary::new(), now).is_err());
}

#[test]
fn not_active_answers_nothing_but_leaves_on_soa_or_soc() {
    let now = Instant::now();
    let mut cn = node(1, now);
    // A PReq is not answered before PRE_OPERATIONAL_2.
    assert!(cn.on_frame(now, &preq(1, Flags::empty(), &[])).is_empty());
    assert!(cn.pres_for(&preq(1, Flags::empty(), &[])).is_none());
    let out = cn.on_frame(now, &soa(RequestedService::IdentRequest, 1, Flags::empty()));
    assert_eq!(cn.state(), NmtState::PreOperational1);
    let Message::Asnd(Asnd::IdentResponse(r)) = decode(&out[0]).message else { panic!() };
    assert_eq!(r.nmt_state, NmtState::PreOperational1);
    assert_eq!(r.ip_address, std::net::Ipv4Addr::new(192, 168, 100, 1));
    assert_eq!(r.feature_flags, motus_epl_protocol::od::MOTUS_CN_FEATURE_FLAGS);
    assert_eq!(r.response_time, 50_000);
    // Another node's IdentRequest: nothing.
    assert!(cn.on_frame(now, &soa(RequestedService::IdentRequest, 2, Flags::empty())).is_empty());
    let mut cn = node(1, now);
    cn.on_frame(now, &soc());
    assert_eq!(cn.state(), NmtState::PreOperational1);
}

#[test]
fn every_nmt_state_command() {
    let now = Instant::now();
    let mut cn = node(3, now);
    boot(&mut cn, now, NmtState::Operational);
    // PRes: RD only in OPERATIONAL.
    let pres =
        |cn: &mut ControlledNode| match decode(cn.pres_for(&preq(3, Flags::empty(), &[])).unwrap()).message {
            Message::PRes(p) => p,
            _ => panic!(),
        };
    assert!(pres(&mut cn).flags.contains(Flags::RD));
    cn.on_frame(now, &nmt(3, NmtCommandId::StopNode, &[]));
    assert_eq!(cn.state(), NmtState::Stopped);
    assert!(cn.on_frame(now, &preq(3, Flags::empty(), &[])).is_empty(), "no PRes in STOPPED");
    cn.on_frame(now, &nmt(3, NmtCommandId::StartNode, &[]));
    assert_eq!(cn.state(), NmtState::Stopped, "StartNode is for READY_TO_OPERATE only");
    cn.on_frame(now, &nmt(3, NmtCommandId::EnterPreOperational2, &[]));
    assert_eq!(cn.state(), NmtState::PreOperational2);
    assert!(!pres(&mut cn).flags.contains(Flags::RD));
    cn.on_frame(now, &nmt(3, NmtCommandId::EnableReadyToOperate, &[]));
    assert_eq!(cn.state(), NmtState::ReadyToOperate);
    assert_eq!(pres(&mut cn).nmt_state, NmtState::ReadyToOperate);
    cn.on_frame(now, &nmt(3, NmtCommandId::EnterPreOperational2, &[]));
    assert_eq!(cn.state(), NmtState::PreOperational2);
    cn.on_frame(now, &nmt(3, NmtCommandId::StopNode, &[]));
    assert_eq!(cn.state(), NmtState::Stopped);
    // Commands for other nodes are ignored, broadcast ones obeyed.
    cn.on_frame(now, &nmt(4, NmtCommandId::ResetNode, &[]));
    assert_eq!(cn.state(), NmtState::Stopped);
    for reset in [
        NmtCommandId::ResetNode,
        NmtCommandId::ResetCommunication,
        NmtCommandId::ResetConfiguration,
        NmtCommandId::SwReset,
    ] {
        cn.on_frame(now, &nmt(3, NmtCommandId::ResetConfiguration, &[]));
        boot(&mut cn, now, NmtState::Operational);
        cn.take_events();
        cn.on_frame(now, &nmt(BROADCAST_NODE_ID, reset, &[]));
        assert_eq!(cn.state(), NmtState::NotActive, "{reset}");
        let first = cn.take_events().into_iter().find_map(|e| match e {
            CnEvent::State { to, .. } => Some(to),
            _ => None,
        });
        let expected = match reset {
            NmtCommandId::SwReset => NmtState::Initialising,
            NmtCommandId::ResetNode => NmtState::ResetApplication,
            NmtCommandId::ResetCommunication => NmtState::ResetCommunication,
            _ => NmtState::ResetConfiguration,
        };
        assert_eq!(first, Some(expected), "{reset}");
    }
    // "Ex" commands: the node list names node 3 (byte 0, bit 3) or not.
    cn.on_frame(now, &nmt(3, NmtCommandId::ResetConfiguration, &[]));
    boot(&mut cn, now, NmtState::ReadyToOperate);
    cn.on_frame(now, &nmt(BROADCAST_NODE_ID, NmtCommandId::StartNodeEx, &[0x04]));
    assert_eq!(cn.state(), NmtState::ReadyToOperate);
    cn.on_frame(now, &nmt(BROADCAST_NODE_ID, NmtCommandId::StartNodeEx, &[0x08]));
    assert_eq!(cn.state(), NmtState::Operational);
}

#[test]
fn resets_restore_what_they_should() {
    let now = Instant::now();
    let mut cn = node(1, now);
    boot(&mut cn, now, NmtState::PreOperational2);
    cn.od_mut().set_u32(0x1006, 0, 2000).unwrap();
    cn.od_mut().set_u8(0x6200, 1, 9).unwrap();
    cn.on_frame(now, &nmt(1, NmtCommandId::ResetConfiguration, &[]));
    assert_eq!(cn.od().u32(0x1006, 0), Some(2000), "kept by ResetConfiguration");
    cn.on_frame(now, &nmt(1, NmtCommandId::ResetCommunication, &[]));
    assert_eq!(cn.od().u32(0x1006, 0), Some(1000), "communication profile restored");
    assert_eq!(cn.od().u8(0x6200, 1), Some(9), "application objects kept");
    cn.on_frame(now, &nmt(1, NmtCommandId::ResetNode, &[]));
    assert_eq!(cn.od().u8(0x6200, 1), Some(0), "everything restored");
}

#[test]
fn pres_carries_the_mapping_and_preq_payload_is_applied_in_operational() {
    let now = Instant::now();
    let mut cn = node(1, now);
    let od = cn.od_mut();
    od.set_u64(0x1A00, 1, 0x0008_0000_0001_6000).unwrap();
    od.set_u8(0x1A00, 0, 1).unwrap();
    od.set_u64(0x1600, 1, 0x0008_0000_0001_6200).unwrap();
    od.set_u8(0x1600, 0, 1).unwrap();
    od.set_u8(0x6000, 1, 0x5A).unwrap();
    boot(&mut cn, now, NmtState::ReadyToOperate);
    cn.on_frame(now, &preq(1, Flags::RD, &[0x33]));
    assert_eq!(cn.od().u8(0x6200, 1), Some(0), "not applied before OPERATIONAL");
    cn.on_frame(now, &nmt(1, NmtCommandId::StartNode, &[]));
    cn.on_frame(now, &preq(1, Flags::empty(), &[0x33]));
    assert_eq!(cn.od().u8(0x6200, 1), Some(0), "not applied without RD");
    let out = cn.on_frame(now, &preq(1, Flags::RD | Flags::MS, &[0x33]));
    assert_eq!(cn.od().u8(0x6200, 1), Some(0x33));
    assert_eq!(cn.counters().preq_applied, 1);
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].len(), 60);
    let Message::PRes(p) = decode(&out[0]).message else { panic!() };
    assert_eq!(p.payload, [0x5A]);
    assert!(p.flags.contains(Flags::RD) && p.flags.contains(Flags::MS));
    // The prepared PRes is the same frame (MS copied from the PReq).
    let fast = cn.pres_for(&preq(1, Flags::RD | Flags::MS, &[0x33])).unwrap().to_vec();
    assert_eq!(fast, out[0]);
    assert!(cn.on_answered_preq(now, &preq(1, Flags::RD, &[0x44])).is_empty());
    assert_eq!(cn.od().u8(0x6200, 1), Some(0x44));
    // Inputs changed by the application show in the next PRes.
    cn.od_mut().set_u8(0x6000, 1, 0x11).unwrap();
    let Message::PRes(p) = decode(cn.pres_for(&preq(1, Flags::empty(), &[])).unwrap()).message else {
        panic!()
    };
    assert_eq!(p.payload, [0x11]);
    // Not for this node, not from the MN: not a PReq to answer.
    assert!(cn.pres_for(&preq(2, Flags::empty(), &[])).is_none());
}

fn sdo_req(send: u8, recv: u8, scon: u8, rcon: u8, command: Option<SdoCommand>) -> SdoFrame {
    SdoFrame {
        receive_sequence: recv,
        receive_con: rcon,
        send_sequence: send,
        send_con: scon,
        command,
        reserved: 0,
    }
}

#[test]
fn an_answer_left_uninvited_is_announced_again() {
    let now = Instant::now();
    let mut cn = node(1, now);
    boot(&mut cn, now, NmtState::PreOperational2);
    cn.on_frame(now, &sdo(1, sdo_req(0, 0, 1, 0, None)));
    assert_eq!(cn.async_pending(), 1);
    let rs = |cn: &mut ControlledNode| {
        let Message::PRes(p) = decode(&cn.on_frame(now, &preq(1, Flags::empty(), &[]))[0]).message else {
            panic!()
        };
        p.pr_rs.rs
    };
    // REANNOUNCE_AFTER PRes say 1, the next 0 (the MN resets its count), then 1 again (it
    // queues a fresh invitation); and so on while the MN does not invite.
    let seen: Vec<u8> = (0..2 * (REANNOUNCE_AFTER + 1)).map(|_| rs(&mut cn)).collect();
    let mut expected = vec![1; REANNOUNCE_AFTER as usize];
    expected.push(0);
    expected.extend(std::iter::repeat_n(1, REANNOUNCE_AFTER as usize));
    expected.push(0);
    assert_eq!(seen, expected);
    // Invited: the answer leaves; nothing waits, RS 0 from then on.
    assert_eq!(cn.on_frame(now, &soa(RequestedService::UnspecifiedInvite, 1, Flags::empty())).len(), 1);
    assert!((0..2 * REANNOUNCE_AFTER).all(|_| rs(&mut cn) == 0));
    // A new answer: counted from zero again.
    cn.on_frame(now, &sdo(1, sdo_req(0, 0, 1, 0, None)));
    assert!((0..REANNOUNCE_AFTER).all(|_| rs(&mut cn) == 1));
}

#[test]
fn sdo_answers_wait_for_the_async_slot_announced_by_rs() {
    let now = Instant::now();
    let mut cn = node(1, now);
    boot(&mut cn, now, NmtState::PreOperational2);
    assert!(cn.on_frame(now, &sdo(1, sdo_req(0, 0, 1, 0, None))).is_empty());
    assert_eq!(cn.async_pending(), 1);
    let status = cn.on_frame(now, &soa(RequestedService::StatusRequest, 1, Flags::empty()));
    let Message::Asnd(Asnd::StatusResponse(s)) = decode(&status[0]).message else { panic!() };
    assert_eq!((s.pr_rs.rs, s.pr_rs.pr), (1, PR_GENERIC));
    let Message::PRes(p) = decode(&cn.on_frame(now, &preq(1, Flags::empty(), &[]))[0]).message else {
        panic!()
    };
    assert_eq!((p.pr_rs.rs, p.pr_rs.pr), (1, PR_GENERIC));
    // An invitation for another node, or for the MN: nothing.
    assert!(cn.on_frame(now, &soa(RequestedService::UnspecifiedInvite, 2, Flags::empty())).is_empty());
    let out = cn.on_frame(now, &soa(RequestedService::UnspecifiedInvite, 1, Flags::empty()));
    let f = decode(&out[0]);
    assert_eq!((f.src_node, f.dst_node), (1, MN_NODE_ID));
    let Message::Asnd(Asnd::Sdo(ack)) = f.message else { panic!() };
    assert_eq!((ack.receive_con, ack.send_con), (1, 1), "InitAck");
    assert_eq!(cn.async_pending(), 0);
    let Message::PRes(p) = decode(&cn.on_frame(now, &preq(1, Flags::empty(), &[]))[0]).message else {
        panic!()
    };
    assert_eq!((p.pr_rs.rs, p.pr_rs.pr), (0, 0));
    // Connection up, then an expedited write of 0x1006 and a write of 0x1F9E (reset).
    cn.on_frame(now, &sdo(1, sdo_req(0, 0, 2, 1, None)));
    let write = |tid: u8, index: u16, sub: u8, value: &[u8]| {
        let [a, b] = index.to_le_bytes();
        let mut data = vec![a, b, sub, 0];
        data.extend_from_slice(value);
        SdoCommand {
            transaction_id: tid,
            response: false,
            abort: false,
            segmentation: 0,
            pad_size: 0,
            command_id: SdoCommandId::WriteByIndex,
            segment_size: u16::try_from(data.len()).unwrap(),
            data,
            flags_reserved: 0,
            reserved1: 0,
            reserved2: 0,
        }
    };
    cn.on_frame(now, &sdo(1, sdo_req(1, 0, 2, 2, Some(write(1, 0x1006, 0, &2000u32.to_le_bytes())))));
    assert_eq!(cn.od().u32(0x1006, 0), Some(2000));
    assert!(cn.take_events().iter().any(
        |e| *e == CnEvent::SdoWrite { index: 0x1006, subindex: 0, value: 2000u32.to_le_bytes().to_vec() }
    ));
    cn.on_frame(now, &sdo(1, sdo_req(2, 0, 2, 2, Some(write(2, 0x1F9E, 0, &[0x29])))));
    assert_eq!(cn.state(), NmtState::PreOperational2, "the reset waits for the SDO answer to leave");
    while cn.async_pending() > 0 {
        assert!(!cn.on_frame(now, &soa(RequestedService::UnspecifiedInvite, 1, Flags::empty())).is_empty());
    }
    assert_eq!(cn.state(), NmtState::NotActive, "0x1F9E = ResetCommunication");
    assert_eq!(cn.od().u32(0x1006, 0), Some(1000));
}

#[test]
fn error_signalling_handshake_and_new_errors() {
    let now = Instant::now();
    let mut cn = node(1, now);
    boot(&mut cn, now, NmtState::Operational);
    let status = |cn: &mut ControlledNode, er: bool| {
        let flags = if er { Flags::ER } else { Flags::empty() };
        let out = cn.on_frame(now, &soa(RequestedService::StatusRequest, 1, flags));
        match decode(&out[0]).message {
            Message::Asnd(Asnd::StatusResponse(s)) => s,
            _ => panic!(),
        }
    };
    assert!(!status(&mut cn, false).flags.contains(Flags::EC));
    assert!(status(&mut cn, true).flags.contains(Flags::EC));
    assert!(status(&mut cn, true).flags.contains(Flags::EC));
    assert!(status(&mut cn, false).flags.contains(Flags::EC), "reported once more without ER");
    assert!(!status(&mut cn, false).flags.contains(Flags::EC));
    // A new error: EN set in PRes and StatusResponse, with the entry; EA acknowledges it.
    let entry = StatusEntry { entry_type: 0x1000, code: 0x8235, ..StatusEntry::default() };
    cn.post_error(entry);
    let s = status(&mut cn, false);
    assert!(s.flags.contains(Flags::EN));
    assert_eq!(s.entries, [entry]);
    let Message::PRes(p) = decode(&cn.on_frame(now, &preq(1, Flags::RD, &[]))[0]).message else { panic!() };
    assert!(p.flags.contains(Flags::EN));
    cn.on_frame(now, &preq(1, Flags::RD | Flags::EA, &[]));
    cn.post_error(entry);
    assert!(!status(&mut cn, false).flags.contains(Flags::EN), "toggled after the acknowledgement");
    // ER resets the signalling.
    let s = status(&mut cn, true);
    assert!(s.entries.is_empty() && s.flags.contains(Flags::EC));
}

#[test]
fn loss_of_soc_beyond_the_threshold_is_a_cycle_error() {
    let t0 = Instant::now();
    let mut cn = node(1, t0);
    // 1 ms cycle, 0.5 ms tolerance, threshold 15: the second loss in a row is an error.
    cn.od_mut().set_u32(0x1C14, 0, 500_000).unwrap();
    cn.on_frame(t0, &nmt(1, NmtCommandId::ResetConfiguration, &[]));
    boot(&mut cn, t0, NmtState::Operational);
    let ms = Duration::from_millis(1);
    let mut now = t0;
    for _ in 0..20 {
        now += ms;
        cn.poll(now);
        cn.on_frame(now, &soc());
        cn.on_frame(now, &preq(1, Flags::RD, &[]));
    }
    assert_eq!(cn.counters().loss_of_soc, 0);
    assert_eq!(cn.state(), NmtState::Operational);
    // One late SoC (2 ms gap): one loss, no error.
    now += ms * 2;
    cn.poll(now);
    assert_eq!(cn.counters().loss_of_soc, 1);
    cn.on_frame(now, &soc());
    cn.on_frame(now, &preq(1, Flags::RD, &[]));
    assert_eq!(cn.state(), NmtState::Operational);
    assert_eq!(cn.od().u32(0x1C0B, 1), Some(1));
    // The MN stops: the deadline comes, then the next one: cycle error.
    let deadline = cn.next_deadline().unwrap();
    cn.poll(deadline);
    cn.poll(deadline + ms);
    assert_eq!(cn.state(), NmtState::PreOperational1);
    assert_eq!(cn.counters().cycle_errors, 1);
    assert!(cn.take_events().contains(&CnEvent::State {
        from: NmtState::Operational,
        to: NmtState::PreOperational1,
        cause: StateCause::CycleError
    }));
    // No monitoring in PRE_OPERATIONAL_1.
    assert_eq!(cn.next_deadline(), None);
}

#[test]
fn loss_of_preq_counts_and_can_stop_the_node() {
    let t0 = Instant::now();
    let mut cn = node(1, t0);
    cn.od_mut().set_u32(0x1C0D, 3, 24).unwrap();
    boot(&mut cn, t0, NmtState::Operational);
    let mut now = t0;
    for cycle in 0..4 {
        now += Duration::from_millis(1);
        cn.on_frame(now, &soc());
        if cycle == 0 {
            cn.on_frame(now, &preq(1, Flags::RD, &[]));
        }
    }
    // Cycles 1 and 2 had no PReq (the SoC of cycles 2 and 3 notice it): 16 < 24.
    assert_eq!(cn.counters().loss_of_preq, 2);
    assert_eq!(cn.od().u32(0x1C0D, 1), Some(2));
    assert_eq!(cn.state(), NmtState::Operational);
    now += Duration::from_millis(1);
    cn.on_frame(now, &soc());
    assert_eq!(cn.state(), NmtState::PreOperational1);
}

#[test]
fn not_active_falls_back_to_basic_ethernet() {
    let t0 = Instant::now();
    let mut cn = node(1, t0);
    let deadline = cn.next_deadline().unwrap();
    assert_eq!(deadline, t0 + Duration::from_secs(5));
    cn.poll(deadline - Duration::from_millis(1));
    assert_eq!(cn.state(), NmtState::NotActive);
    cn.poll(deadline);
    assert_eq!(cn.state(), NmtState::BasicEthernet);
    cn.on_frame(deadline, &soa(RequestedService::NoService, 0, Flags::empty()));
    assert_eq!(cn.state(), NmtState::PreOperational1);
}

/// The runtime on an in-process segment: a PReq gets the prepared PRes, the SoA's
/// IdentRequest the IdentResponse, and the turnaround is measured.
#[test]
fn runtime_answers_on_a_link() {
    use crate::transport::{EthLink, MemHub};
    use std::sync::Arc;
    let hub = MemHub::with_clock("cn-runtime", motus_clock::SystemClock::shared());
    let mn: Arc<dyn EthLink> = Arc::new(hub.connect());
    let link: Arc<dyn EthLink> = Arc::new(hub.connect());
    let clock = motus_clock::SystemClock::shared();
    let cn = ControlledNode::new(
        5,
        link.mac(),
        ObjectDictionary::controlled_node(5, &DeviceIdentity::default()),
        clock.now(),
    )
    .unwrap();
    let rt = ControlledNodeRuntime::start(cn, link, clock, CnRuntimeConfig::default()).unwrap();
    let mut buf = vec![0u8; 1518];
    let mut recv = |want: fn(&EplFrame) -> bool| -> EplFrame {
        let until = Instant::now() + Duration::from_secs(10);
        while Instant::now() < until {
            if let Some((n, _)) = mn.recv(&mut buf, Duration::from_millis(100)).unwrap() {
                let f = decode(&buf[..n]);
                if want(&f) {
                    return f;
                }
            }
        }
        panic!("no answer");
    };
    mn.send(&soa(RequestedService::IdentRequest, 5, Flags::empty())).unwrap();
    let f = recv(|f| matches!(f.message, Message::Asnd(Asnd::IdentResponse(_))));
    assert_eq!(f.src_node, 5);
    mn.send(&soc()).unwrap();
    let mut p = preq(5, Flags::empty(), &[]);
    p[..6].copy_from_slice(&rt.with_node(|n| n.mac()).0);
    for _ in 0..10 {
        mn.send(&p).unwrap();
        let f = recv(|f| matches!(f.message, Message::PRes(_)));
        assert_eq!(f.src_node, 5);
    }
    let events = rt.take_events();
    assert!(events.iter().any(|e| matches!(e, CnEvent::State { to: NmtState::PreOperational2, .. })));
    let stats = rt.stop();
    assert_eq!(stats.pres_sent, 10);
    assert_eq!(stats.turnaround.count, 10);
    assert_eq!(stats.state, NmtState::PreOperational2);
}

#[test]
fn a_reset_can_take_time_during_which_the_node_is_silent() {
    let t0 = Instant::now();
    let mut cn = node(1, t0);
    cn.set_reset_time(Duration::from_millis(800));
    boot(&mut cn, t0, NmtState::PreOperational2);
    cn.on_frame(t0, &nmt(BROADCAST_NODE_ID, NmtCommandId::ResetNode, &[]));
    assert_eq!(cn.state(), NmtState::ResetConfiguration);
    assert_eq!(cn.next_deadline(), Some(t0 + Duration::from_millis(800)));
    let t1 = t0 + Duration::from_millis(799);
    assert!(cn.on_frame(t1, &soa(RequestedService::IdentRequest, 1, Flags::empty())).is_empty());
    assert_eq!(cn.state(), NmtState::ResetConfiguration);
    let t2 = t0 + Duration::from_millis(800);
    cn.poll(t2);
    assert_eq!(cn.state(), NmtState::NotActive);
    assert_eq!(cn.on_frame(t2, &soa(RequestedService::IdentRequest, 1, Flags::empty())).len(), 1);
    assert_eq!(cn.state(), NmtState::PreOperational1);
}
