//! [`RawSocket`]: an AF_PACKET raw socket bound to one Linux interface and EtherType 0x88AB
//! (needs CAP_NET_RAW, i.e. root or a capability).
//!
//! Bound to 0x88AB rather than ETH_P_ALL, the socket receives only POWERLINK frames and not its
//! own transmissions (the kernel loops outgoing frames back only to ETH_P_ALL taps), which is
//! what [`EthLink`] promises. Promiscuous mode (PACKET_ADD_MEMBERSHIP / PACKET_MR_PROMISC, undone
//! when the socket closes) lets a monitor see unicast PReq addressed to other MACs on a real NIC;
//! a veth or bridge port already passes them up to packet sockets.
//!
//! No frame is lost silently: every received frame carries the kernel's count of the frames
//! the socket dropped so far (`SO_RXQ_OVFL`, [`EthLink::rx_drops`]), so a reader knows where
//! frames are missing, and [`EthLink::kernel_rx_stats`] reads the socket's totals
//! (`PACKET_STATISTICS`). [`RawSocket::set_recv_buffer`] enlarges the receive queue.
//!
//! [`RingSocket`] is the same port read through a **TPACKET_V3 receive ring** (`PACKET_RX_RING`,
//! [`ring`]): a ring of blocks (by default 64 MiB: 2048 blocks of 32 KiB, [`RingConfig`])
//! mapped into the process and shared with the kernel, which writes each frame with its time
//! stamp into the current block and hands the block over when it is full or 4 ms after its
//! first frame; the reader copies the frames out and hands the block back. No system call per
//! frame, no per-frame socket buffer (a 60-byte frame takes 144 bytes of ring, against about a
//! kilobyte of `SO_RCVBUF` accounting), so the same memory holds several times more frames and
//! a reader that falls behind for seconds loses nothing. When the ring is full the kernel
//! drops frames and counts them (`PACKET_STATISTICS`, `tpacket_stats_v3`); the ring places
//! them where they are missing in the stream ([`EthLink::rx_drops`]), like `SO_RXQ_OVFL`.
//! A frame's time is the kernel's reception time stamp (not the time it was read, which lags
//! by up to a block's 4 ms). The monitor reads raw interfaces this way by default.
//!
//! This is the only module of the crate with `unsafe` (with its submodule [`ring`]): socket2
//! and nix have no safe way to build a `sockaddr_ll` for `bind`, to set PACKET_ADD_MEMBERSHIP,
//! PACKET_VERSION or PACKET_RX_RING, to read PACKET_STATISTICS, or to read a ring of memory
//! that the kernel writes concurrently (mmap, atomic block status, bounded copies out).
#![allow(unsafe_code)]

pub mod ring;

use std::io::{self, IoSliceMut};
use std::mem::{size_of, zeroed};
use std::os::fd::{AsFd, AsRawFd, BorrowedFd};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

use motus_epl_protocol::{MacAddr, ETHERTYPE_EPL};
use nix::sys::socket::{self as nixsock, sockopt, ControlMessageOwned, MsgFlags};
use socket2::{Domain, SockAddr, Socket, Type};

use super::{recv_with_timeout, EthLink, KernelRxStats};
pub use ring::{RingConfig, RingSocket};

/// The kernel's drop count as carried by the received frames: a wrapping 32-bit counter,
/// extended to 64 bits.
#[derive(Debug, Default)]
struct DropCount {
    raw: u32,
    total: u64,
}

/// A raw Ethernet port on a Linux interface (see the module documentation).
#[derive(Debug)]
pub struct RawSocket {
    socket: Socket,
    interface: String,
    ifindex: u32,
    mac: MacAddr,
    drops: Mutex<DropCount>,
    kernel: Mutex<KernelRxStats>,
}

