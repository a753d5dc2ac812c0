//! Network namespaces joined by a bridge, for tests and demonstrations on a real kernel data
//! path (needs root: `ip netns`, veth, AF_PACKET).
//!
//! [`BridgedPorts::create`] makes two namespaces: namespace A holds one veth end per port,
//! namespace B holds the peers, all enslaved to a bridge with ageing time 0, so it floods every
//! frame like a hub and every port also sees unicast frames (`specs/powerlink.md` §8). IPv6 is
//! disabled in both, so no stray neighbour discovery frames appear. Dropping the value deletes
//! both namespaces, and with them every veth and the bridge.

use std::fs::File;
use std::io;
use std::process::Command;
use std::sync::Arc;

use crate::transport::{EthLink, RawSocket};

fn sh(args: &[&str]) -> io::Result<()> {
    let (cmd, rest) = args.split_first().ok_or_else(|| io::Error::other("empty command"))?;
    let out = Command::new(cmd).args(rest).output()?;
    if out.status.success() {
        Ok(())
    } else {
        Err(io::Error::other(format!("{}: {}", args.join(" "), String::from_utf8_lossy(&out.stderr).trim())))
    }
}

/// Two namespaces and a bridge (see the module documentation).
#[derive(Debug)]
pub struct BridgedPorts {
    a: String,
    b: String,
}

impl BridgedPorts {
    /// Creates the namespaces (named after `tag` and the process ID) and one port per name.
    pub fn create(tag: &str, ports: &[&str]) -> io::Result<Self> {
        let id = std::process::id();
        let ns = BridgedPorts { a: format!("motus-{tag}-{id}-a"), b: format!("motus-{tag}-{id}-b") };
        for n in [&ns.a, &ns.b] {
            sh(&["ip", "netns", "add", n])?;
            for key in ["all", "default"] {
                let k = format!("net.ipv6.conf.{key}.disable_ipv6=1");
                sh(&["ip", "netns", "exec", n, "sysctl", "-qw", &k])?;
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
        ])?;
        sh(&["ip", "-n", &ns.b, "link", "set", "br0", "up"])?;
        for p in ports {
            let peer = format!("p{p}");
            sh(&[
                "ip", "-n", &ns.a, "link", "add", p, "type", "veth", "peer", "name", &peer, "netns", &ns.b,
            ])?;
            sh(&["ip", "-n", &ns.b, "link", "set", &peer, "master", "br0"])?;
            sh(&["ip", "-n", &ns.b, "link", "set", &peer, "up"])?;
            sh(&["ip", "-n", &ns.a, "link", "set", p, "up"])?;
        }
        Ok(ns)
    }

    /// Name of namespace A (the one holding the ports).
    pub fn ports_namespace(&self) -> &str {
        &self.a
    }

    /// Opens raw sockets (promiscuous) on `ports` of namespace A, from a thread that enters it.
    pub fn open(&self, ports: &[&str]) -> io::Result<Vec<Arc<dyn EthLink>>> {
        let path = format!("/run/netns/{}", self.a);
        let ports: Vec<String> = ports.iter().map(|s| s.to_string()).collect();
        std::thread::spawn(move || -> io::Result<Vec<Arc<dyn EthLink>>> {
            let f = File::open(&path)?;
            nix::sched::setns(f, nix::sched::CloneFlags::CLONE_NEWNET)?;
            ports.iter().map(|p| Ok(Arc::new(RawSocket::open(p, true)?) as Arc<dyn EthLink>)).collect()
        })
        .join()
        .map_err(|_| io::Error::other("the thread opening the sockets panicked"))?
    }
}

impl Drop for BridgedPorts {
    fn drop(&mut self) {
        for n in [&self.b, &self.a] {
            let _ = Command::new("ip").args(["netns", "del", n]).status();
        }
    }
}

/// True when running as root (what [`BridgedPorts::create`] needs).
pub fn is_root() -> bool {
    nix::unistd::Uid::effective().is_root()
}
