//! [`UdpLink`]: Ethernet frames carried in UDP datagrams on the loopback interface, so a whole
//! segment runs without privileges.
//!
//! # Design
//! Each port binds its own UDP socket on 127.0.0.1 (port 0: the kernel picks a free one) and
//! sends every frame as one datagram to **every other port of the same segment** (a hub: no MAC
//! filtering, no echo to the sender). The datagram holds the whole Ethernet frame (MACs,
//! EtherType 0x88AB, EPL part), not only the EPL part that Wireshark's UDP 3819 dissector
//! expects: unicast PReq keep their destination MAC, and a [`crate::PcapLink`] around a
//! `UdpLink` records exactly the Ethernet frames a real segment would carry.
//!
//! Ports of one process share a [`UdpHub`] (a list of member addresses; a port that joins late,
//! such as a monitor, is seen by the others from their next send). Ports in different processes
//! use [`UdpLink::bind`] with an explicit peer list, or [`UdpLink::join_segment`]: a segment is a
//! block of consecutive UDP ports (`base .. base + slots`); each port binds the first free one
//! and sends to all the others (a send to a free slot is refused by the kernel and ignored), so
//! `motus sim epl`, `motus epl monitor` and `motus safety run` in three processes see each
//! other's frames with nothing to configure but the base port.
//!
//! Each port has a locally administered MAC `02:00:7f:00:PP:PP` (PP = its UDP port).

use std::io;
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4, UdpSocket};
use std::os::fd::AsFd;
use std::sync::{Arc, PoisonError, RwLock};
use std::time::{Duration, Instant};

use motus_epl_protocol::MacAddr;

use super::{recv_with_timeout, EthLink};

/// Peers of a [`UdpLink`]: a shared hub or a fixed list.
#[derive(Debug, Clone)]
enum Peers {
    Hub(Arc<RwLock<Vec<SocketAddr>>>),
    Fixed(Vec<SocketAddr>),
}

/// An in-process UDP "hub": every [`UdpLink`] made by [`UdpHub::connect`] sends each frame to
/// every other member.
#[derive(Debug, Clone, Default)]
pub struct UdpHub {
    members: Arc<RwLock<Vec<SocketAddr>>>,
}

impl UdpHub {
    /// An empty hub.
    pub fn new() -> Self {
        Self::default()
    }

    /// Binds a new port on 127.0.0.1 and adds it to the hub.
    pub fn connect(&self) -> io::Result<UdpLink> {
        let socket = UdpSocket::bind(SocketAddrV4::new(Ipv4Addr::LOCALHOST, 0))?;
        let local = socket.local_addr()?;
        self.members.write().unwrap_or_else(PoisonError::into_inner).push(local);
        UdpLink::from_socket(socket, Peers::Hub(Arc::clone(&self.members)))
    }

    /// Addresses of the members.
    pub fn members(&self) -> Vec<SocketAddr> {
        self.members.read().unwrap_or_else(PoisonError::into_inner).clone()
    }
}

/// One port of a UDP-carried Ethernet segment (see the module documentation).
#[derive(Debug)]
pub struct UdpLink {
    socket: UdpSocket,
    local: SocketAddr,
    peers: Peers,
    mac: MacAddr,
}

impl UdpLink {
    /// Binds `local` and sends every frame to each address of `peers` (other than `local`).
    pub fn bind(local: SocketAddr, peers: Vec<SocketAddr>) -> io::Result<Self> {
        let socket = UdpSocket::bind(local)?;
        Self::from_socket(socket, Peers::Fixed(peers))
    }

    /// Joins the segment of `slots` consecutive ports starting at `base` (see the module
    /// documentation): binds the first free port of the block; `AddrInUse` when all are taken.
    pub fn join_segment(base: SocketAddr, slots: u16) -> io::Result<Self> {
        let addrs: Vec<SocketAddr> = (0..slots)
            .filter_map(|i| base.port().checked_add(i).map(|p| SocketAddr::new(base.ip(), p)))
            .collect();
        for a in &addrs {
            match UdpSocket::bind(a) {
                Ok(socket) => return Self::from_socket(socket, Peers::Fixed(addrs.clone())),
                Err(e) if e.kind() == io::ErrorKind::AddrInUse => continue,
                Err(e) => return Err(e),
            }
        }
        Err(io::Error::new(
            io::ErrorKind::AddrInUse,
            format!("every port of the UDP segment {base} (+{slots}) is in use"),
        ))
    }

    fn from_socket(socket: UdpSocket, peers: Peers) -> io::Result<Self> {
        let local = socket.local_addr()?;
        socket.set_nonblocking(true)?;
        let [p0, p1] = local.port().to_be_bytes();
        Ok(Self { socket, local, peers, mac: MacAddr([0x02, 0x00, 0x7f, 0x00, p0, p1]) })
    }

    /// The local UDP address.
    pub fn local_addr(&self) -> SocketAddr {
        self.local
    }
}

impl EthLink for UdpLink {
    fn send(&self, frame: &[u8]) -> io::Result<()> {
        let send_all = |peers: &[SocketAddr]| -> io::Result<()> {
            for p in peers.iter().filter(|p| **p != self.local) {
                match self.socket.send_to(frame, p) {
                    // A peer that has gone away is not this port's failure.
                    Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => {}
                    other => {
                        other?;
                    }
                }
            }
            Ok(())
        };
        match &self.peers {
            Peers::Hub(m) => send_all(&m.read().unwrap_or_else(PoisonError::into_inner)),
            Peers::Fixed(v) => send_all(v),
        }
    }

    fn recv(&self, buf: &mut [u8], timeout: Duration) -> io::Result<Option<(usize, Instant)>> {
        recv_with_timeout(self.socket.as_fd(), timeout, || loop {
            match self.socket.recv_from(buf) {
                Ok((n, _)) => return Ok(n),
                // ICMP port unreachable from an earlier send_to: not a receive failure.
                Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => continue,
                Err(e) => return Err(e),
            }
        })
    }

    fn mac(&self) -> MacAddr {
        self.mac
    }

    fn describe(&self) -> String {
        format!("udp {}", self.local)
    }
}
