//! The TPACKET_V3 receive ring ([`RingSocket`]) on veth ports in network namespaces (needs
//! root: skipped with a printed reason otherwise; CI runs as root). Namespace A holds the
//! ports, namespace B their peers on a bridge that floods every frame (`motus_epl::netns`).
//!
//! * `ring_receives_every_frame_in_order`: 50,000 POWERLINK frames sent as fast as possible
//!   from one port arrive on another through the ring, in order and byte for byte, and the
//!   frames received plus the kernel's drops are the frames sent.
//! * `ring_places_drops_where_frames_are_missing`: a burst overflows a small ring that nobody
//!   reads; the drop count grows exactly at the frame after the gap, by the gap's size.
//! * `monitor_on_ring_accounts_for_every_frame`: the monitor on a ring that overflowed marks
//!   the cycle with the gap, counts no miss for it and keeps the segment's cycle numbers.
//!
//! Function only: the drops, the ring's freezes and the kernel's counters are printed, never
//! compared with timing figures.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use motus_epl::netns::{is_root, BridgedPorts};
use motus_epl::{EthLink, Monitor, MonitorConfig, RingConfig, RingSocket};
use motus_epl_protocol::{EplFrame, Flags, MacAddr, Message, NmtState, PRes, PrRs, Soc};

/// One test at a time: they send bursts that would disturb each other on two cores.
fn exclusive() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(PoisonError::into_inner)
}

/// False (and the reason printed) when not root.
fn can_run(test: &str) -> bool {
    if is_root() {
        return true;
    }
    eprintln!("{test}: skipped: needs root (network namespaces, veth, AF_PACKET)");
    false
}

/// Opens a ring on `port` of the namespaces' port side (from a thread that enters it).
fn open_ring(ns: &BridgedPorts, port: &str, config: RingConfig) -> RingSocket {
    let path = format!("/run/netns/{}", ns.ports_namespace());
    let port = port.to_owned();
    std::thread::spawn(move || {
        nix::sched::setns(std::fs::File::open(path).unwrap(), nix::sched::CloneFlags::CLONE_NEWNET).unwrap();
        RingSocket::open(&port, true, config).unwrap()
    })
    .join()
    .unwrap()
}

/// Frames dropped by the kernel's per-CPU input queues (second column of
/// /proc/net/softnet_stat, summed): frames lost before any socket saw them.
fn softnet_drops() -> u64 {
    std::fs::read_to_string("/proc/net/softnet_stat")
        .unwrap_or_default()
        .lines()
        .filter_map(|l| l.split_whitespace().nth(1).and_then(|c| u64::from_str_radix(c, 16).ok()))
        .sum()
}

/// Block time-out of the rings that overflow in a burst: long, so that no block is closed by
/// time-out during the burst. A block closed by the kernel's timer on one CPU while a frame
/// arrives on another, in a ring at least three quarters full, loses that frame (the kernel
/// checks for room without its lock); the ring then places that loss and the freeze's at the
/// first of them (two losses between two reads of the kernel's count), which these tests would
/// report as misplaced drops. A monitor that keeps up never fills the ring that far.
const BURST_TIMEOUT_MS: u32 = 1000;

const MN: MacAddr = MacAddr([2, 0, 0, 0, 0, 240]);
const CN: MacAddr = MacAddr([2, 0, 0, 0, 0, 1]);

/// Frame `i` of a numbered stream: a SoC (RelativeTime `i`) for even `i`, else a PRes of node 1
/// carrying `i`.
fn numbered(i: u64) -> Vec<u8> {
    let frame = if i % 2 == 0 {
        EplFrame::new(MN, MacAddr::SOC, 255, 240, Message::Soc(Soc { relative_time: i, ..Soc::default() }))
    } else {
        let mut payload = i.to_le_bytes().to_vec();
        payload.extend_from_slice(&[0xA5; 8]);
        let pres = PRes {
            nmt_state: NmtState::Operational,
            flags: Flags::RD,
            pr_rs: PrRs::default(),
            pdo_version: 0,
            payload,
            reserved: 0,
        };
        EplFrame::new(CN, MacAddr::PRES, 255, 1, Message::PRes(pres))
    };
    frame.encode().unwrap()
}

/// The number a frame of [`numbered`] carries.
fn number_of(bytes: &[u8]) -> u64 {
    match EplFrame::decode(bytes).unwrap().message {
        Message::Soc(s) => s.relative_time,
        Message::PRes(p) => u64::from_le_bytes(p.payload[..8].try_into().unwrap()),
        other => panic!("unexpected frame {other:?}"),
    }
}

fn send_all(link: &dyn EthLink, frames: impl IntoIterator<Item = Vec<u8>>) {
    for f in frames {
        loop {
            match link.send(&f) {
                Ok(()) => break,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    std::thread::sleep(Duration::from_millis(1))
                }
                Err(e) => panic!("send: {e}"),
            }
        }
    }
}

/// What a reader of a numbered stream saw.
#[derive(Debug, Default)]
struct Seen {
    received: u64,
    /// Frames whose number was not the previous one plus one plus the drops placed before it.
    misplaced: u64,
    /// Numbers missing between received frames (and before the first).
    gaps: u64,
    last: Option<u64>,
}

