//! [`MemLink`]: a segment inside one process. Frames pass between the ports' threads through
//! memory, with no socket and no kernel path.
//!
//! # Why
//! A simulated segment whose MN, CNs and supervisor run in one process (`motus demo`) does
//! not need the kernel: over UDP loopback it cost ~26,000 `sendto` calls per second at rest,
//! and under web load the loopback's soft interrupts (normal priority, whatever the threads'
//! real-time class) held POWERLINK frames long enough to trip the juggler's supervisor. A
//! `MemLink` costs one queue push and one wake-up per receiving port.
//!
//! # Design
//! A [`MemHub`] is a named medium (`mem://<name>`, one per name in the process): each port has
//! a bounded receive queue (the ring of a NIC: when it is full, the oldest frame is dropped and
//! counted); a send copies the frame into every other port's queue and wakes its reader. A
//! port never receives its own frames, and there is no MAC filtering (a hub). Each port has a
//! locally administered MAC `02:00:6d:65:PP:PP` (PP = its number on the hub).
//!
//! A port may instead have a receiver run in the sending thread
//! ([`EthLink::attach_receiver`]): the simulated drives of an in-process segment need no
//! thread of their own, so a PReq is answered inside the MN's send, with no wake-up of another
//! thread (on a loaded 2-core host every wake-up is a chance to wait behind other work).
//! Frames for such ports go to the hub's pending list, delivered in order by one thread at a
//! time: the sender waits for a thread that is delivering (microseconds), then delivers what
//! is left, so that its frame has been handled when its send returns. A receiver's own sends
//! are delivered after it returns, never nested.
//!
//! # Time
//! A hub runs on a [`motus_clock::Clock`]: the system clock ([`MemHub::named`]), or any other
//! ([`MemHub::with_clock`]), such as a threaded [`motus_clock::VirtualClock`] shared with the
//! nodes: frames are stamped with the clock's time, and a reader waiting in [`EthLink::recv`]
//! parks on the clock ([`motus_clock::Clock::park_until`]) until its time-out, woken by the
//! send that queues a frame for it ([`motus_clock::Clock::unpark`]). On virtual time a frame
//! then arrives at the instant it was sent, and a time-out ends exactly at its deadline. A
//! send delivers to the receivers run in the sending thread before it queues the frame for
//! reading threads, and returns once those have done what they do in answer at that instant
//! ([`motus_clock::Clock::settle`], nothing on the system clock): the order of events within
//! an instant, and so the whole run, is the same every time.

use std::collections::{HashMap, VecDeque};
use std::io;
use std::sync::atomic::{AtomicBool, AtomicU16, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock, PoisonError, RwLock, Weak};
use std::time::{Duration, Instant};

use motus_clock::{SharedClock, SystemClock};
use motus_epl_protocol::MacAddr;

use super::{EthLink, FrameHandler, MAX_FRAME};

/// Frames a port's queue holds before the oldest is dropped (a NIC ring's size).
pub const MEM_QUEUE_FRAMES: usize = 256;

/// One port's receive queue, or its receiver run in the sending thread.
#[derive(Default)]
struct Port {
    number: u16,
    queue: Mutex<Queue>,
    dropped: AtomicU64,
    /// Set while `receiver` holds a handler (read on every send without taking its lock).
    inline: AtomicBool,
    receiver: Mutex<Option<FrameHandler>>,
}

impl std::fmt::Debug for Port {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Port")
            .field("number", &self.number)
            .field("inline", &self.inline.load(Ordering::Relaxed))
            .finish_non_exhaustive()
    }
}

/// A port's received frames and the threads waiting for them.
#[derive(Default)]
struct Queue {
    frames: VecDeque<(Vec<u8>, Instant)>,
    /// Threads waiting in [`EthLink::recv`], unparked (on the hub's clock) by a send.
    waiters: Vec<std::thread::Thread>,
}

/// A frame waiting for a port's receiver.
type Pending = (Arc<Port>, Vec<u8>, Instant);

#[derive(Debug)]
struct Medium {
    name: String,
    clock: SharedClock,
    ports: RwLock<Vec<Arc<Port>>>,
    next: AtomicU16,
    /// Frames for ports with a receiver, in sending order.
    pending: Mutex<VecDeque<Pending>>,
    /// Held by the one thread delivering `pending`.
    delivering: Mutex<()>,
}

