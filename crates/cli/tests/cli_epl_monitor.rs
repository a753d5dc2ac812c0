//! `motus epl monitor` through the binary: the cycle-only watch (no `--map`) of an
//! openPOWERLINK capture, its per-cycle lines and its summary.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::MOTUS;
use std::process::Command;

#[test]
fn cycle_only_monitor_of_a_capture_accounts_for_every_frame() {
    let capture = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../epl-protocol/tests/data/oplk_mn_cn_bridge_monitor.pcapng");
    let o = Command::new(MOTUS)
        .args(["epl", "monitor", "--pcap", capture.to_str().unwrap(), "--every", "100"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let lines: Vec<serde_json::Value> =
        String::from_utf8_lossy(&o.stdout).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    let (summary, cycles) = lines.split_last().unwrap();
    // 601 cycles, one line in 100 (no cycle has a miss or a lost frame).
    assert_eq!(cycles.len(), 7, "{cycles:?}");
    for c in cycles {
        let f = &c["frames"];
        assert_eq!(f["received"], f["decoded"].as_u64().unwrap() + f["undecoded"].as_u64().unwrap());
        assert_eq!(c["missing"], serde_json::json!([]));
        assert!(
            f["kernel_drops"].is_null() && f["kernel_packets"].is_null(),
            "a capture has no kernel counters"
        );
    }
    assert_eq!(cycles[2]["pres"][0]["node"], 1);
    let s = &summary["summary"];
    assert_eq!(s["frames"]["received"], 3279);
    assert_eq!(s["frames"]["dropped"], 0);
    assert_eq!(s["cycles"], 601);
    let n1 = s["nodes"].as_array().unwrap().iter().find(|n| n["node"] == 1).unwrap();
    assert_eq!((n1["pres"].as_u64(), n1["misses"].as_u64()), (Some(575), Some(0)), "{n1}");
    assert_eq!(n1["nmt_state"], "OPERATIONAL");
    assert!(stderr.contains("frames: 3279 received = 3279 decoded + 0 undecoded"), "{stderr}");
    assert!(stderr.contains("node 1: OPERATIONAL, polled 575, PRes 575, misses 0"), "{stderr}");
}
