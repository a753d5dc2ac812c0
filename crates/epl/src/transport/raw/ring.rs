//! [`RingSocket`]: an AF_PACKET socket that receives through a TPACKET_V3 ring (see the
//! documentation of the parent module, [`super`], for what the ring is and why it needs
//! `unsafe`).
//!
//! The ring is `blocks` blocks of `block_size` bytes, mapped into this process and shared with
//! the kernel. A block belongs either to the kernel (`TP_STATUS_KERNEL`), which fills it with
//! frames, or to user space (`TP_STATUS_USER`), once the kernel has closed it: full, or
//! [`RingConfig::block_timeout_ms`] after its first frame. The reader walks the blocks in ring
//! order, copies each frame out and hands the block back when all its frames are read.
//!
//! **Drops.** The kernel drops a frame when the block it should go to still belongs to the
//! reader: when the ring is full (it then "freezes" until that block comes back) and, rarely,
//! when a frame arrives while another CPU closes a block of a ring at least three quarters
//! full. Either way the lost frames sit at a block boundary. The kernel counts them
//! (`PACKET_STATISTICS`, `tpacket_stats_v3`, reset by each read) and flags each block it closes
//! while that count is not zero (`TP_STATUS_LOSING`). The ring reads the count when it opens a
//! flagged block closed since the last read (the frames were lost just before that block) and
//! in [`EthLink::kernel_rx_stats`]; drops read there go before the first flagged block closed
//! since the previous read, else before the block the kernel fills now, else (ring full)
//! before the refill of the block being read. They enter [`EthLink::rx_drops`] when that block
//! is opened, so a reader sees them where the frames are missing. Exact when the losses
//! between two reads of the count are at one boundary (one freeze, or one block closed late);
//! several are all placed at the first. The totals are always exact.
#![allow(unsafe_code)]

use std::io;
use std::mem::{offset_of, size_of};
use std::os::fd::{AsFd, AsRawFd, BorrowedFd};
use std::ptr::NonNull;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant, SystemTime};

use motus_epl_protocol::MacAddr;
use socket2::Socket;

use super::{bind_epl, interface_mac, packet_option, packet_socket, send_frame, set_promiscuous};
use crate::transport::{EthLink, KernelRxStats};

/// TPACKET_V3 does not cut the ring into frames, but the kernel checks that `tp_frame_nr`
/// frames of this size fill the blocks exactly.
const FRAME_SIZE: u32 = 2048;

/// Size and timing of a [`RingSocket`]'s ring.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RingConfig {
    /// Bytes per block: a power of two, at least one page and [`RingConfig::MIN_BLOCK_SIZE`].
    pub block_size: u32,
    /// Blocks in the ring (at least 2).
    pub blocks: u32,
    /// Time after which the kernel hands over a block that is not full, in milliseconds (at
    /// least 1): the most a frame waits in the ring on a quiet link.
    pub block_timeout_ms: u32,
}

impl RingConfig {
    /// Block size of [`RingConfig::with_mib`]: 32 KiB (about 200 minimal frames).
    pub const BLOCK_SIZE: u32 = 32 << 10;
    /// Smallest block accepted (4 KiB).
    pub const MIN_BLOCK_SIZE: u32 = 4 << 10;
    /// Default ring size in MiB.
    pub const DEFAULT_MIB: u32 = 64;
    /// Default [`RingConfig::block_timeout_ms`].
    pub const BLOCK_TIMEOUT_MS: u32 = 4;
    /// Largest ring, in bytes (the kernel wants the ring's size in 32 bits).
    pub const MAX_BYTES: u64 = u32::MAX as u64;