thread_local! {
    /// Set while this thread delivers pending frames (a receiver that sends must not nest).
    static DELIVERING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

impl Medium {
    fn new(name: &str, clock: SharedClock) -> Self {
        Medium {
            name: name.to_owned(),
            clock,
            ports: RwLock::default(),
            next: AtomicU16::default(),
            pending: Mutex::default(),
            delivering: Mutex::default(),
        }
    }

    /// Delivers the pending frames in this thread, after any other thread that is delivering
    /// has finished (delivering is quick: the receivers are simulated nodes' handlers). A
    /// receiver's own sends, made while this thread delivers, are delivered by the same loop.
    fn deliver_pending(&self) {
        if DELIVERING.with(std::cell::Cell::get) {
            return;
        }
        let guard = self.delivering.lock().unwrap_or_else(PoisonError::into_inner);
        DELIVERING.with(|d| d.set(true));
        loop {
            let next = self.pending.lock().unwrap_or_else(PoisonError::into_inner).pop_front();
            let Some((port, frame, at)) = next else { break };
            let mut receiver = port.receiver.lock().unwrap_or_else(PoisonError::into_inner);
            if let Some(handler) = receiver.as_mut() {
                handler(&frame, at);
            }
        }
        DELIVERING.with(|d| d.set(false));
        drop(guard);
    }
}

/// The hubs of the process by name; a hub lives while one of its links does.
fn registry() -> &'static Mutex<HashMap<String, Weak<Medium>>> {
    static HUBS: OnceLock<Mutex<HashMap<String, Weak<Medium>>>> = OnceLock::new();
    HUBS.get_or_init(Mutex::default)
}

/// A named in-process medium: every [`MemLink`] made by [`MemHub::connect`] receives the
/// frames of every other one.
#[derive(Debug, Clone)]
pub struct MemHub {
    medium: Arc<Medium>,
}

impl MemHub {
    /// The hub called `name` in this process (created on first use).
    pub fn named(name: &str) -> MemHub {
        let mut hubs = registry().lock().unwrap_or_else(PoisonError::into_inner);
        hubs.retain(|_, w| w.strong_count() > 0);
        if let Some(medium) = hubs.get(name).and_then(Weak::upgrade) {
            return MemHub { medium };
        }
        let medium = Arc::new(Medium::new(name, SystemClock::shared()));
        hubs.insert(name.to_owned(), Arc::downgrade(&medium));
        MemHub { medium }
    }

    /// A hub of its own called `name` on `clock` (not reachable by name: [`MemHub::named`]
    /// and `mem://` links never join it). Every node of the segment runs on the same clock;
    /// on a [`motus_clock::VirtualClock`] the segment runs on virtual time (see the module
    /// documentation).
    pub fn with_clock(name: &str, clock: SharedClock) -> MemHub {
        MemHub { medium: Arc::new(Medium::new(name, clock)) }
    }

    /// The hub's clock.
    pub fn clock(&self) -> &SharedClock {
        &self.medium.clock
    }

    /// A new port on the hub.
    pub fn connect(&self) -> MemLink {
        let number = self.medium.next.fetch_add(1, Ordering::Relaxed);
        let port = Arc::new(Port { number, ..Port::default() });
        self.medium.ports.write().unwrap_or_else(PoisonError::into_inner).push(Arc::clone(&port));
        let [p0, p1] = number.to_be_bytes();
        MemLink { medium: Arc::clone(&self.medium), port, mac: MacAddr([0x02, 0x00, 0x6d, 0x65, p0, p1]) }
    }
}

/// One port on a [`MemHub`]; leaves the hub when dropped.
#[derive(Debug)]
pub struct MemLink {
    medium: Arc<Medium>,
    port: Arc<Port>,
    mac: MacAddr,
}

impl MemLink {
    /// Frames this port's full queue dropped (its reader was too slow).
    pub fn dropped(&self) -> u64 {
        self.port.dropped.load(Ordering::Relaxed)
    }
}

impl Drop for MemLink {
    fn drop(&mut self) {
        self.medium
            .ports
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .retain(|p| !Arc::ptr_eq(p, &self.port));
    }
}