impl RawSocket {
    /// Opens a raw socket on `interface` for EtherType 0x88AB; `promiscuous` also receives
    /// unicast frames for other MACs. The interface is looked up in the network namespace of
    /// the calling thread, and the socket stays in that namespace.
    pub fn open(interface: &str, promiscuous: bool) -> io::Result<Self> {
        let (socket, ifindex, ifindex_c) = packet_socket(interface)?;
        nixsock::setsockopt(&socket, sockopt::RxqOvfl, &1).map_err(io::Error::from)?;
        bind_epl(&socket, ifindex_c)?;
        socket.set_nonblocking(true)?;
        if promiscuous {
            set_promiscuous(&socket, ifindex_c)?;
        }
        let mac = interface_mac(interface)?;
        Ok(Self {
            socket,
            interface: interface.to_owned(),
            ifindex,
            mac,
            drops: Mutex::new(DropCount::default()),
            kernel: Mutex::new(KernelRxStats::default()),
        })
    }

    /// The interface index.
    pub fn ifindex(&self) -> u32 {
        self.ifindex
    }

    /// Asks for a receive queue of `bytes` (`SO_RCVBUFFORCE` when permitted, CAP_NET_ADMIN,
    /// else `SO_RCVBUF`, capped by `net.core.rmem_max`); returns the size the kernel granted
    /// (it doubles the request for its bookkeeping).
    ///
    /// # Errors
    /// The kernel refused both options.
    pub fn set_recv_buffer(&self, bytes: usize) -> io::Result<usize> {
        if nixsock::setsockopt(&self.socket, sockopt::RcvBufForce, &bytes).is_err() {
            self.socket.set_recv_buffer_size(bytes)?;
        }
        self.socket.recv_buffer_size()
    }

    /// One non-blocking receive with the drop count of the frame.
    fn recv_once(&self, buf: &mut [u8]) -> io::Result<usize> {
        let mut cmsg = nix::cmsg_space!(u32);
        let mut iov = [IoSliceMut::new(buf)];
        let msg =
            nixsock::recvmsg::<()>(self.socket.as_raw_fd(), &mut iov, Some(&mut cmsg), MsgFlags::empty())
                .map_err(io::Error::from)?;
        // No SO_RXQ_OVFL message: the socket has dropped nothing yet.
        let mut raw = 0u32;
        for c in msg.cmsgs().map_err(io::Error::from)? {
            if let ControlMessageOwned::RxqOvfl(n) = c {
                raw = n;
            }
        }
        let n = msg.bytes;
        let mut d = self.drops.lock().unwrap_or_else(PoisonError::into_inner);
        let delta = raw.wrapping_sub(d.raw);
        d.raw = raw;
        d.total += u64::from(delta);
        Ok(n)
    }
}

/// A packet socket for `interface` (looked up in the calling thread's network namespace) with
/// protocol 0: it receives nothing until [`bind_epl`] names the EtherType and the interface (a
/// socket created with the EtherType would queue that EtherType from every interface until
/// then). Returns the socket and the interface index (unsigned and as `sockaddr_ll` wants it).
fn packet_socket(interface: &str) -> io::Result<(Socket, u32, i32)> {
    let ifindex = nix::net::if_::if_nametoindex(interface)
        .map_err(|e| io::Error::new(io::ErrorKind::NotFound, format!("interface {interface:?}: {e}")))?;
    let socket = Socket::new(Domain::PACKET, Type::RAW, None).map_err(|e| {
        if e.kind() == io::ErrorKind::PermissionDenied {
            io::Error::new(e.kind(), format!("raw socket on {interface}: {e} (needs root or CAP_NET_RAW)"))
        } else {
            e
        }
    })?;
    let ifindex_c = i32::try_from(ifindex)
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "interface index out of range"))?;
    Ok((socket, ifindex, ifindex_c))
}