    /// A ring of `mib` MiB in blocks of [`RingConfig::BLOCK_SIZE`] (or a page, if larger),
    /// handed over after [`RingConfig::BLOCK_TIMEOUT_MS`]; at least two blocks.
    pub fn with_mib(mib: u32) -> Self {
        let block_size = Self::BLOCK_SIZE.max(page_size());
        let bytes = u64::from(mib) << 20;
        let blocks = u32::try_from(bytes / u64::from(block_size)).unwrap_or(u32::MAX).max(2);
        Self { block_size, blocks, block_timeout_ms: Self::BLOCK_TIMEOUT_MS }
    }

    /// The ring's size in bytes.
    pub fn bytes(&self) -> u64 {
        u64::from(self.block_size) * u64::from(self.blocks)
    }

    /// Checks the layout (see the fields' documentation).
    ///
    /// # Errors
    /// `InvalidInput`, naming the field at fault.
    pub fn validate(&self) -> io::Result<()> {
        let bad = |what: String| Err(io::Error::new(io::ErrorKind::InvalidInput, what));
        let page = page_size();
        if !self.block_size.is_power_of_two()
            || self.block_size < page
            || self.block_size < Self::MIN_BLOCK_SIZE
        {
            return bad(format!(
                "ring block size {}: must be a power of two of at least {} bytes",
                self.block_size,
                page.max(Self::MIN_BLOCK_SIZE)
            ));
        }
        if self.blocks < 2 {
            return bad(format!("ring of {} blocks: needs at least 2", self.blocks));
        }
        if self.bytes() > Self::MAX_BYTES {
            return bad(format!("ring of {} bytes: at most {} bytes", self.bytes(), Self::MAX_BYTES));
        }
        if self.block_timeout_ms == 0 {
            return bad("ring block time-out 0 ms: must be at least 1 ms".into());
        }
        Ok(())
    }
}

impl Default for RingConfig {
    fn default() -> Self {
        Self::with_mib(Self::DEFAULT_MIB)
    }
}

/// The system's page size (4096 if unknown).
fn page_size() -> u32 {
    // SAFETY: sysconf reads a system constant; it has no preconditions.
    let n = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    u32::try_from(n).ok().filter(|&p| p > 0).unwrap_or(4096)
}

/// A block closed by the kernel and not yet opened by the reader.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Closed {
    block: usize,
    /// The kernel's sequence number of the block (one per block filled, from 1).
    seq: u64,
}

/// The ring as seen just before a read of the kernel's counters, from the block read next
/// (after the one being read, if any) in ring order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct Scan {
    /// The first closed block.
    first: Option<Closed>,
    /// The first closed block flagged `TP_STATUS_LOSING` and closed since the previous read.
    first_losing: Option<Closed>,
    /// The newest closed block's sequence number.
    newest: Option<u64>,
    /// The first block the kernel owns, after the closed ones (`None`: the ring is full).
    kernel: Option<usize>,
}

/// Drops waiting for block `block` to be opened with a sequence number of at least `min_seq`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Waiting {
    block: usize,
    min_seq: u64,
    drops: u64,
}

/// Where the kernel's drops go in the stream of frames (see the module documentation).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
struct DropPlacement {
    waiting: Vec<Waiting>,
    /// Drops placed before the frames returned so far.
    placed: u64,
    /// The newest block (sequence number) known closed at the last read of the count.
    seen_seq: u64,
}

impl DropPlacement {
    /// Whether opening a block calls for a read of the count: it is flagged and was closed
    /// since the last read (its flag then means frames lost just before it).
    fn read_at_open(&self, seq: u64, losing: bool) -> bool {
        losing && seq > self.seen_seq
    }

