//! CycleTracker on a hand-made frame sequence: SoC, PReq/PRes per node, SoA, ASnd.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_epl_protocol::*;

const MN: MacAddr = MacAddr([2, 0, 0, 0, 0, 0xf0]);

fn soc(rel: u64) -> EplFrame {
    EplFrame::new(
        MN,
        MacAddr::BROADCAST,
        255,
        240,
        Message::Soc(Soc { relative_time: rel, ..Soc::default() }),
    )
}
fn preq(node: u8) -> EplFrame {
    EplFrame::new(MN, MacAddr([2, 0, 0, 0, 0, node]), node, 240, Message::PReq(PReq::default()))
}
fn pres(node: u8, state: NmtState, rd: bool) -> EplFrame {
    let flags = if rd { Flags::RD } else { Flags::empty() };
    let p = PRes {
        nmt_state: state,
        flags,
        pr_rs: PrRs::default(),
        pdo_version: 0,
        payload: vec![0; 4],
        reserved: 0,
    };
    EplFrame::new(MacAddr([2, 0, 0, 0, 0, node]), MacAddr::PRES, 255, node, Message::PRes(p))
}

#[test]
fn cycles_report_polled_and_answered_nodes() {
    let mut t = CycleTracker::new();
    // A SoA before any SoC (PreOp1 reduced cycle) is only counted.
    let soa = EplFrame::new(
        MN,
        MacAddr::BROADCAST,
        255,
        240,
        Message::Soa(Soa::new(NmtState::Operational, RequestedService::StatusRequest, 2)),
    );
    assert_eq!(t.push(0, &soa), None);
    assert_eq!(t.frames_before_first_soc(), 1);
    // Cycle 0 at t = 1 ms: nodes 1 and 2 polled, only 1 answers.
    assert_eq!(t.push(1_000_000, &soc(0)), None);
    t.push(1_100_000, &preq(1));
    t.push(1_200_000, &pres(1, NmtState::Operational, true));
    t.push(1_300_000, &preq(2));
    t.push(1_500_000, &soa);
    // Cycle 1 at t = 3 ms closes cycle 0.
    let c0 = t.push(3_000_000, &soc(2000)).unwrap();
    assert_eq!(c0.index, 0);
    assert_eq!(c0.duration_ns, Some(2_000_000));
    assert_eq!(c0.polled, [1, 2]);
    assert_eq!(c0.missing(), [2]);
    let p = c0.pres_of(1).unwrap();
    assert_eq!(
        (p.after_soc_ns, p.ready, p.nmt_state, p.payload_len),
        (200_000, true, NmtState::Operational, 4)
    );
    assert_eq!(c0.soa, Some((RequestedService::StatusRequest, 2)));
    t.push(3_100_000, &preq(2));
    t.push(3_150_000, &pres(2, NmtState::PreOperational2, false));
    let c1 = t.finish().unwrap();
    assert_eq!((c1.index, c1.relative_time_us, c1.duration_ns), (1, 2000, None));
    assert!(c1.saw_pres(2) && !c1.saw_pres(1));
    assert!(c1.missing().is_empty());
    assert_eq!(t.cycles_started(), 2);
    assert_eq!(t.finish(), None);
}
