//! The segment scenario over raw sockets on veth pairs in network namespaces (needs root; CI
//! runs as root). Namespace A holds one veth end per node (mn, cn1..cn5, mon); namespace B
//! holds the peers, all ports of a bridge with ageing time 0, so it floods every frame like a
//! hub and the monitor port also sees unicast PReq (specs/powerlink.md §8). IPv6 is disabled
//! in both namespaces. A Drop guard deletes both namespaces (and with them every veth and the
//! bridge), even when the test fails.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::fs::File;
use std::process::Command;
use std::sync::Arc;
use std::time::Duration;

use motus_epl::sim::MnConfig;
use motus_epl::{EthLink, RawSocket};

fn sh(args: &[&str]) {
    let out = Command::new(args[0]).args(&args[1..]).output().unwrap_or_else(|e| panic!("{args:?}: {e}"));
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

struct Netns {
    a: String,
    b: String,
}

impl Netns {
    fn create(ports: &[&str]) -> Self {
        let id = std::process::id();
        let ns = Netns { a: format!("motus-epl-{id}-a"), b: format!("motus-epl-{id}-b") };
        for n in [&ns.a, &ns.b] {
            sh(&["ip", "netns", "add", n]);
            for key in ["all", "default"] {
                let k = format!("net.ipv6.conf.{key}.disable_ipv6=1");
                sh(&["ip", "netns", "exec", n, "sysctl", "-qw", &k]);
            }
        }
        sh(&[
            "ip",
            "-n",
            &ns.b,
            "link",
            "add",
            "br0",
            "type",
            "bridge",
            "ageing_time",
            "0",
            "forward_delay",
            "0",
        ]);
        sh(&["ip", "-n", &ns.b, "link", "set", "br0", "up"]);
        for p in ports {
            let peer = format!("p{p}");
            sh(&["ip", "-n", &ns.a, "link", "add", p, "type", "veth", "peer", "name", &peer, "netns", &ns.b]);
            sh(&["ip", "-n", &ns.b, "link", "set", &peer, "master", "br0"]);
            sh(&["ip", "-n", &ns.b, "link", "set", &peer, "up"]);
            sh(&["ip", "-n", &ns.a, "link", "set", p, "up"]);
        }
        ns
    }
}

impl Drop for Netns {
    fn drop(&mut self) {
        for n in [&self.b, &self.a] {
            let _ = Command::new("ip").args(["netns", "del", n]).status();
        }
    }
}

fn require_root() {
    let out = Command::new("id").arg("-u").output().expect("id -u");
    let uid = String::from_utf8_lossy(&out.stdout).trim().to_owned();
    assert_eq!(
        uid, "0",
        "the veth test needs root (network namespaces, veth, AF_PACKET); run it as root like CI does"
    );
}

/// Opens raw sockets on `ports` from a thread that has entered namespace `ns`.
fn open_in(ns: &str, ports: &[&str]) -> Vec<Arc<dyn EthLink>> {
    let path = format!("/run/netns/{ns}");
    let ports: Vec<String> = ports.iter().map(|s| s.to_string()).collect();
    std::thread::spawn(move || {
        let f = File::open(&path).unwrap();
        nix::sched::setns(f, nix::sched::CloneFlags::CLONE_NEWNET).unwrap();
        ports
            .iter()
            .map(|p| Arc::new(RawSocket::open(p, true).unwrap()) as Arc<dyn EthLink>)
            .collect::<Vec<_>>()
    })
    .join()
    .unwrap()
}

fn run(label: &str, cycle: Duration, pres_timeout: Duration, max_miss: f64) {
    require_root();
    let ports = ["mn", "cn1", "cn2", "cn3", "cn4", "cn5", "mon"];
    let ns = Netns::create(&ports);
    let mut links = open_in(&ns.a, &ports);
    let mon = links.pop().unwrap();
    let mn = links.remove(0);
    for l in &links {
        assert_ne!(l.mac(), mn.mac(), "{}", l.describe());
    }
    let config = MnConfig { cycle, pres_timeout, ..MnConfig::default() };
    let out = common::run_scenario(label, mn, links, mon, config, common::max_miss(max_miss));
    assert!(out.monitored_cycles > 0);
    drop(ns);
}

#[test]
fn veth_segment_1ms() {
    let _one_at_a_time = common::exclusive();
    // See tests/udp.rs for the limits.
    run("veth 1 ms", Duration::from_millis(1), Duration::from_micros(300), 0.005);
}

#[test]
fn veth_segment_400us() {
    let _one_at_a_time = common::exclusive();
    // See tests/udp.rs for the 5 % limit at 400 us.
    run("veth 400 us", Duration::from_micros(400), Duration::from_micros(150), 0.05);
}
