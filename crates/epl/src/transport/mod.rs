//! Ethernet links that carry POWERLINK frames: the [`EthLink`] trait and its implementations.
//!
//! A link is one port on a shared medium (a hub): [`EthLink::send`] puts a whole Ethernet frame
//! (without FCS) on the medium, [`EthLink::recv`] returns the next frame sent by *another* port.
//! A link never returns its own frames (like an AF_PACKET socket bound to EtherType 0x88AB,
//! `specs/powerlink.md` §8), and does no MAC filtering: every port sees every frame, unicast
//! PReq included, as on a hub or a bridge with ageing time 0.

mod faulty;
mod mem;
mod pcap;
pub mod raw;
mod udp;

use std::io;
use std::sync::Arc;
use std::time::{Duration, Instant};

use motus_epl_protocol::MacAddr;

pub use faulty::{FaultConfig, FaultCounters, FaultyLink};
pub use mem::{MemHub, MemLink, MEM_QUEUE_FRAMES};
pub use pcap::PcapLink;
pub use raw::{RawSocket, RingConfig, RingSocket};
pub use udp::{UdpHub, UdpLink};

/// Largest frame a link passes (1514 bytes without FCS, plus room for a VLAN tag).
pub const MAX_FRAME: usize = 1518;

/// Receive counters the kernel keeps for a link's socket (`PACKET_STATISTICS` of a packet
/// socket), cumulative since the link was opened.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct KernelRxStats {
    /// Frames that reached the socket: queued for reading plus dropped.
    pub packets: u64,
    /// Frames the kernel dropped because the socket's receive queue was full.
    pub drops: u64,
}

/// A receiver that a link runs for every frame its port receives, in the sending thread
/// ([`EthLink::attach_receiver`]): the frame's bytes and the time it was sent.
pub type FrameHandler = Box<dyn FnMut(&[u8], Instant) + Send>;

/// One port on an Ethernet medium carrying POWERLINK frames.
pub trait EthLink: Send + Sync {
    /// Sends one Ethernet frame (destination MAC first, no FCS).
    fn send(&self, frame: &[u8]) -> io::Result<()>;
    /// Waits up to `timeout` for a frame from another port; copies it into `buf` and returns
    /// its length and the time it was received, or `None` on time-out. A frame longer than
    /// `buf` is truncated to `buf.len()`.
    fn recv(&self, buf: &mut [u8], timeout: Duration) -> io::Result<Option<(usize, Instant)>>;
    /// This port's MAC address (the source MAC of the frames a node sends on it).
    fn mac(&self) -> MacAddr;
    /// A human-readable description ("udp 127.0.0.1:40001", "raw eth0").
    fn describe(&self) -> String;
    /// Delivers every frame this port receives to `handler`, run in the thread that sent the
    /// frame, instead of queueing it for [`EthLink::recv`]: a node served this way needs no
    /// thread of its own. Only an in-process medium can ([`MemLink`]); every other link
    /// gives the handler back (its node needs a receiving thread: [`serve_on_thread`]).
    ///
    /// # Errors
    /// The link cannot deliver frames in the sending thread: the handler, unused.
    fn attach_receiver(&self, handler: FrameHandler) -> Result<(), FrameHandler> {
        Err(handler)
    }
    /// Ends [`EthLink::attach_receiver`] and drops the handler: frames are queued again.
    fn detach_receiver(&self) {}
    /// Frames lost on this port before the frame [`EthLink::recv`] returned last, cumulative
    /// since the link was opened (the kernel's count carried by that frame, `SO_RXQ_OVFL`):
    /// when it grows between two frames, that many frames were lost between them. `None`: the
    /// link cannot tell.
    fn rx_drops(&self) -> Option<u64> {
        None
    }
    /// The kernel's receive counters of this port's socket. `Ok(None)`: the link has none.
    ///
    /// # Errors
    /// The kernel did not return them.
    fn kernel_rx_stats(&self) -> io::Result<Option<KernelRxStats>> {
        Ok(None)
    }
}

impl<T: EthLink + ?Sized> EthLink for Arc<T> {
    fn send(&self, frame: &[u8]) -> io::Result<()> {
        (**self).send(frame)
    }
    fn recv(&self, buf: &mut [u8], timeout: Duration) -> io::Result<Option<(usize, Instant)>> {
        (**self).recv(buf, timeout)
    }
    fn mac(&self) -> MacAddr {
        (**self).mac()
    }
    fn describe(&self) -> String {
        (**self).describe()
    }
    fn attach_receiver(&self, handler: FrameHandler) -> Result<(), FrameHandler> {
        (**self).attach_receiver(handler)
    }
    fn detach_receiver(&self) {
        (**self).detach_receiver();
    }
    fn rx_drops(&self) -> Option<u64> {
        (**self).rx_drops()
    }
    fn kernel_rx_stats(&self) -> io::Result<Option<KernelRxStats>> {
        (**self).kernel_rx_stats()
    }
}

