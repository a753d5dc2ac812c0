//! Replays the real openPOWERLINK captures of `shared/fixtures/powerlink/` (copied into
//! tests/data/): every EPL frame must decode and re-encode to the same bytes, and once node 1
//! is OPERATIONAL its PRes must appear in every SoC cycle.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::collections::BTreeMap;
use std::fs::File;

use motus_epl_protocol::{
    Asnd, CycleTracker, EplFrame, Message, NmtCommandId, NmtState, Padding, ValueMap, ETHERTYPE_EPL,
};
use pcap_file::pcapng::{Block, PcapNgReader};

/// (timestamp in capture ticks, frame bytes) of every packet in a pcapng file.
fn packets(name: &str) -> Vec<(u64, Vec<u8>)> {
    let path = format!("{}/tests/data/{name}", env!("CARGO_MANIFEST_DIR"));
    let mut reader = PcapNgReader::new(File::open(&path).unwrap()).unwrap();
    let mut out = Vec::new();
    while let Some(block) = reader.next_block() {
        if let Block::EnhancedPacket(epb) = block.unwrap() {
            out.push((u64::try_from(epb.timestamp.as_nanos()).unwrap(), epb.data.to_vec()));
        }
    }
    out
}

fn is_epl(frame: &[u8]) -> bool {
    frame.len() >= 14 && u16::from_be_bytes([frame[12], frame[13]]) == ETHERTYPE_EPL
}

fn check_capture(name: &str) {
    let pkts = packets(name);
    let mut by_type: BTreeMap<&'static str, usize> = BTreeMap::new();
    let mut non_epl = 0;
    let mut tracker = CycleTracker::new();
    let mut cycles = Vec::new();
    let mut nmt_commands = Vec::new();
    for (at, bytes) in &pkts {
        if !is_epl(bytes) {
            non_epl += 1;
            continue;
        }
        let frame = EplFrame::decode(bytes).unwrap_or_else(|e| panic!("{name}: {e} in {bytes:02x?}"));
        assert_eq!(&frame.encode().unwrap(), bytes, "{name}: re-encode of {frame:?}");
        // The JSON form round-trips too.
        let json = serde_json::to_string(&frame).unwrap();
        let back: EplFrame = serde_json::from_str(&json).unwrap();
        assert_eq!(back, frame, "{name}: JSON {json}");
        // Captured frames are 36 (SoC), 54 (SoA) unpadded, or padded to 60 and above.
        if bytes.len() < 60 {
            assert_eq!(frame.padding, Padding::Unpadded, "{name}: {json}");
        }
        *by_type.entry(frame.message.name()).or_default() += 1;
        if let Message::Asnd(Asnd::NmtCommand(c)) = &frame.message {
            nmt_commands.push((frame.dst_node, c.command));
        }
        if let Some(c) = tracker.push(*at, &frame) {
            cycles.push(c);
        }
    }
    assert!(non_epl <= 10, "{name}: {non_epl} non-EPL frames");
    for t in ["SoC", "PReq", "PRes", "SoA", "ASnd"] {
        assert!(by_type.get(t).copied().unwrap_or(0) > 0, "{name}: no {t} in {by_type:?}");
    }
    // The boot sequence of specs/powerlink.md §6.
    for cmd in [NmtCommandId::ResetNode, NmtCommandId::EnableReadyToOperate, NmtCommandId::StartNode] {
        assert!(nmt_commands.iter().any(|(_, c)| *c == cmd), "{name}: no {cmd} in {nmt_commands:?}");
    }
    assert!(nmt_commands.contains(&(1, NmtCommandId::StartNode)));

    // Cycle tracking: once node 1's PRes says OPERATIONAL, every later cycle has its PRes.
    assert!(cycles.len() > 100, "{name}: {} cycles", cycles.len());
    let first_op = cycles
        .iter()
        .position(|c| c.pres_of(1).is_some_and(|p| p.nmt_state == NmtState::Operational))
        .unwrap_or_else(|| panic!("{name}: node 1 never OPERATIONAL"));
    let operational = &cycles[first_op..];
    assert!(operational.len() > 50, "{name}: only {} operational cycles", operational.len());
    for c in operational {
        let p =
            c.pres_of(1).unwrap_or_else(|| panic!("{name}: cycle {} has no PRes of node 1: {c:?}", c.index));
        assert_eq!(p.nmt_state, NmtState::Operational, "{name}: cycle {}", c.index);
        assert!(p.ready, "{name}: RD=0 in cycle {}", c.index);
        assert_eq!(c.polled, [1], "{name}: cycle {}", c.index);
        assert!(c.missing().is_empty());
        assert_eq!(p.payload_len, 1);
    }
    // The 50 ms Demo_3CN cycle (specs/powerlink.md §5: median 50.0007 ms, 47.2-52.8 ms).
    let mut periods: Vec<u64> = cycles.iter().filter_map(|c| c.duration_ns).collect();
    periods.sort_unstable();
    let median = periods[periods.len() / 2];
    assert!((49_000_000..51_000_000).contains(&median), "{name}: median SoC period {median} ns");
    // RelativeTime grows by the cycle time (50 000 µs) from one SoC to the next.
    let steps: Vec<u64> =
        operational.windows(2).map(|w| w[1].relative_time_us - w[0].relative_time_us).collect();
    assert!(steps.iter().all(|&s| s == 50_000), "{name}: RelativeTime steps {steps:?}");

    // Value extraction: the one mapped byte (0x6000/01) at payload offset 0.
    let map =
        ValueMap::from_toml("[[node]]\nnode = 1\nvalues = [{ name = \"in\", offset = 0, type = \"u8\" }]\n")
            .unwrap();
    let last_pres = pkts
        .iter()
        .rev()
        .filter(|(_, b)| is_epl(b))
        .map(|(_, b)| EplFrame::decode(b).unwrap())
        .find(|f| matches!(f.message, Message::PRes(_)))
        .unwrap();
    let samples = map.extract_frame(&last_pres).unwrap().unwrap();
    assert_eq!(samples.len(), 1);
    // A 4-byte value at offset 0 of the 1-byte payload is out of range.
    let wide =
        ValueMap::from_toml("[[node]]\nnode = 1\nvalues = [{ name = \"x\", offset = 0, type = \"i32\" }]\n")
            .unwrap();
    assert!(wide.extract_frame(&last_pres).is_err());
}