impl EthLink for MemLink {
    fn send(&self, frame: &[u8]) -> io::Result<()> {
        if frame.len() > MAX_FRAME {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("frame of {} bytes exceeds {MAX_FRAME}", frame.len()),
            ));
        }
        let now = self.medium.clock.now();
        let ports = self.medium.ports.read().unwrap_or_else(PoisonError::into_inner);
        let others = || ports.iter().filter(|p| !Arc::ptr_eq(p, &self.port));
        // First the receivers run in the sending thread, then the queues: whatever a reading
        // thread sends in answer to this frame is delivered after it.
        let mut inline = false;
        {
            let mut pending = self.medium.pending.lock().unwrap_or_else(PoisonError::into_inner);
            for p in others().filter(|p| p.inline.load(Ordering::Acquire)) {
                pending.push_back((Arc::clone(p), frame.to_vec(), now));
                inline = true;
            }
        }
        for p in others().filter(|p| !p.inline.load(Ordering::Acquire)) {
            let mut q = p.queue.lock().unwrap_or_else(PoisonError::into_inner);
            if q.frames.len() >= MEM_QUEUE_FRAMES {
                q.frames.pop_front();
                p.dropped.fetch_add(1, Ordering::Relaxed);
            }
            q.frames.push_back((frame.to_vec(), now));
            for waiter in &q.waiters {
                self.medium.clock.unpark(waiter);
            }
        }
        drop(ports);
        if inline {
            self.medium.deliver_pending();
        }
        // On a threaded virtual clock, what the readers do in answer (in this instant) is done
        // before the sender goes on: the order of events does not depend on the OS. Not from
        // inside a delivery (the outer send settles, once the delivery lock is free).
        if !DELIVERING.with(std::cell::Cell::get) {
            self.medium.clock.settle();
        }
        Ok(())
    }

    fn recv(&self, buf: &mut [u8], timeout: Duration) -> io::Result<Option<(usize, Instant)>> {
        let clock = &self.medium.clock;
        let now = clock.now();
        // A time-out too long for an `Instant` waits a year (and then again).
        let deadline = now.checked_add(timeout).unwrap_or(now + Duration::from_secs(365 * 86_400));
        let me = std::thread::current();
        let mut q = self.port.queue.lock().unwrap_or_else(PoisonError::into_inner);
        let got = loop {
            if let Some((frame, at)) = q.frames.pop_front() {
                let n = frame.len().min(buf.len());
                if let (Some(dst), Some(src)) = (buf.get_mut(..n), frame.get(..n)) {
                    dst.copy_from_slice(src);
                }
                break Some((n, at));
            }
            if clock.now() >= deadline {
                break None;
            }
            // Registered before the lock is released: a frame queued from now on unparks us
            // (an unpark before the park ends it at once).
            if !q.waiters.iter().any(|t| t.id() == me.id()) {
                q.waiters.push(me.clone());
            }
            drop(q);
            clock.park_until(deadline);
            q = self.port.queue.lock().unwrap_or_else(PoisonError::into_inner);
        };
        q.waiters.retain(|t| t.id() != me.id());
        Ok(got)
    }

    fn mac(&self) -> MacAddr {
        self.mac
    }

    fn describe(&self) -> String {
        format!("mem {} port {}", self.medium.name, self.port.number)
    }

    fn attach_receiver(&self, handler: FrameHandler) -> Result<(), FrameHandler> {
        *self.port.receiver.lock().unwrap_or_else(PoisonError::into_inner) = Some(handler);
        self.port.inline.store(true, Ordering::Release);
        Ok(())
    }

    fn detach_receiver(&self) {
        self.port.inline.store(false, Ordering::Release);
        // Taken out under the lock, dropped after it: a handler may own this very link.
        let handler = self.port.receiver.lock().unwrap_or_else(PoisonError::into_inner).take();
        drop(handler);
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn every_other_port_receives_a_frame_and_the_sender_does_not() {
        let hub = MemHub::named("test-every-other");
        let (a, b, c) = (hub.connect(), hub.connect(), hub.connect());
        a.send(&[1, 2, 3]).unwrap();
        let mut buf = [0u8; 16];
        for port in [&b, &c] {
            let (n, _) = port.recv(&mut buf, Duration::from_millis(100)).unwrap().unwrap();
            assert_eq!(&buf[..n], &[1, 2, 3]);
        }
        assert!(a.recv(&mut buf, Duration::from_millis(5)).unwrap().is_none());
        assert_ne!(a.mac(), b.mac());
    }

    #[test]
    fn a_name_is_one_medium_and_another_name_another() {
        let a = MemHub::named("test-name-1").connect();
        let b = MemHub::named("test-name-1").connect();
        let other = MemHub::named("test-name-2").connect();
        a.send(&[9]).unwrap();
        let mut buf = [0u8; 4];
        assert!(b.recv(&mut buf, Duration::from_millis(100)).unwrap().is_some());
        assert!(other.recv(&mut buf, Duration::from_millis(5)).unwrap().is_none());
    }

    #[test]
    fn a_receiver_waits_for_a_frame_from_another_thread() {
        let hub = MemHub::named("test-threads");
        let (a, b) = (hub.connect(), hub.connect());
        let t = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(20));
            a.send(&[7; 60]).unwrap();
            a
        });
        let mut buf = [0u8; MAX_FRAME];
        let (n, _) = b.recv(&mut buf, Duration::from_secs(5)).unwrap().unwrap();
        assert_eq!(n, 60);
        drop(t.join().unwrap());
    }

    #[test]
    fn a_full_queue_drops_its_oldest_frames_and_oversized_frames_are_refused() {
        let hub = MemHub::named("test-full");
        let (a, b) = (hub.connect(), hub.connect());
        for i in 0..MEM_QUEUE_FRAMES + 3 {
            a.send(&[u8::try_from(i % 256).unwrap()]).unwrap();
        }
        assert_eq!(b.dropped(), 3);
        let mut buf = [0u8; 4];
        b.recv(&mut buf, Duration::from_millis(10)).unwrap().unwrap();
        assert_eq!(buf[0], 3, "the oldest three were dropped");
        assert!(a.send(&vec![0; MAX_FRAME + 1]).is_err());
    }

    #[test]
    fn a_receiver_runs_in_the_sending_thread_and_its_own_sends_follow_in_order() {
        let hub = MemHub::named("test-inline");
        let (a, b, c) = (hub.connect(), Arc::new(hub.connect()), hub.connect());
        let seen = Arc::new(Mutex::new(Vec::new()));
        let (echo, log) = (Arc::clone(&b), Arc::clone(&seen));
        let sender = std::thread::current().id();
        b.attach_receiver(Box::new(move |frame, _| {
            assert_eq!(std::thread::current().id(), sender);
            log.lock().unwrap().push(frame.to_vec());
            // An answer sent from inside the receiver: queued for the others, not nested.
            echo.send(&[frame[0] + 100]).unwrap();
        }))
        .map_err(|_| "not attached")
        .unwrap();
        a.send(&[1]).unwrap();
        a.send(&[2]).unwrap();
        assert_eq!(*seen.lock().unwrap(), vec![vec![1], vec![2]]);
        let mut buf = [0u8; 4];
        let order: Vec<u8> =
            std::iter::from_fn(|| c.recv(&mut buf, Duration::from_millis(10)).unwrap().map(|_| buf[0]))
                .collect();
        assert_eq!(order, vec![1, 101, 2, 102], "each answer follows its request");
        // Detached: frames are queued again, and the handler (which owns `b`) is dropped.
        b.detach_receiver();
        a.send(&[3]).unwrap();
        assert_eq!(seen.lock().unwrap().len(), 2);
        assert!(b.recv(&mut buf, Duration::from_millis(10)).unwrap().is_some());
        assert_eq!(Arc::strong_count(&b), 1);
    }

    #[test]
    fn on_virtual_time_a_frame_arrives_at_its_send_instant_and_a_time_out_at_its_deadline() {
        use motus_clock::{Clock, VirtualClock};
        let clock = VirtualClock::threaded();
        let hub = MemHub::with_clock("test-virtual", clock.shared());
        let (a, b) = (hub.connect(), hub.connect());
        let reader = motus_clock::spawn(hub.clock(), std::thread::Builder::new(), move || {
            let mut buf = [0u8; 4];
            let mut seen = Vec::new();
            for _ in 0..3 {
                let got = b.recv(&mut buf, Duration::from_millis(10)).unwrap();
                seen.push((got.map(|(n, at)| (buf[..n].to_vec(), at)), b.medium.clock.now()));
            }
            seen
        })
        .unwrap();
        let t0 = clock.base();
        clock.sleep(Duration::from_millis(3));
        a.send(&[1]).unwrap();
        clock.sleep(Duration::from_millis(1));
        a.send(&[2]).unwrap();
        let seen = motus_clock::while_blocked(&clock, || reader.join().unwrap());
        let ms = Duration::from_millis;
        assert_eq!(
            seen,
            vec![
                (Some((vec![1], t0 + ms(3))), t0 + ms(3)),
                (Some((vec![2], t0 + ms(4))), t0 + ms(4)),
                (None, t0 + ms(14)),
            ]
        );
        assert!(MemHub::named("test-virtual").medium.ports.read().unwrap().is_empty(), "not by name");
    }

    #[test]
    fn a_dropped_port_leaves_the_hub() {
        let hub = MemHub::named("test-leave");
        let a = hub.connect();
        drop(hub.connect());
        a.send(&[1]).unwrap();
        assert_eq!(hub.medium.ports.read().unwrap().len(), 1);
    }
}