    /// `drops` just read; `scan` was taken just before the read, while the reader held
    /// `held` (block, sequence number) if any, and had opened `last_opened` last.
    fn add(&mut self, drops: u64, scan: &Scan, held: Option<(usize, u64)>, last_opened: u64) {
        if drops > 0 {
            let (block, min_seq) = if let Some(c) = scan.first_losing {
                // Lost just before this block: its current content.
                (Some(c.block), c.seq)
            } else if let Some(k) = scan.kernel {
                // Lost before the block the kernel fills now (or resumes at).
                (Some(k), 0)
            } else if let Some((b, seq)) = held {
                // Ring full: the kernel waits for the block being read; lost before its refill.
                (Some(b), seq + 1)
            } else {
                // Ring full, nothing held: the kernel waits for the block read next.
                scan.first.map_or((None, 0), |c| (Some(c.block), c.seq + 1))
            };
            match block {
                Some(block) => self.waiting.push(Waiting { block, min_seq, drops }),
                None => self.placed += drops,
            }
        }
        let newest = scan.newest.unwrap_or(0).max(last_opened);
        self.seen_seq = self.seen_seq.max(newest);
    }

    /// Block `block` is opened with sequence number `seq`: the drops waiting for it are placed
    /// before its first frame.
    fn open(&mut self, block: usize, seq: u64) {
        let mut placed = 0;
        self.waiting.retain(|w| {
            let due = w.block == block && seq >= w.min_seq;
            if due {
                placed += w.drops;
            }
            !due
        });
        self.placed += placed;
    }
}

/// The ring's memory, unmapped when dropped.
#[derive(Debug)]
struct Mapping {
    base: NonNull<u8>,
    len: usize,
}

// SAFETY: the mapping is memory owned by this value alone (no other pointer into it escapes
// the ring's methods), so it may move to another thread; `RingSocket` keeps it in a `Mutex`,
// so only one thread at a time reads or hands back blocks.
unsafe impl Send for Mapping {}

impl Drop for Mapping {
    fn drop(&mut self) {
        // SAFETY: `base` and `len` are exactly what `mmap` returned and this is the only unmap;
        // no reference into the mapping outlives the ring's methods.
        unsafe {
            libc::munmap(self.base.as_ptr().cast::<libc::c_void>(), self.len);
        }
    }
}

/// The block being read.
#[derive(Debug, Clone, Copy)]
struct OpenBlock {
    /// Offset of the next frame's header from the block's start.
    offset: usize,
    /// Frames not yet read.
    remaining: u32,
    /// The block's sequence number.
    seq: u64,
    /// The clocks read when the block was opened: its frames' times.
    clock: ClockPair,
}

/// The reader's side of the ring.
#[derive(Debug)]
struct RingState {
    map: Mapping,
    block_size: usize,
    blocks: usize,
    /// The block read now or next, in ring order.
    next: usize,
    /// `next` once it belongs to user space and its header was read.
    open: Option<OpenBlock>,
    /// Sequence number of the block opened last (0: none yet).
    last_opened: u64,
    drops: DropPlacement,
    kernel: KernelRxStats,
    freezes: u64,
}

/// Offset of a block's `block_status` (a `u32`, 4-byte aligned) from the block's start.
const BLOCK_STATUS: usize =
    offset_of!(libc::tpacket_block_desc, hdr) + offset_of!(libc::tpacket_hdr_v1, block_status);

impl RingState {
    /// The start of block `i` (`i < blocks`).
    fn block(&self, i: usize) -> *mut u8 {
        debug_assert!(i < self.blocks);
        // SAFETY: `i < blocks`, so the offset `i * block_size` lies inside the mapping of
        // `blocks * block_size` bytes.
        unsafe { self.map.base.as_ptr().add(i * self.block_size) }
    }

    /// The status word of block `i`, shared with the kernel.
    fn status(&self, i: usize) -> &AtomicU32 {
        // SAFETY: blocks start on page boundaries, so `block_status` (offset 8) is a 4-byte
        // aligned `u32` inside the mapping, which lives as long as `self`. The kernel updates it
        // with plain aligned 32-bit stores after a write barrier; we only touch it atomically.
        unsafe { AtomicU32::from_ptr(self.block(i).add(BLOCK_STATUS).cast::<u32>()) }
    }

