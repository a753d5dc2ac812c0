//! [`RawSocket`]: an AF_PACKET raw socket bound to one Linux interface and EtherType 0x88AB
//! (needs CAP_NET_RAW, i.e. root or a capability).
//!
//! Bound to 0x88AB rather than ETH_P_ALL, the socket receives only POWERLINK frames and not its
//! own transmissions (the kernel loops outgoing frames back only to ETH_P_ALL taps), which is
//! what [`EthLink`] promises. Promiscuous mode (PACKET_ADD_MEMBERSHIP / PACKET_MR_PROMISC, undone
//! when the socket closes) lets a monitor see unicast PReq addressed to other MACs on a real NIC;
//! a veth or bridge port already passes them up to packet sockets.
//!
//! This is the only module of the crate with `unsafe`: socket2 and nix have no safe way to build
//! a `sockaddr_ll` for `bind` or to set PACKET_ADD_MEMBERSHIP.
#![allow(unsafe_code)]

use std::io::{self, Read};
use std::mem::{size_of, zeroed};
use std::os::fd::{AsFd, AsRawFd};
use std::time::{Duration, Instant};

use motus_epl_protocol::{MacAddr, ETHERTYPE_EPL};
use socket2::{Domain, Protocol, SockAddr, Socket, Type};

use super::{recv_with_timeout, EthLink};

/// A raw Ethernet port on a Linux interface (see the module documentation).
#[derive(Debug)]
pub struct RawSocket {
    socket: Socket,
    interface: String,
    ifindex: u32,
    mac: MacAddr,
}

impl RawSocket {
    /// Opens a raw socket on `interface` for EtherType 0x88AB; `promiscuous` also receives
    /// unicast frames for other MACs. The interface is looked up in the network namespace of
    /// the calling thread, and the socket stays in that namespace.
    pub fn open(interface: &str, promiscuous: bool) -> io::Result<Self> {
        let ifindex = nix::net::if_::if_nametoindex(interface)
            .map_err(|e| io::Error::new(io::ErrorKind::NotFound, format!("interface {interface:?}: {e}")))?;
        let proto_be = ETHERTYPE_EPL.to_be();
        let socket = Socket::new(Domain::PACKET, Type::RAW, Some(Protocol::from(i32::from(proto_be))))
            .map_err(|e| {
                if e.kind() == io::ErrorKind::PermissionDenied {
                    io::Error::new(
                        e.kind(),
                        format!("raw socket on {interface}: {e} (needs root or CAP_NET_RAW)"),
                    )
                } else {
                    e
                }
            })?;
        let ifindex_c = i32::try_from(ifindex)
            .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "interface index out of range"))?;
        // SAFETY: `try_init` hands us zeroed storage of `sockaddr_storage` size, which is larger
        // than and suitably aligned for `sockaddr_ll`; we write a fully initialised
        // `sockaddr_ll` into it and report exactly its size as the address length.
        let ((), addr) = unsafe {
            SockAddr::try_init(|storage, len| {
                let mut ll: libc::sockaddr_ll = zeroed();
                ll.sll_family = libc::AF_PACKET as libc::sa_family_t;
                ll.sll_protocol = proto_be;
                ll.sll_ifindex = ifindex_c;
                std::ptr::write(storage.cast::<libc::sockaddr_ll>(), ll);
                *len = size_of::<libc::sockaddr_ll>() as libc::socklen_t;
                Ok(())
            })
        }?;
        socket.bind(&addr)?;
        socket.set_nonblocking(true)?;
        if promiscuous {
            set_promiscuous(&socket, ifindex_c)?;
        }
        let mac = interface_mac(interface)?;
        Ok(Self { socket, interface: interface.to_owned(), ifindex, mac })
    }

    /// The interface index.
    pub fn ifindex(&self) -> u32 {
        self.ifindex
    }
}

/// The MAC address of `interface` (from getifaddrs' AF_PACKET entry, in the calling thread's
/// network namespace).
fn interface_mac(interface: &str) -> io::Result<MacAddr> {
    let addrs = nix::ifaddrs::getifaddrs().map_err(io::Error::from)?;
    addrs
        .filter(|a| a.interface_name == interface)
        .find_map(|a| a.address.as_ref().and_then(|s| s.as_link_addr()).and_then(|l| l.addr()))
        .map(MacAddr)
        .ok_or_else(|| io::Error::new(io::ErrorKind::NotFound, format!("no MAC address for {interface}")))
}

fn set_promiscuous(socket: &Socket, ifindex: i32) -> io::Result<()> {
    let mreq = libc::packet_mreq {
        mr_ifindex: ifindex,
        mr_type: libc::PACKET_MR_PROMISC as libc::c_ushort,
        mr_alen: 0,
        mr_address: [0; 8],
    };
    // SAFETY: the fd is an open packet socket owned by `socket`; `mreq` is a valid, initialised
    // `packet_mreq` that lives across the call, and we pass its exact size.
    let rc = unsafe {
        libc::setsockopt(
            socket.as_raw_fd(),
            libc::SOL_PACKET,
            libc::PACKET_ADD_MEMBERSHIP,
            std::ptr::addr_of!(mreq).cast::<libc::c_void>(),
            size_of::<libc::packet_mreq>() as libc::socklen_t,
        )
    };
    if rc == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

impl EthLink for RawSocket {
    fn send(&self, frame: &[u8]) -> io::Result<()> {
        let n = self.socket.send(frame)?;
        if n == frame.len() {
            Ok(())
        } else {
            Err(io::Error::new(io::ErrorKind::WriteZero, format!("sent {n} of {} bytes", frame.len())))
        }
    }

    fn recv(&self, buf: &mut [u8], timeout: Duration) -> io::Result<Option<(usize, Instant)>> {
        recv_with_timeout(self.socket.as_fd(), timeout, || (&self.socket).read(buf))
    }

    fn mac(&self) -> MacAddr {
        self.mac
    }

    fn describe(&self) -> String {
        format!("raw {} (ifindex {}, {})", self.interface, self.ifindex, self.mac)
    }
}