#[test]
fn veth_merged_capture_round_trips_and_node1_is_cyclic() {
    check_capture("oplk_mn_cn_veth_merged.pcapng");
}

#[test]
fn bridge_monitor_capture_round_trips_and_node1_is_cyclic() {
    check_capture("oplk_mn_cn_bridge_monitor.pcapng");
}

#[test]
fn ident_response_from_capture() {
    // The first IdentResponse of CN 1 (specs/powerlink.md §3.6: IP 192.168.100.1, state 0x1D).
    let ident = packets("oplk_mn_cn_veth_merged.pcapng")
        .into_iter()
        .filter(|(_, b)| is_epl(b))
        .map(|(_, b)| EplFrame::decode(&b).unwrap())
        .find_map(|f| match f.message {
            Message::Asnd(Asnd::IdentResponse(i)) => Some((f.src_node, f.dst_node, i)),
            _ => None,
        })
        .unwrap();
    let (src, dst, i) = ident;
    assert_eq!((src, dst), (1, 255));
    assert_eq!(i.ip_address, std::net::Ipv4Addr::new(192, 168, 100, 1));
    assert_eq!(i.subnet_mask, std::net::Ipv4Addr::new(255, 255, 255, 0));
    assert_eq!(i.nmt_state, NmtState::PreOperational1);
    assert_eq!(i.epl_version, 0x20);
    assert_eq!(i.response_time, 50_000); // demo CN PResMaxLatency (§5)
}
