//! The monitor on the real openPOWERLINK captures of crates/epl-protocol/tests/data: once node 1
//! sends valid data (RD, OPERATIONAL), its PRes is fresh in every cycle; the cycle-only watch
//! counts every frame, cycle and PRes; pcapng time stamp resolutions and drop counts.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::fs::File;
use std::ops::ControlFlow;
use std::path::Path;
use std::time::Duration;

use motus_epl::replay::{read_capture, CapturedFrame};
use motus_epl::{CycleSample, Monitor, MonitorConfig, MonitorStats, NodeCounters};
use motus_epl_protocol::{NmtState, Value, ValueMap};
use pcap_file::pcapng::blocks::enhanced_packet::{EnhancedPacketBlock, EnhancedPacketOption};
use pcap_file::pcapng::blocks::interface_description::{
    InterfaceDescriptionBlock, InterfaceDescriptionOption,
};
use pcap_file::pcapng::PcapNgWriter;
use pcap_file::DataLink;

fn check(name: &str) {
    let path = format!("{}/../epl-protocol/tests/data/{name}", env!("CARGO_MANIFEST_DIR"));
    let frames = read_capture(&path).unwrap();
    assert!(frames.len() > 500, "{name}: {} frames", frames.len());
    // Demo_3CN: CN 1 maps one byte (object 0x6000/1) at payload offset 0 (specs/powerlink.md §7).
    let map =
        ValueMap::from_toml("[[node]]\nnode = 1\nvalues = [{ name = \"in\", offset = 0, type = \"u8\" }]\n")
            .unwrap();
    let mut monitor = Monitor::new(map, MonitorConfig { stale_after: 0 });
    let mut samples = Vec::new();
    let stats = monitor.replay(&frames, |s| {
        samples.push(s.clone());
        ControlFlow::Continue(())
    });
    let first_valid =
        samples.iter().position(|s| s.all_fresh()).unwrap_or_else(|| panic!("{name}: never valid"));
    let operational = &samples[first_valid..];
    assert!(operational.len() > 50, "{name}: {} operational cycles", operational.len());
    for s in operational {
        let n = s.node(1).unwrap();
        assert_eq!(n.age, Some(0), "{name}: cycle {} node 1 stale", s.index);
        assert!(n.valid, "{name}: cycle {}", s.index);
        assert!(matches!(n.value("in"), Some(Value::U8(_))));
    }
    assert_eq!(stats.cycles as usize, samples.len());
}

#[test]
fn bridge_monitor_capture() {
    check("oplk_mn_cn_bridge_monitor.pcapng");
}

#[test]
fn merged_veth_capture() {
    check("oplk_mn_cn_veth_merged.pcapng");
}

