//! `motus epl monitor --if` on a veth port in network namespaces, through the TPACKET_V3 ring
//! (the default) and through the plain socket (`--no-ring`): 100 cycles of a 1 ms segment sent
//! from another port are all received, decoded and counted. Needs root (namespaces, veth,
//! AF_PACKET): skipped with a printed reason otherwise.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::MOTUS;
use motus_epl::netns::{is_root, BridgedPorts};
use motus_epl_protocol::{
    EplFrame, Flags, MacAddr, Message, NmtState, PReq, PRes, PrRs, RequestedService, Soa, Soc,
};

/// Cycle `k` of a 1 ms segment with one CN: SoC (RelativeTime k ms), PReq, PRes, SoA.
fn cycle_frames(k: u64) -> Vec<Vec<u8>> {
    let mn = MacAddr([2, 0, 0, 0, 0, 240]);
    let cn = MacAddr([2, 0, 0, 0, 0, 1]);
    let soc = Soc { relative_time: 1000 * k, ..Soc::default() };
    let preq = PReq { flags: Flags::RD, payload: vec![0; 4], ..PReq::default() };
    let pres = PRes {
        nmt_state: NmtState::Operational,
        flags: Flags::RD,
        pr_rs: PrRs::default(),
        pdo_version: 0,
        payload: vec![1, 2, 3, 4],
        reserved: 0,
    };
    let soa = Soa::new(NmtState::Operational, RequestedService::NoService, 0);
    [
        EplFrame::new(mn, MacAddr::SOC, 255, 240, Message::Soc(soc)),
        EplFrame::new(mn, cn, 1, 240, Message::PReq(preq)),
        EplFrame::new(cn, MacAddr::PRES, 255, 1, Message::PRes(pres)),
        EplFrame::new(mn, MacAddr::SOA, 255, 240, Message::Soa(soa)),
    ]
    .iter()
    .map(|f| f.encode().unwrap())
    .collect()
}

/// Runs the monitor with `extra` arguments for 100 cycles; returns its summary and stderr.
fn monitor_100_cycles(tag: &str, extra: &[&str]) -> (serde_json::Value, String) {
    let ns = BridgedPorts::create(tag, &["feed", "mon"]).unwrap();
    let tx = ns.open(&["feed"]).unwrap().pop().unwrap();
    let mut child = Command::new("ip")
        .args(["netns", "exec", ns.ports_namespace(), MOTUS, "epl", "monitor", "--if", "mon"])
        .args(["--cycles", "100", "--every", "1000"])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The monitor is listening once it says so.
    let mut err_lines = BufReader::new(child.stderr.take().unwrap()).lines();
    let mut stderr = String::new();
    for line in err_lines.by_ref() {
        let line = line.unwrap();
        stderr.push_str(&line);
        stderr.push('\n');
        if line.starts_with("monitoring") {
            break;
        }
    }
    let rest = std::thread::spawn(move || err_lines.map(|l| l.unwrap() + "\n").collect::<String>());
    // 101 cycles and a few more: the SoC of cycle 100 closes cycle 99, the 100th reported.
    for k in 0..105 {
        for f in cycle_frames(k) {
            tx.send(&f).unwrap();
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    // Liveness only.
    let t = Instant::now();
    while child.try_wait().unwrap().is_none() && t.elapsed() < Duration::from_secs(30) {
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = child.kill();
    let out = child.wait_with_output().unwrap();
    stderr.push_str(&rest.join().unwrap());
    assert!(out.status.success(), "{stderr}");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let summary: serde_json::Value = serde_json::from_str(stdout.lines().last().unwrap()).unwrap();
    drop(ns);
    (summary["summary"].clone(), stderr)
}

fn check(s: &serde_json::Value, stderr: &str) {
    let f = &s["frames"];
    // Cycles 0..=99 and the SoC of cycle 100.
    assert_eq!(f["received"], 401, "{s}\n{stderr}");
    assert_eq!(f["decoded"], 401);
    assert_eq!((f["dropped"].as_u64(), f["kernel_drops"].as_u64()), (Some(0), Some(0)), "{s}");
    assert!(f["kernel_packets"].as_u64().unwrap() >= 401, "{s}");
    assert_eq!(s["cycles"], 100);
    let n1 = s["nodes"].as_array().unwrap().iter().find(|n| n["node"] == 1).unwrap();
    assert_eq!((n1["pres"].as_u64(), n1["misses"].as_u64()), (Some(100), Some(0)), "{n1}");
}

#[test]
fn monitor_on_an_interface_reads_through_the_ring_by_default() {
    if !is_root() {
        eprintln!("skipped: needs root (network namespaces, veth, AF_PACKET)");
        return;
    }
    let (s, stderr) = monitor_100_cycles("cliring", &["--ring-mb", "8"]);
    assert!(stderr.contains("receive ring: 8 MiB"), "{stderr}");
    assert!(stderr.contains("TPACKET_V3 ring"), "{stderr}");
    check(&s, &stderr);
    let (s, stderr) = monitor_100_cycles("cliplain", &["--no-ring"]);
    assert!(stderr.contains("receive queue:") && !stderr.contains("TPACKET_V3"), "{stderr}");
    check(&s, &stderr);
}