    /// The status and header of block `i`, if it belongs to user space.
    fn closed_header(&self, i: usize) -> Option<(u32, libc::tpacket_hdr_v1)> {
        // Acquire: the kernel's writes to the block happened before it set TP_STATUS_USER.
        let status = self.status(i).load(Ordering::Acquire);
        if status & libc::TP_STATUS_USER == 0 {
            return None;
        }
        // SAFETY: the block belongs to user space (TP_STATUS_USER seen with Acquire), so the
        // kernel does not write it until we hand it back; the block descriptor lies at the
        // block's start, inside the mapping (a block is at least 4 KiB).
        let desc = unsafe { std::ptr::read(self.block(i).cast::<libc::tpacket_block_desc>()) };
        // SAFETY: `bh1` is the only member of the union, the one TPACKET_V3 fills.
        Some((status, unsafe { desc.hdr.bh1 }))
    }

    /// Opens block `next` if the kernel has handed it over; true when a block is open.
    fn try_open(&mut self, fd: BorrowedFd<'_>) -> io::Result<bool> {
        if self.open.is_some() {
            return Ok(true);
        }
        let Some((status, h)) = self.closed_header(self.next) else { return Ok(false) };
        if self.drops.read_at_open(h.seq_num, status & libc::TP_STATUS_LOSING != 0) {
            self.read_stats(fd)?;
        }
        self.drops.open(self.next, h.seq_num);
        self.last_opened = h.seq_num;
        self.open = Some(OpenBlock {
            offset: h.offset_to_first_pkt as usize,
            remaining: h.num_pkts,
            seq: h.seq_num,
            clock: ClockPair::now(),
        });
        Ok(true)
    }

    /// Hands block `next` back to the kernel and moves to the following one.
    fn release(&mut self) {
        // Release: our reads of the block happen before the kernel may refill it.
        self.status(self.next).store(libc::TP_STATUS_KERNEL, Ordering::Release);
        self.next = (self.next + 1) % self.blocks;
        self.open = None;
    }

    /// Looks at the closed blocks after the one being read (see [`Scan`]).
    fn scan(&self) -> Scan {
        let (start, count) =
            if self.open.is_some() { (self.next + 1, self.blocks - 1) } else { (self.next, self.blocks) };
        let mut scan = Scan::default();
        for k in 0..count {
            let block = (start + k) % self.blocks;
            let Some((status, h)) = self.closed_header(block) else {
                scan.kernel = Some(block);
                return scan;
            };
            let c = Closed { block, seq: h.seq_num };
            scan.first.get_or_insert(c);
            if scan.first_losing.is_none()
                && status & libc::TP_STATUS_LOSING != 0
                && h.seq_num > self.drops.seen_seq
            {
                scan.first_losing = Some(c);
            }
            scan.newest = Some(h.seq_num);
        }
        scan
    }

    /// Reads (and so resets) the kernel's counters and places the new drops.
    fn read_stats(&mut self, fd: BorrowedFd<'_>) -> io::Result<()> {
        // The scan comes first: a block closed after the read carries a flag for later drops.
        let scan = self.scan();
        let st = packet_statistics_v3(fd)?;
        self.kernel.packets += u64::from(st.tp_packets);
        self.kernel.drops += u64::from(st.tp_drops);
        self.freezes += u64::from(st.tp_freeze_q_cnt);
        let held = self.open.map(|o| (self.next, o.seq));
        self.drops.add(u64::from(st.tp_drops), &scan, held, self.last_opened);
        Ok(())
    }

    /// Copies the next frame of the ring into `buf`; `None` when no block is ready.
    fn next_frame(&mut self, fd: BorrowedFd<'_>, buf: &mut [u8]) -> io::Result<Option<(usize, Instant)>> {
        loop {
            if !self.try_open(fd)? {
                return Ok(None);
            }
            let Some(open) = self.open else { return Ok(None) };
            if open.remaining == 0 {
                self.release();
                continue;
            }
            let (n, at, step) = self.read_frame(open.offset, &open.clock, buf)?;
            self.open = Some(OpenBlock {
                offset: open.offset.saturating_add(step),
                remaining: open.remaining - 1,
                ..open
            });
            return Ok(Some((n, at)));
        }
    }

