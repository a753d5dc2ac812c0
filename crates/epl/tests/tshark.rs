//! tshark reads a pcap written by PcapLink around the MN's link of a simulated UDP segment
//! (boot-up through OPERATIONAL) with no expert errors, and decodes every frame type.
//! Fails (does not skip) when tshark is missing: CI installs it.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::process::Command;
use std::sync::Arc;
use std::time::Duration;

use motus_epl::sim::{DriveParams, Segment};
use motus_epl::{EthLink, PcapLink, UdpHub};

#[test]
fn tshark_accepts_simulated_segment() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("segment.pcap");
    let hub = UdpHub::new();
    let mn = Arc::new(PcapLink::create(hub.connect().unwrap(), &path).unwrap());
    let mut b =
        Segment::builder().cycle(Duration::from_millis(2)).mn_link(Arc::clone(&mn) as Arc<dyn EthLink>);
    for node in 1..=3 {
        b = b.drive(node, Arc::new(hub.connect().unwrap()), DriveParams::default());
    }
    let seg = b.start().unwrap();
    assert!(seg.wait_operational(Duration::from_secs(5)));
    std::thread::sleep(Duration::from_millis(200));
    seg.stop();
    mn.flush().unwrap();

    let out = Command::new("tshark")
        .args(["-n", "-q", "-z", "expert", "-r"])
        .arg(&path)
        .output()
        .expect("tshark must be installed (apt-get install tshark)");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "tshark: {}", String::from_utf8_lossy(&out.stderr));
    assert!(!text.contains("Errors ("), "expert errors:\n{text}");
    assert!(!text.contains("Malformed"), "malformed:\n{text}");

    // Every message type and service of the boot-up is decoded as POWERLINK.
    let out = Command::new("tshark")
        .args(["-n", "-r"])
        .arg(&path)
        .args([
            "-T",
            "fields",
            "-e",
            "epl.mtyp",
            "-e",
            "epl.src",
            "-e",
            "epl.asnd.svid",
            "-e",
            "epl.asnd.nmtcommand.cid",
        ])
        .output()
        .unwrap();
    let fields = String::from_utf8_lossy(&out.stdout);
    let lines: Vec<&str> = fields.lines().collect();
    assert!(lines.len() > 100, "{} frames", lines.len());
    assert!(lines.iter().all(|l| !l.is_empty() && !l.starts_with('\t')), "undecoded frame in:\n{fields}");
    let has = |f: &dyn Fn(&[&str]) -> bool| lines.iter().any(|l| f(&l.split('\t').collect::<Vec<_>>()));
    for mtyp in ["1", "3", "4", "5", "6"] {
        assert!(has(&|c| c[0] == mtyp), "message type {mtyp} missing");
    }
    // IdentResponse (0x01), StatusResponse (0x02), NMT commands EnableReadyToOperate (0x24),
    // StartNode (0x21), ResetNode (0x28) (specs/powerlink.md §4.3, §4.5).
    let asnd: Vec<&&str> = lines.iter().filter(|l| l.starts_with("6\t")).take(12).collect();
    assert!(has(&|c| c[2] == "0x01"), "no IdentResponse in {asnd:?}");
    assert!(has(&|c| c[2] == "0x02"), "no StatusResponse");
    for cid in ["0x24", "0x21", "0x28"] {
        assert!(
            has(&|c| c.get(3) == Some(&cid)),
            "no NMT command {cid}:\n{}",
            &fields[..fields.len().min(3000)]
        );
    }
}