impl<T: EthLink + ?Sized> EthLink for Box<T> {
    fn send(&self, frame: &[u8]) -> io::Result<()> {
        (**self).send(frame)
    }
    fn recv(&self, buf: &mut [u8], timeout: Duration) -> io::Result<Option<(usize, Instant)>> {
        (**self).recv(buf, timeout)
    }
    fn mac(&self) -> MacAddr {
        (**self).mac()
    }
    fn describe(&self) -> String {
        (**self).describe()
    }
    fn attach_receiver(&self, handler: FrameHandler) -> Result<(), FrameHandler> {
        (**self).attach_receiver(handler)
    }
    fn detach_receiver(&self) {
        (**self).detach_receiver();
    }
    fn rx_drops(&self) -> Option<u64> {
        (**self).rx_drops()
    }
    fn kernel_rx_stats(&self) -> io::Result<Option<KernelRxStats>> {
        (**self).kernel_rx_stats()
    }
}

/// Serves `handler` from a thread of its own called `name` (for a link that cannot deliver in
/// the sending thread, see [`EthLink::attach_receiver`]): every received frame goes to the
/// handler until `stop` is set. A receive error is logged and retried after 5 ms on `clock`
/// (the thread takes part in the clock's time: [`motus_clock::spawn`]).
///
/// # Errors
/// The thread could not be spawned.
pub fn serve_on_thread(
    name: String,
    link: Arc<dyn EthLink>,
    mut handler: FrameHandler,
    stop: Arc<std::sync::atomic::AtomicBool>,
    class: motus_realtime::ThreadClass,
    clock: &motus_clock::SharedClock,
) -> io::Result<std::thread::JoinHandle<()>> {
    let thread_clock = Arc::clone(clock);
    motus_clock::spawn(clock, std::thread::Builder::new().name(name), move || {
        motus_realtime::promote_current_thread(class);
        let mut buf = vec![0u8; MAX_FRAME];
        while !stop.load(std::sync::atomic::Ordering::Relaxed) {
            match link.recv(&mut buf, Duration::from_millis(20)) {
                Ok(Some((n, at))) => handler(buf.get(..n).unwrap_or(&[]), at),
                Ok(None) => {}
                Err(e) => {
                    tracing::warn!(link = %link.describe(), "recv: {e}");
                    thread_clock.sleep(Duration::from_millis(5));
                }
            }
        }
    })
}

/// Receives from a non-blocking socket with a precise time-out: `try_recv` is attempted, and
/// on `WouldBlock` the thread waits in `ppoll` (nanosecond time-out on an hrtimer; a socket's
/// `SO_RCVTIMEO` is rounded up to whole jiffies, several milliseconds, which is useless for a
/// sub-millisecond cycle).
pub(crate) fn recv_with_timeout(
    fd: std::os::fd::BorrowedFd<'_>,
    timeout: Duration,
    mut try_recv: impl FnMut() -> io::Result<usize>,
) -> io::Result<Option<(usize, Instant)>> {
    use nix::poll::{ppoll, PollFd, PollFlags};
    use nix::sys::time::TimeSpec;
    let deadline = Instant::now() + timeout;
    loop {
        match try_recv() {
            Ok(n) => return Ok(Some((n, Instant::now()))),
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => {}
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        }
        let now = Instant::now();
        if now >= deadline {
            return Ok(None);
        }
        let mut fds = [PollFd::new(fd, PollFlags::POLLIN)];
        match ppoll(&mut fds, Some(TimeSpec::from_duration(deadline - now)), None) {
            Ok(_) | Err(nix::errno::Errno::EINTR) => {}
            Err(e) => return Err(e.into()),
        }
    }
}

/// Default number of ports of a UDP segment named by [`open_link`].
pub const UDP_SEGMENT_SLOTS: u16 = 16;

/// Opens a link named on the command line:
/// * `udp://127.0.0.1:3819` joins the UDP segment of [`UDP_SEGMENT_SLOTS`] ports from 3819
///   ([`UdpLink::join_segment`]; no privileges needed; `?slots=N` changes the block size);
/// * `mem://<name>` joins the in-process segment `<name>` ([`MemHub::named`]): for a
///   segment whose nodes all run in this process (no socket, no kernel path);
/// * anything else is a Linux interface name opened as a [`RawSocket`] (needs CAP_NET_RAW),
///   promiscuous when `promiscuous` is set.
pub fn open_link(name: &str, promiscuous: bool) -> io::Result<Arc<dyn EthLink>> {
    if let Some(rest) = name.strip_prefix("udp://") {
        let (addr, query) = rest.split_once('?').unwrap_or((rest, ""));
        let base: std::net::SocketAddr = addr.parse().map_err(|e| {
            io::Error::new(io::ErrorKind::InvalidInput, format!("{name}: not an address:port ({e})"))
        })?;
        let mut slots = UDP_SEGMENT_SLOTS;
        for kv in query.split('&').filter(|s| !s.is_empty()) {
            match kv.split_once('=') {
                Some(("slots", v)) => {
                    slots = v.parse().ok().filter(|n| *n >= 2).ok_or_else(|| {
                        io::Error::new(io::ErrorKind::InvalidInput, format!("{name}: slots must be 2..65535"))
                    })?;
                }
                _ => {
                    return Err(io::Error::new(
                        io::ErrorKind::InvalidInput,
                        format!("{name}: unknown option {kv:?} (known: slots=N)"),
                    ))
                }
            }
        }
        return Ok(Arc::new(UdpLink::join_segment(base, slots)?));
    }
    if let Some(hub) = name.strip_prefix("mem://") {
        if hub.is_empty() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("{name}: the segment needs a name"),
            ));
        }
        return Ok(Arc::new(MemHub::named(hub).connect()));
    }
    Ok(Arc::new(RawSocket::open(name, promiscuous)?))
}