    /// Copies the frame whose header is at `offset` in block `next` into `buf`: its length
    /// (truncated to `buf`), its time (from `clock`, read when the block was opened) and the
    /// offset of the following frame's header.
    fn read_frame(
        &mut self,
        offset: usize,
        clock: &ClockPair,
        buf: &mut [u8],
    ) -> io::Result<(usize, Instant, usize)> {
        let hdr_end = offset.checked_add(size_of::<libc::tpacket3_hdr>());
        if hdr_end.map_or(true, |e| e > self.block_size) {
            return Err(self.corrupt(offset));
        }
        // SAFETY: block `next` belongs to user space (it is open); the header lies inside the
        // block (checked just above); `read_unaligned` copies it without forming a reference.
        let h = unsafe {
            std::ptr::read_unaligned(self.block(self.next).add(offset).cast::<libc::tpacket3_hdr>())
        };
        let start = offset.checked_add(usize::from(h.tp_mac));
        let end = start.and_then(|s| s.checked_add(h.tp_snaplen as usize));
        let (Some(start), Some(end)) = (start, end) else { return Err(self.corrupt(offset)) };
        if end > self.block_size {
            return Err(self.corrupt(offset));
        }
        let n = (end - start).min(buf.len());
        // SAFETY: `start..start + n` lies inside block `next` (checked above), which belongs to
        // user space; `buf` holds at least `n` bytes and cannot overlap the mapping.
        unsafe {
            std::ptr::copy_nonoverlapping(self.block(self.next).add(start), buf.as_mut_ptr(), n);
        }
        let at = clock.instant_of(h.tp_sec, h.tp_nsec);
        Ok((n, at, h.tp_next_offset as usize))
    }

    /// A frame header out of its block (never seen: the kernel wrote it): the rest of the block
    /// is skipped, and the error says so.
    fn corrupt(&mut self, offset: usize) -> io::Error {
        let lost = self.open.map_or(0, |o| o.remaining);
        if let Some(o) = self.open.as_mut() {
            o.remaining = 0;
        }
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!(
                "ring block {}: frame at offset {offset} runs past the block; {lost} frames skipped",
                self.next
            ),
        )
    }
}

/// The monotonic clock ([`Instant`]) and the wall clock (CLOCK_REALTIME, the clock of the
/// kernel's time stamps) read at one moment, to turn time stamps into instants.
#[derive(Debug, Clone, Copy)]
struct ClockPair {
    mono: Instant,
    wall: SystemTime,
}

impl ClockPair {
    /// Largest gap between the two wall-clock readings around the monotonic one that is taken
    /// as one moment (a larger gap: the thread was interrupted; read again).
    const MAX_GAP: Duration = Duration::from_micros(20);

    /// Reads both clocks: the wall clock before and after the monotonic clock, up to 4 times
    /// until the two wall readings are at most [`ClockPair::MAX_GAP`] apart (else the closest).
    fn now() -> Self {
        let read = || {
            let before = SystemTime::now();
            let mono = Instant::now();
            let gap = SystemTime::now().duration_since(before).unwrap_or(Duration::ZERO);
            (Self { mono, wall: before + gap / 2 }, gap)
        };
        let mut best = read();
        for _ in 0..3 {
            if best.1 <= Self::MAX_GAP {
                break;
            }
            let next = read();
            if next.1 < best.1 {
                best = next;
            }
        }
        best.0
    }

    /// The instant of the kernel time stamp `sec`.`nsec` (never later than the reading).
    fn instant_of(&self, sec: u32, nsec: u32) -> Instant {
        let stamp = SystemTime::UNIX_EPOCH + Duration::new(u64::from(sec), nsec.min(999_999_999));
        let age = self.wall.duration_since(stamp).unwrap_or(Duration::ZERO);
        self.mono.checked_sub(age).unwrap_or(self.mono)
    }
}

