//! The juggler with the supervisor as a POWERLINK node on a veth segment (issue 20,
//! acceptance 4): `motus sim epl --safety-node 100` (the MN and five drives, each on its own
//! veth port, the drives taking SafeToRun from node 100's PRes only), `motus safety run
//! --node 100` on another port (a CN the MN boots and polls, publishing SafeToRun and a lease
//! counter in its PRes), and `motus epl monitor` on a third, as separate processes.
//!
//! * A student program aiming beyond the thrower's limit is stopped through the schedule:
//!   the supervisor clears SafeToRun in its PRes, every drive brakes and comes to rest short
//!   of the limit.
//! * Juggling runs under the node's PRes; killing the supervisor (SIGKILL) stops every drive
//!   by its lease.
//!
//! Needs root (network namespaces, raw sockets); skipped with a printed reason otherwise. The
//! time-outs are liveness bounds, not timing figures.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::MOTUS;
use motus_epl::netns::{is_root, BridgedPorts};
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

const SAFETY_NODE: &str = "100";
/// Status word bit of the simulated drives: stopped by the safety lease.
const STATUS_LEASE_STOP: u64 = 0x0008;

/// A `motus` process in the ports' namespace whose stdout and stderr lines arrive on a channel.
struct Proc {
    child: Child,
    rx: mpsc::Receiver<String>,
    name: &'static str,
}

impl Proc {
    fn start(name: &'static str, ns: &str, args: &[&str]) -> Proc {
        let mut child = Command::new("ip")
            .args(["netns", "exec", ns, MOTUS])
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let (tx, rx) = mpsc::channel();
        for out in [
            Box::new(child.stdout.take().unwrap()) as Box<dyn std::io::Read + Send>,
            Box::new(child.stderr.take().unwrap()),
        ] {
            let tx = tx.clone();
            std::thread::spawn(move || {
                for l in BufReader::new(out).lines().map_while(Result::ok) {
                    if tx.send(l).is_err() {
                        break;
                    }
                }
            });
        }
        Proc { child, rx, name }
    }

    /// Waits up to `timeout` (a liveness bound) for a line containing all of `needles`.
    fn wait_for(&self, needles: &[&str], timeout: Duration) -> String {
        let end = Instant::now() + timeout;
        let mut seen = Vec::new();
        while let Some(left) = end.checked_duration_since(Instant::now()) {
            match self.rx.recv_timeout(left) {
                Ok(l) if needles.iter().all(|n| l.contains(n)) => return l,
                Ok(l) => seen.push(l),
                Err(_) => break,
            }
        }
        panic!(
            "{}: no line with {needles:?} within {timeout:?}; last lines {:?}",
            self.name,
            &seen[seen.len().saturating_sub(15)..]
        );
    }

    fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        self.kill();
    }
}

/// The last of `cycles` monitor lines of the drives 1..=5: (speed, position, status) each.
fn drives_after(ns: &str, map: &Path, cycles: usize) -> Vec<(f64, f64, u64)> {
    let count = cycles.to_string();
    let mon = Proc::start(
        "monitor",
        ns,
        &["epl", "monitor", "--if", "w0", "--map", map.to_str().unwrap(), "--cycles", &count],
    );
    let mut last = serde_json::Value::Null;
    for _ in 0..cycles {
        let l = mon.wait_for(&["\"cycle\""], Duration::from_secs(10));
        last = serde_json::from_str(&l).unwrap();
    }
    let nodes = last["nodes"].as_array().unwrap();
    (1..=5u64)
        .map(|n| {
            let d = nodes.iter().find(|d| d["node"] == n).unwrap_or_else(|| panic!("node {n} in {last}"));
            let v = &d["values"];
            let number =
                |name: &str| v[name].as_f64().unwrap_or_else(|| panic!("{name} of node {n} in {last}"));
            (number("speed"), number("position"), number("status") as u64)
        })
        .collect()
}