impl Seen {
    /// Checks one frame: its bytes, its order, and the drops placed before it (`placed`: the
    /// growth of [`EthLink::rx_drops`] since the previous frame).
    fn frame(&mut self, bytes: &[u8], placed: u64) {
        let i = number_of(bytes);
        assert_eq!(bytes, numbered(i).as_slice(), "frame {i} altered");
        let expected = self.last.map_or(0, |l| l + 1);
        assert!(i >= expected, "frame {i} after frame {:?}: out of order or repeated", self.last);
        self.gaps += i - expected;
        if i - expected != placed {
            self.misplaced += 1;
        }
        self.last = Some(i);
        self.received += 1;
    }
}

/// Reads the numbered stream from `ring` until `sent` frames are accounted for (received or
/// dropped by the kernel) or `stop` is set.
fn read_numbered(ring: &RingSocket, sent: u64, stop: &AtomicBool) -> Seen {
    let mut seen = Seen::default();
    let mut buf = vec![0u8; 2048];
    let mut drops = ring.rx_drops().unwrap();
    while !stop.load(Ordering::Relaxed) {
        match ring.recv(&mut buf, Duration::from_millis(100)).unwrap() {
            Some((n, _)) => {
                let now = ring.rx_drops().unwrap();
                seen.frame(&buf[..n], now - drops);
                drops = now;
            }
            None => {
                let k = ring.kernel_rx_stats().unwrap().unwrap();
                if seen.received + k.drops >= sent {
                    break;
                }
            }
        }
    }
    seen
}

#[test]
fn ring_receives_every_frame_in_order() {
    let _one = exclusive();
    if !can_run("ring_receives_every_frame_in_order") {
        return;
    }
    const SENT: u64 = 50_000;
    let ns = BridgedPorts::create("ring", &["feed", "mon"]).unwrap();
    let tx = ns.open(&["feed"]).unwrap().pop().unwrap();
    let ring = Arc::new(open_ring(&ns, "mon", RingConfig::with_mib(32)));
    eprintln!("{}", ring.describe());
    let softnet_before = softnet_drops();
    let stop = Arc::new(AtomicBool::new(false));
    let reader = {
        let (ring, stop) = (Arc::clone(&ring), Arc::clone(&stop));
        std::thread::spawn(move || read_numbered(&ring, SENT, &stop))
    };
    let t = Instant::now();
    send_all(&*tx, (0..SENT).map(numbered));
    let sending = t.elapsed();
    // Liveness only: the reader ends when every frame is accounted for.
    while !reader.is_finished() && t.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(20));
    }
    stop.store(true, Ordering::Relaxed);
    let seen = reader.join().unwrap();
    let kernel = ring.kernel_rx_stats().unwrap().unwrap();
    let softnet = softnet_drops() - softnet_before;
    eprintln!(
        "sent {SENT} in {sending:?}; received {}, kernel {kernel:?}, ring full {} times, \
         softnet drops {softnet}",
        seen.received,
        ring.freezes()
    );
    assert_eq!(
        seen.received + kernel.drops,
        SENT,
        "frames missing without a count: {seen:?} {kernel:?} (softnet drops {softnet})"
    );
    assert_eq!(kernel.packets, SENT, "{kernel:?}");
    // The frames after the last one received were dropped.
    assert_eq!(seen.gaps + (SENT - 1 - seen.last.unwrap()), kernel.drops, "{seen:?}");
    drop(ns);
}

#[test]
fn ring_places_drops_where_frames_are_missing() {
    let _one = exclusive();
    if !can_run("ring_places_drops_where_frames_are_missing") {
        return;
    }
    let ns = BridgedPorts::create("ringdrop", &["feed", "mon"]).unwrap();
    let tx = ns.open(&["feed"]).unwrap().pop().unwrap();
    // 4 blocks of 16 KiB: about 450 small frames. A block is handed over when full, or after
    // a second (the burst closes none by time-out: see `BURST_TIMEOUT_MS`).
    let config = RingConfig { block_size: 16 << 10, blocks: 4, block_timeout_ms: BURST_TIMEOUT_MS };
    let ring = open_ring(&ns, "mon", config);
    // A burst of 2,000 frames while nobody reads, then 100 more after the ring was drained.
    send_all(&*tx, (0..2_000).map(numbered));
    std::thread::sleep(Duration::from_millis(300));
    let mut buf = vec![0u8; 2048];
    let mut seen = Seen::default();
    let mut drops = ring.rx_drops().unwrap();
    let mut drain = |seen: &mut Seen| {
        // Liveness only: a block that is not full comes after the ring's time-out.
        while let Some((n, _)) =
            ring.recv(&mut buf, Duration::from_millis(2 * BURST_TIMEOUT_MS as u64)).unwrap()
        {
            let now = ring.rx_drops().unwrap();
            seen.frame(&buf[..n], now - drops);
            drops = now;
        }
    };
    drain(&mut seen);
    let first = seen.received;
    send_all(&*tx, (2_000..2_100).map(numbered));
    std::thread::sleep(Duration::from_millis(100));
    drain(&mut seen);
    let kernel = ring.kernel_rx_stats().unwrap().unwrap();
    eprintln!(
        "burst: {first} received; in all {seen:?}, kernel {kernel:?}, ring full {} times",
        ring.freezes()
    );
    assert!(kernel.drops > 0, "2,000 frames fit in a ring of {} bytes", config.bytes());
    assert_eq!(seen.received + kernel.drops, 2_100, "{seen:?} {kernel:?}");
    assert_eq!(kernel.packets, 2_100);
    assert_eq!(seen.last, Some(2_099), "the frames after the burst all arrive");
    assert_eq!(seen.gaps, kernel.drops);
    assert_eq!(ring.rx_drops(), Some(kernel.drops), "every drop placed");
    assert_eq!(seen.misplaced, 0, "a drop count not at its gap: {seen:?}");
    drop(ns);
}