/// Binds a packet socket to EtherType 0x88AB on the interface `ifindex`.
fn bind_epl(socket: &Socket, ifindex: i32) -> io::Result<()> {
    let proto_be = ETHERTYPE_EPL.to_be();
    // SAFETY: `try_init` hands us zeroed storage of `sockaddr_storage` size, which is larger
    // than and suitably aligned for `sockaddr_ll`; we write a fully initialised
    // `sockaddr_ll` into it and report exactly its size as the address length.
    let ((), addr) = unsafe {
        SockAddr::try_init(|storage, len| {
            let mut ll: libc::sockaddr_ll = zeroed();
            ll.sll_family = libc::AF_PACKET as libc::sa_family_t;
            ll.sll_protocol = proto_be;
            ll.sll_ifindex = ifindex;
            std::ptr::write(storage.cast::<libc::sockaddr_ll>(), ll);
            *len = size_of::<libc::sockaddr_ll>() as libc::socklen_t;
            Ok(())
        })
    }?;
    socket.bind(&addr)
}

/// A plain C structure the kernel fills for `getsockopt(SOL_PACKET, ...)`: every bit
/// pattern of its size is a valid value.
///
/// # Safety
/// Implement only for `#[repr(C)]` structures of integers (the `libc` packet statistics).
pub(super) unsafe trait PacketOption: Copy {}

// SAFETY: `tpacket_stats` is `#[repr(C)]` with two `c_uint` fields.
unsafe impl PacketOption for libc::tpacket_stats {}
// SAFETY: `tpacket_stats_v3` is `#[repr(C)]` with three `c_uint` fields.
unsafe impl PacketOption for libc::tpacket_stats_v3 {}

/// Reads the SOL_PACKET option `name` of the packet socket `fd` into a `T` that starts as
/// `value` (PACKET_STATISTICS: reads and resets the counters).
pub(super) fn packet_option<T: PacketOption>(
    fd: BorrowedFd<'_>,
    name: libc::c_int,
    mut value: T,
) -> io::Result<T> {
    let mut len = size_of::<T>() as libc::socklen_t;
    // SAFETY: `fd` is an open packet socket; `value` is a live, writable `T` (a plain C
    // structure of integers, `PacketOption`) and `len` holds its exact size, so the kernel
    // writes at most that many bytes into it, and any bytes it writes form a valid `T`.
    let rc = unsafe {
        libc::getsockopt(
            fd.as_raw_fd(),
            libc::SOL_PACKET,
            name,
            std::ptr::addr_of_mut!(value).cast::<libc::c_void>(),
            &mut len,
        )
    };
    if rc == 0 {
        Ok(value)
    } else {
        Err(io::Error::last_os_error())
    }
}

/// Reads and resets the socket's PACKET_STATISTICS (frames queued plus dropped, and dropped,
/// since the last read).
fn packet_statistics(socket: &Socket) -> io::Result<libc::tpacket_stats> {
    packet_option(socket.as_fd(), libc::PACKET_STATISTICS, libc::tpacket_stats { tp_packets: 0, tp_drops: 0 })
}

/// Sends `frame` whole on `socket` (a short send is an error).
pub(super) fn send_frame(socket: &Socket, frame: &[u8]) -> io::Result<()> {
    let n = socket.send(frame)?;
    if n == frame.len() {
        Ok(())
    } else {
        Err(io::Error::new(io::ErrorKind::WriteZero, format!("sent {n} of {} bytes", frame.len())))
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
        send_frame(&self.socket, frame)
    }

    fn recv(&self, buf: &mut [u8], timeout: Duration) -> io::Result<Option<(usize, Instant)>> {
        recv_with_timeout(self.socket.as_fd(), timeout, || self.recv_once(buf))
    }

    fn rx_drops(&self) -> Option<u64> {
        Some(self.drops.lock().unwrap_or_else(PoisonError::into_inner).total)
    }

    fn kernel_rx_stats(&self) -> io::Result<Option<KernelRxStats>> {
        // The kernel resets its counters on every read: keep the totals here.
        let mut k = self.kernel.lock().unwrap_or_else(PoisonError::into_inner);
        let st = packet_statistics(&self.socket)?;
        k.packets += u64::from(st.tp_packets);
        k.drops += u64::from(st.tp_drops);
        Ok(Some(*k))
    }

    fn mac(&self) -> MacAddr {
        self.mac
    }

    fn describe(&self) -> String {
        format!("raw {} (ifindex {}, {})", self.interface, self.ifindex, self.mac)
    }
}