/// The fixture capture `name` (a copy of `/work/shared/fixtures/powerlink/`).
fn fixture(name: &str) -> String {
    format!("{}/../epl-protocol/tests/data/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// Replays `frames` in a cycle-only monitor; returns its stats and node counters.
fn cycles_only(frames: &[CapturedFrame]) -> (MonitorStats, Vec<CycleSample>, BTreeMap<u8, NodeCounters>) {
    let mut monitor = Monitor::cycles_only(MonitorConfig::default());
    let mut samples = Vec::new();
    let stats = monitor.replay(frames, |s| {
        samples.push(s.clone());
        ControlFlow::Continue(())
    });
    let nodes = monitor.node_counters().into_iter().map(|c| (c.node, c)).collect();
    (stats, samples, nodes)
}

/// The cycle-only watch of the openPOWERLINK captures: every frame decoded, node 1 polled and
/// answering in every cycle (counts from `tshark -Y epl`: SoC, PReq, PRes), no miss, and the
/// 50 ms cycle of Demo_3CN measured from the nanosecond time stamps.
#[test]
fn cycle_only_report_on_the_fixture_captures() {
    // (file, frames, POWERLINK frames, SoC, PReq = PRes to/from node 1, first frame's time
    // stamp); the merged capture also holds 4 ICMPv6 router solicitations.
    let cases = [
        ("oplk_mn_cn_bridge_monitor.pcapng", 3279, 3279, 601, 575, 1_795_262_959_132_618_193u64),
        ("oplk_mn_cn_veth_merged.pcapng", 4396, 4392, 879, 851, 1_795_262_863_424_014_947),
    ];
    for (name, frames, epl, socs, polls, first_ns) in cases {
        let captured = read_capture(fixture(name)).unwrap();
        assert_eq!(captured[0].at_ns, first_ns, "{name}");
        let (st, samples, nodes) = cycles_only(&captured);
        assert_eq!(
            (st.frames, st.decoded, st.undecoded, st.dropped),
            (frames, epl, frames - epl, 0),
            "{name}"
        );
        assert_eq!(st.kernel, None);
        assert_eq!((st.cycles, st.cycles_with_loss, st.cycles_lost), (socs, 0, 0), "{name}");
        let n1 = nodes[&1];
        assert_eq!((n1.polled, n1.pres, n1.misses), (polls, polls, 0), "{name}: {n1:?}");
        // Every closed cycle that polled node 1 expected it (the last one is still open).
        assert!(n1.expected + 1 >= polls, "{name}: {n1:?}");
        assert_eq!(n1.nmt_state, Some(NmtState::Operational), "{name}");
        assert_eq!(nodes[&240].nmt_state, Some(NmtState::Operational), "{name}: the MN, from its SoA");
        assert!(samples.iter().all(|s| s.missing.is_empty() && s.nodes.is_empty()));
        assert!(samples.iter().rev().skip(1).all(CycleSample::complete));
        let mean = st.cycle_time.mean_ns().unwrap();
        assert!((49_500_000..50_500_000).contains(&mean), "{name}: mean cycle {mean} ns");
    }
}

/// Writes `frames` as a pcapng with one Ethernet interface described by `options`, time
/// stamps converted to its units by `units`; `drops` gives the epb_dropcount of a frame.
fn write_pcapng(
    path: &Path,
    options: Vec<InterfaceDescriptionOption<'static>>,
    frames: &[CapturedFrame],
    units: impl Fn(u64) -> u64,
) {
    let mut w = PcapNgWriter::new(File::create(path).unwrap()).unwrap();
    w.write_pcapng_block(InterfaceDescriptionBlock {
        linktype: DataLink::ETHERNET,
        snaplen: 0xFFFF,
        options,
    })
    .unwrap();
    for f in frames {
        let options = if f.dropped_before > 0 {
            vec![EnhancedPacketOption::DropCount(f.dropped_before)]
        } else {
            vec![]
        };
        w.write_pcapng_block(EnhancedPacketBlock {
            interface_id: 0,
            // pcap-file writes the Duration's nanoseconds as the raw count of units.
            timestamp: Duration::from_nanos(units(f.at_ns)),
            original_len: f.data.len() as u32,
            data: Cow::Borrowed(&f.data),
            options,
        })
        .unwrap();
    }
}

/// pcapng time stamps in microseconds (the default when if_tsresol is absent, or if_tsresol
/// 6), in 2^-20 s, and with an if_tsoffset replay at the recorded speed: the same time stamps
/// (to the unit) and the same 50 ms cycle as the nanosecond original.
#[test]
fn pcapng_time_stamp_resolution_is_honoured() {
    let original = read_capture(fixture("oplk_mn_cn_bridge_monitor.pcapng")).unwrap();
    let (reference, _, _) = cycles_only(&original);
    let dir = tempfile::tempdir().unwrap();
    const OFFSET_S: u64 = 1_700_000_000;
    type Case = (&'static str, Vec<InterfaceDescriptionOption<'static>>, fn(u64) -> u64, u64);
    let cases: [Case; 4] = [
        ("default-us", vec![], |ns| ns / 1000, 1000),
        ("tsresol-6", vec![InterfaceDescriptionOption::IfTsResol(6)], |ns| ns / 1000, 1000),
        (
            "tsresol-2^-20",
            vec![InterfaceDescriptionOption::IfTsResol(0x80 | 20)],
            |ns| ((u128::from(ns) << 20) / 1_000_000_000) as u64,
            955, // one unit (10^9 / 2^20 ns) plus the rounding of the conversion back
        ),
        (
            "us-with-offset",
            vec![InterfaceDescriptionOption::IfTsResol(6), InterfaceDescriptionOption::IfTsOffset(OFFSET_S)],
            |ns| (ns - OFFSET_S * 1_000_000_000) / 1000,
            1000,
        ),
    ];
    for (label, options, units, unit_ns) in cases {
        let path = dir.path().join(format!("{label}.pcapng"));
        write_pcapng(&path, options, &original, units);
        let replayed = read_capture(&path).unwrap();
        assert_eq!(replayed.len(), original.len(), "{label}");
        for (r, o) in replayed.iter().zip(&original) {
            assert_eq!(r.data, o.data);
            assert!(r.at_ns <= o.at_ns && o.at_ns - r.at_ns < unit_ns, "{label}: {} vs {}", r.at_ns, o.at_ns);
        }
        let (st, _, _) = cycles_only(&replayed);
        assert_eq!(st.cycles, reference.cycles, "{label}");
        let (mean, reference_mean) =
            (st.cycle_time.mean_ns().unwrap(), reference.cycle_time.mean_ns().unwrap());
        assert!(
            mean.abs_diff(reference_mean) < unit_ns,
            "{label}: mean cycle {mean} ns, original {reference_mean} ns"
        );
    }
}

/// Frames the capturing system lost (pcapng epb_dropcount) are counted and mark their cycles:
/// node 1's lost PRes are not misses, and the lost SoCs are estimated from the SoC's
/// RelativeTime, so the cycle count matches the original's.
#[test]
fn capture_drop_counts_mark_cycles_and_are_not_misses() {
    let original = read_capture(fixture("oplk_mn_cn_bridge_monitor.pcapng")).unwrap();
    let (reference, _, _) = cycles_only(&original);
    // Drop frames 2000..2010 and 2500..2503 (operational cycles: SoC, PReq, PRes, SoA...).
    let mut lossy = Vec::new();
    let mut lost = 0u64;
    for (i, f) in original.iter().enumerate() {
        if (2000..2010).contains(&i) || (2500..2503).contains(&i) {
            lost += 1;
            continue;
        }
        let mut f = f.clone();
        f.dropped_before = std::mem::take(&mut lost);
        lossy.push(f);
    }
    let path = tempfile::tempdir().unwrap();
    let file = path.path().join("lossy.pcapng");
    write_pcapng(&file, vec![InterfaceDescriptionOption::IfTsResol(9)], &lossy, |ns| ns);
    let replayed = read_capture(&file).unwrap();
    assert_eq!(replayed.iter().map(|f| f.dropped_before).sum::<u64>(), 13);
    let (st, samples, nodes) = cycles_only(&replayed);
    assert_eq!((st.frames, st.dropped), (reference.frames - 13, 13));
    assert_eq!(st.cycles_with_loss, 2);
    assert!(st.cycles_lost >= 1, "{st:?}");
    assert_eq!(st.cycles + st.cycles_lost, reference.cycles, "{st:?}");
    assert_eq!(nodes[&1].misses, 0);
    let lossy_cycles: Vec<u64> =
        samples.iter().filter(|s| s.lost_frames > 0).map(|s| s.lost_frames).collect();
    assert_eq!(lossy_cycles, vec![10, 3]);
    // The cycle index after the gap is the original's.
    let (_, reference_samples, _) = cycles_only(&original);
    let last = samples.last().unwrap();
    let reference_last = reference_samples.last().unwrap();
    assert_eq!((last.index, last.report.soc_at_ns), (reference_last.index, reference_last.report.soc_at_ns));
}