/// The monitor on a ring loses no frame silently: a burst of 2,000 cycles overflows the ring
/// (256 blocks of 4 KiB, at most 7,168 small frames) while the monitor does not read; then
/// it reads 150 cycles at about 1 ms (the ring holds about a second of them). Every frame
/// sent is received or counted as a kernel drop where it is missing: the cycle with the gap
/// is marked, no drop is counted as a miss, and the cycle numbers stay the segment's.
#[test]
fn monitor_on_ring_accounts_for_every_frame() {
    let _one = exclusive();
    if !can_run("monitor_on_ring_accounts_for_every_frame") {
        return;
    }
    const BURST: u64 = 2_000;
    let ns = BridgedPorts::create("ringmon", &["feed", "mon"]).unwrap();
    let tx = ns.open(&["feed"]).unwrap().pop().unwrap();
    let config = RingConfig { block_size: 4 << 10, blocks: 256, block_timeout_ms: BURST_TIMEOUT_MS };
    let mon = Arc::new(open_ring(&ns, "mon", config));
    let burst: Vec<Vec<u8>> = (0..BURST).flat_map(common::cycle_frames).collect();
    send_all(&*tx, burst.iter().cloned());
    std::thread::sleep(Duration::from_millis(300));
    let mut paced: Vec<Vec<Vec<u8>>> = (BURST..BURST + 150).map(common::cycle_frames).collect();
    paced.push(common::cycle_frames(BURST + 150).into_iter().take(1).collect());
    let sent = (burst.len() + paced.iter().map(Vec::len).sum::<usize>()) as u64;
    let stop = Arc::new(AtomicBool::new(false));
    let monitor = {
        let (mon, stop) = (Arc::clone(&mon), Arc::clone(&stop));
        std::thread::spawn(move || {
            let mut m = Monitor::cycles_only(MonitorConfig::default());
            let mut samples = Vec::new();
            let st = m
                .run(&*mon, &stop, |s| {
                    samples.push(s.clone());
                    if s.stats.frames + s.stats.dropped >= sent {
                        ControlFlow::Break(())
                    } else {
                        ControlFlow::Continue(())
                    }
                })
                .unwrap();
            (st, samples, m.node_counters())
        })
    };
    // Liveness only: time for the monitor to drain the ring before the paced cycles.
    std::thread::sleep(Duration::from_millis(200));
    for c in &paced {
        send_all(&*tx, c.iter().cloned());
        std::thread::sleep(Duration::from_millis(1));
    }
    // Liveness only: the monitor ends when every frame is accounted for.
    let t = Instant::now();
    while !monitor.is_finished() && t.elapsed() < Duration::from_secs(30) {
        std::thread::sleep(Duration::from_millis(20));
    }
    stop.store(true, Ordering::Relaxed);
    let (st, samples, nodes) = monitor.join().unwrap();
    let kernel = mon.kernel_rx_stats().unwrap().unwrap();
    eprintln!("sent {sent}; {st:?}; kernel {kernel:?}; ring full {} times", mon.freezes());
    assert_eq!(st.frames, st.decoded + st.undecoded);
    assert_eq!(st.undecoded, 0);
    assert_eq!(st.frames + st.dropped, sent, "{st:?}");
    assert!(st.dropped > 0, "{} frames fit in a ring of {} bytes", burst.len(), config.bytes());
    assert_eq!((kernel.packets, kernel.drops), (sent, st.dropped), "{kernel:?}");
    assert!(st.cycles_with_loss >= 1);
    // Cycles 0..BURST+150 were closed (the last SoC opens the next): those seen plus those
    // whose SoC was dropped, estimated from the SoC's RelativeTime.
    assert_eq!(st.cycles + st.cycles_lost, BURST + 150, "{st:?}");
    assert_eq!(samples.iter().filter(|s| s.lost_frames > 0).count() as u64, st.cycles_with_loss);
    let n1 = nodes.iter().find(|c| c.node == 1).unwrap();
    assert_eq!(n1.misses, 0, "a dropped PRes counted as a miss: {n1:?}");
    assert_eq!(n1.pres, samples.iter().map(|s| s.report.pres.len() as u64).sum::<u64>());
    drop(ns);
}
