//! The monitor on the real openPOWERLINK captures of crates/epl-protocol/tests/data: once node 1
//! sends valid data (RD, OPERATIONAL), its PRes is fresh in every cycle.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::ops::ControlFlow;

use motus_epl::replay::read_capture;
use motus_epl::{Monitor, MonitorConfig};
use motus_epl_protocol::{Value, ValueMap};

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