#[test]
fn the_supervisor_as_a_safety_node_stops_an_unsafe_program_and_its_death_stops_the_drives() {
    if !is_root() {
        eprintln!("skipped: needs root (network namespaces, raw sockets)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let rules = common::juggler_rules_1ms(dir.path());
    let rules_path = rules.to_str().unwrap();
    let map = dir.path().join("map.toml");
    let mut text = String::new();
    for n in 1..=5 {
        text.push_str(&format!(
            "[[node]]\nnode = {n}\nvalues = [{{ name = \"status\", offset = 0, type = \"u16\" }}, \
             {{ name = \"position\", offset = 16, type = \"i32\" }}, {{ name = \"speed\", offset = 20, type = \"i32\" }}]\n"
        ));
    }
    std::fs::write(&map, text).unwrap();
    let ports = ["m0", "d1", "d2", "d3", "d4", "d5", "s0", "w0"];
    let segment = BridgedPorts::create("sn", &ports).unwrap();
    let ns = segment.ports_namespace().to_owned();
    let supervise = |extra: &[&str]| {
        let mut args = vec![
            "safety",
            "run",
            "--rules",
            rules_path,
            "--if",
            "s0",
            "--no-integrity",
            "--node",
            SAFETY_NODE,
        ];
        args.extend(extra);
        Proc::start("supervisor", &ns, &args)
    };
    let simulate = |program: &str| {
        Proc::start(
            "segment",
            &ns,
            &[
                "sim",
                "epl",
                "--if",
                "m0,d1,d2,d3,d4,d5",
                "--config",
                rules_path,
                "--program",
                program,
                "--safety-node",
                SAFETY_NODE,
            ],
        )
    };

    // 1. A student program beyond the thrower's limit.
    let mut sup = supervise(&[]);
    let mut sim = simulate("limit");
    sim.wait_for(&["segment OPERATIONAL"], Duration::from_secs(30));
    sup.wait_for(&["\"event\":\"node\"", "OPERATIONAL"], Duration::from_secs(10));
    // A late frame on a loaded host may stop the drives before the program gets far (the
    // lease of the start-up or a stale sample); the operator resets, as on the machine.
    let deadline = Instant::now() + Duration::from_secs(30);
    let stop = loop {
        assert!(Instant::now() < deadline, "no stop by limits_thrower");
        let l = sup.wait_for(&["\"event\""], Duration::from_secs(10));
        if l.contains("\"unsafe\"") && l.contains("limits_thrower") {
            break l;
        }
        if l.contains("\"held\":true") {
            use std::io::Write;
            let stdin = sup.child.stdin.as_mut().unwrap();
            writeln!(stdin, "reset").unwrap();
            stdin.flush().unwrap();
        }
    };
    eprintln!("stop: {stop}");
    let drives = drives_after(&ns, &map, 300);
    eprintln!("after the stop: {drives:?}");
    for (speed, position, status) in &drives {
        assert_eq!(*speed, 0.0, "every drive at rest: {drives:?}");
        assert!(status & STATUS_LEASE_STOP != 0, "stopped by SafeToRun: {drives:?}");
        assert!(*position < 34_000.0, "short of the thrower's limit: {drives:?}");
    }
    sim.kill();
    sup.kill();

    // 2. Juggling runs under the node's PRes (resuming by itself after a stop a loaded host
    // may cause); the supervisor is killed.
    let mut sup = supervise(&["--auto-restart"]);
    let sim = simulate("juggle");
    sim.wait_for(&["segment OPERATIONAL"], Duration::from_secs(30));
    sup.wait_for(&["\"event\":\"safe\""], Duration::from_secs(10));
    let moving = (0..20).any(|_| drives_after(&ns, &map, 50).iter().any(|(speed, _, _)| *speed != 0.0));
    assert!(moving, "juggling runs under the safety node's PRes");
    sup.kill();
    let drives = drives_after(&ns, &map, 500);
    eprintln!("after the supervisor was killed: {drives:?}");
    for (speed, _, status) in &drives {
        assert_eq!(*speed, 0.0, "every drive at rest: {drives:?}");
        assert!(status & STATUS_LEASE_STOP != 0, "stopped by the lease: {drives:?}");
    }
}