/// Reads and resets a TPACKET_V3 socket's PACKET_STATISTICS.
fn packet_statistics_v3(fd: BorrowedFd<'_>) -> io::Result<libc::tpacket_stats_v3> {
    let zero = libc::tpacket_stats_v3 { tp_packets: 0, tp_drops: 0, tp_freeze_q_cnt: 0 };
    packet_option(fd, libc::PACKET_STATISTICS, zero)
}

/// Sets a `SOL_PACKET` option to the bytes of `value`: a C type without padding (`c_int`,
/// `tpacket_req3`), as the option expects.
fn set_packet_option<T: Copy>(socket: &Socket, name: libc::c_int, value: &T) -> io::Result<()> {
    // SAFETY: the fd is an open packet socket owned by `socket`; `value` is a live, initialised
    // `T` without padding and we pass its exact size, so the kernel reads only its bytes.
    let rc = unsafe {
        libc::setsockopt(
            socket.as_raw_fd(),
            libc::SOL_PACKET,
            name,
            std::ptr::from_ref(value).cast::<libc::c_void>(),
            size_of::<T>() as libc::socklen_t,
        )
    };
    if rc == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

/// A raw Ethernet port on a Linux interface that receives through a TPACKET_V3 ring (see the
/// module documentation of [`super`]).
#[derive(Debug)]
pub struct RingSocket {
    // Declared before `socket`: the ring is unmapped before the socket closes.
    ring: Mutex<RingState>,
    socket: Socket,
    interface: String,
    ifindex: u32,
    mac: MacAddr,
    config: RingConfig,
}

impl RingSocket {
    /// Opens a packet socket on `interface` for EtherType 0x88AB with a receive ring laid out
    /// as `config`; `promiscuous` also receives unicast frames for other MACs. The interface
    /// is looked up in the network namespace of the calling thread.
    ///
    /// # Errors
    /// The layout is invalid ([`RingConfig::validate`]), the interface is unknown, the caller
    /// lacks CAP_NET_RAW, or the kernel refused the ring (e.g. out of memory).
    pub fn open(interface: &str, promiscuous: bool, config: RingConfig) -> io::Result<Self> {
        config.validate()?;
        let (socket, ifindex, ifindex_c) = packet_socket(interface)?;
        let ctx = |what: &str, e: io::Error| io::Error::new(e.kind(), format!("{interface}: {what}: {e}"));
        let version = libc::tpacket_versions::TPACKET_V3 as libc::c_int;
        set_packet_option(&socket, libc::PACKET_VERSION, &version).map_err(|e| ctx("TPACKET_V3", e))?;
        let req = libc::tpacket_req3 {
            tp_block_size: config.block_size,
            tp_block_nr: config.blocks,
            tp_frame_size: FRAME_SIZE,
            tp_frame_nr: config.blocks * (config.block_size / FRAME_SIZE),
            tp_retire_blk_tov: config.block_timeout_ms,
            tp_sizeof_priv: 0,
            tp_feature_req_word: 0,
        };
        set_packet_option(&socket, libc::PACKET_RX_RING, &req).map_err(|e| {
            ctx(&format!("receive ring of {} blocks of {} bytes", config.blocks, config.block_size), e)
        })?;
        let len = usize::try_from(config.bytes())
            .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "ring larger than the address space"))?;
        // SAFETY: maps `len` bytes of the socket's ring (exactly its size) at an address the
        // kernel chooses; nothing else refers to that range. Checked for MAP_FAILED below.
        let base = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                len,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_SHARED,
                socket.as_raw_fd(),
                0,
            )
        };
        if base == libc::MAP_FAILED {
            return Err(ctx("mapping the receive ring", io::Error::last_os_error()));
        }
        let base = NonNull::new(base.cast::<u8>())
            .ok_or_else(|| io::Error::other(format!("{interface}: the receive ring was mapped at 0")))?;
        let blocks = config.blocks as usize;
        let ring = RingState {
            map: Mapping { base, len },
            block_size: config.block_size as usize,
            blocks,
            next: 0,
            open: None,
            last_opened: 0,
            drops: DropPlacement::default(),
            kernel: KernelRxStats::default(),
            freezes: 0,
        };
        bind_epl(&socket, ifindex_c)?;
        socket.set_nonblocking(true)?;
        if promiscuous {
            set_promiscuous(&socket, ifindex_c)?;
        }
        let mac = interface_mac(interface)?;
        Ok(Self { ring: Mutex::new(ring), socket, interface: interface.to_owned(), ifindex, mac, config })
    }

    /// The ring's layout.
    pub fn config(&self) -> RingConfig {
        self.config
    }

    /// The interface index.
    pub fn ifindex(&self) -> u32 {
        self.ifindex
    }

    /// Times the ring was full (the kernel froze it until a block came back), as of the last
    /// read of the kernel's counters ([`EthLink::kernel_rx_stats`], or a block handed back).
    pub fn freezes(&self) -> u64 {
        self.lock().freezes
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, RingState> {
        self.ring.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl EthLink for RingSocket {
    /// Sends with a plain `send` on the ring's socket (the ring is for receiving only).
    fn send(&self, frame: &[u8]) -> io::Result<()> {
        send_frame(&self.socket, frame)
    }

    /// The next frame of the ring, with the kernel's time stamp of its reception; waits in
    /// `ppoll` while no block is ready.
    fn recv(&self, buf: &mut [u8], timeout: Duration) -> io::Result<Option<(usize, Instant)>> {
        use nix::poll::{ppoll, PollFd, PollFlags};
        use nix::sys::time::TimeSpec;
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(frame) = self.lock().next_frame(self.socket.as_fd(), buf)? {
                return Ok(Some(frame));
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(None);
            }
            let mut fds = [PollFd::new(self.socket.as_fd(), PollFlags::POLLIN)];
            match ppoll(&mut fds, Some(TimeSpec::from_duration(deadline - now)), None) {
                Ok(_) | Err(nix::errno::Errno::EINTR) => {}
                Err(e) => return Err(e.into()),
            }
            let failed =
                fds.first().and_then(|f| f.revents()).is_some_and(|r| r.contains(PollFlags::POLLERR));
            if failed {
                if let Some(e) = self.socket.take_error()? {
                    return Err(e);
                }
            }
        }
    }

    fn rx_drops(&self) -> Option<u64> {
        Some(self.lock().drops.placed)
    }

    fn kernel_rx_stats(&self) -> io::Result<Option<KernelRxStats>> {
        let mut ring = self.lock();
        ring.read_stats(self.socket.as_fd())?;
        Ok(Some(ring.kernel))
    }

    fn mac(&self) -> MacAddr {
        self.mac
    }

    fn describe(&self) -> String {
        format!(
            "raw {} (ifindex {}, {}; TPACKET_V3 ring of {} blocks of {} KiB)",
            self.interface,
            self.ifindex,
            self.mac,
            self.config.blocks,
            self.config.block_size >> 10
        )
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

    use super::*;

    #[test]
    fn the_default_ring_is_64_mib_of_32_kib_blocks() {
        let c = RingConfig::default();
        assert_eq!(c.bytes(), 64 << 20);
        assert_eq!(c.block_size, RingConfig::BLOCK_SIZE.max(page_size()));
        assert_eq!(c.block_timeout_ms, 4);
        c.validate().unwrap();
        assert_eq!(RingConfig::with_mib(0).blocks, 2, "at least two blocks");
    }

    #[test]
    fn invalid_layouts_are_refused() {
        let ok = RingConfig::with_mib(1);
        for bad in [
            RingConfig { block_size: 3 << 12, ..ok },
            RingConfig { block_size: 1024, ..ok },
            RingConfig { blocks: 1, ..ok },
            RingConfig { block_timeout_ms: 0, ..ok },
            RingConfig { block_size: 1 << 20, blocks: 4096, ..ok },
        ] {
            assert_eq!(bad.validate().unwrap_err().kind(), io::ErrorKind::InvalidInput, "{bad:?}");
        }
    }

    fn closed(block: usize, seq: u64) -> Option<Closed> {
        Some(Closed { block, seq })
    }

    #[test]
    fn drops_of_a_full_ring_wait_for_the_refill_of_the_block_being_read() {
        // 4 blocks; the reader holds block 0 (seq 1), blocks 1..=3 (seq 2..=4) are closed.
        let mut d = DropPlacement::default();
        let full = Scan { first: closed(1, 2), first_losing: None, newest: Some(4), kernel: None };
        d.add(7, &full, Some((0, 1)), 1);
        assert_eq!(d.seen_seq, 4);
        for (b, seq) in [(1, 2), (2, 3), (3, 4)] {
            d.open(b, seq);
            assert_eq!(d.placed, 0, "not before block {b}");
        }
        d.open(0, 5);
        assert_eq!(d.placed, 7, "before the refill of block 0");
        d.open(0, 9);
        assert_eq!(d.placed, 7, "placed once");
        // The same without a block held: the kernel waits for the block read next.
        let mut d = DropPlacement::default();
        d.add(3, &Scan { first: closed(2, 6), first_losing: None, newest: Some(9), kernel: None }, None, 5);
        d.open(2, 6);
        assert_eq!(d.placed, 0);
        d.open(2, 10);
        assert_eq!(d.placed, 3);
    }

    #[test]
    fn drops_go_before_the_first_flagged_block_else_the_kernels_block() {
        let mut d = DropPlacement::default();
        // Blocks 1 (seq 2) and 2 (seq 3, flagged) closed, block 3 being filled.
        let scan = Scan { first: closed(1, 2), first_losing: closed(2, 3), newest: Some(3), kernel: Some(3) };
        d.add(2, &scan, Some((0, 1)), 1);
        d.open(1, 2);
        assert_eq!(d.placed, 0);
        d.open(2, 3);
        assert_eq!(d.placed, 2);
        // Nothing flagged: before the block the kernel fills now.
        d.add(1, &Scan { kernel: Some(3), ..Scan::default() }, Some((2, 3)), 3);
        assert_eq!(d.placed, 2);
        d.open(3, 4);
        assert_eq!(d.placed, 3);
        // A read with no drop places nothing.
        d.add(0, &Scan { kernel: Some(0), ..Scan::default() }, Some((3, 4)), 4);
        assert!(d.waiting.is_empty());
    }

    #[test]
    fn only_a_flag_raised_since_the_last_read_calls_for_a_read() {
        let mut d = DropPlacement::default();
        assert!(d.read_at_open(1, true));
        assert!(!d.read_at_open(1, false));
        // A read when blocks up to seq 5 were closed: their flags are about drops already read.
        d.add(
            0,
            &Scan { first: closed(1, 2), first_losing: None, newest: Some(5), kernel: Some(0) },
            None,
            1,
        );
        assert!(!d.read_at_open(5, true));
        assert!(d.read_at_open(6, true));
    }

    #[test]
    fn a_kernel_time_stamp_becomes_an_instant_in_the_past() {
        let t = SystemTime::now().duration_since(SystemTime::UNIX_EPOCH).unwrap() - Duration::from_secs(2);
        let before = Instant::now();
        let clock = ClockPair::now();
        let at = clock.instant_of(u32::try_from(t.as_secs()).unwrap(), t.subsec_nanos());
        assert!(at < before, "a stamp 2 s old is before now");
        // A stamp from the future (a clock step) is the reading's instant.
        let future = t + Duration::from_secs(3600);
        assert_eq!(clock.instant_of(u32::try_from(future.as_secs()).unwrap(), 0), clock.mono);
    }
}
