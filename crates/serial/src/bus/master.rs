//! Request/response transactions on a half-duplex multi-drop line.
//!
//! One transaction: drop stale input, send the request, collect bytes until the
//! protocol's [`Scanner`] finds a reply the caller accepts, or the time-out elapses. The
//! time-out is the wire time of request and reply at the line's baud rate plus a margin.
//! Idempotent requests are retried; a non-idempotent one (e.g. a relative move) is sent
//! once, and a failure says that its outcome is unknown.
//!
//! Every deadline and statistics window is on the master's [clock](motus_clock::Clock)
//! (the system clock unless made with [`BusMaster::with_clock`]): on a virtual clock with
//! an in-process [`crate::SimLink`], a time-out takes virtual time only.

use super::stats::{BusStats, DeviceStats};
use crate::link::Link;
use motus_clock::{ClockMutex, ClockMutexGuard, SharedClock, SystemClock};
use motus_wire::{Scanner, Stream, StreamEvent};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// Bus master settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BusConfig {
    /// Added to the wire time of each exchange to form the time-out (default 20 ms).
    pub margin: Duration,
    /// Extra attempts for idempotent requests (default 2).
    pub retries: u32,
}

/// Reads without waiting after an exchange's deadline, to collect an answer that arrived in
/// time while this thread was not running (bounded, so a babbling line still times out).
const MAX_LATE_READS: u32 = 8;

impl Default for BusConfig {
    fn default() -> Self {
        BusConfig { margin: Duration::from_millis(20), retries: 2 }
    }
}

/// One request.
#[derive(Debug, Clone, Copy)]
pub struct Request<'a> {
    /// Device key for the per-device counters (e.g. the module address).
    pub device: u32,
    /// Bytes to send.
    pub bytes: &'a [u8],
    /// Length of the expected reply (for the time-out).
    pub reply_len: usize,
    /// True if the request may be repeated safely.
    pub idempotent: bool,
}

/// A transaction failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BusError {
    /// No acceptable reply in time.
    #[error("device {device} on {link}: no valid reply within {timeout:?} after {attempts} attempt(s) ({corrupt} corrupt frame(s) seen)")]
    Timeout {
        /// Device key.
        device: u32,
        /// Link description.
        link: String,
        /// Time-out per attempt.
        timeout: Duration,
        /// Attempts made.
        attempts: u32,
        /// Corrupt frames seen meanwhile.
        corrupt: u64,
    },
    /// The link failed.
    #[error("IO error on {link}: {reason}")]
    Io {
        /// Link description.
        link: String,
        /// The OS error.
        reason: String,
    },
}

struct Inner {
    link: Box<dyn Link>,
}

struct Counters {
    since: Instant,
    devices: BTreeMap<u32, DeviceStats>,
    bytes_tx: u64,
    bytes_rx: u64,
    garbage: u64,
    busy: Duration,
}

impl Counters {
    fn new(since: Instant) -> Self {
        Counters {
            since,
            devices: BTreeMap::new(),
            bytes_tx: 0,
            bytes_rx: 0,
            garbage: 0,
            busy: Duration::ZERO,
        }
    }
}

/// The master of one line. Shared between threads (`Arc<BusMaster>`); each transaction
/// holds the line exclusively.
pub struct BusMaster {
    inner: ClockMutex<Inner>,
    counters: Mutex<Counters>,
    config: BusConfig,
    line: crate::LineSettings,
    describe: String,
    clock: SharedClock,
}

impl BusMaster {
    /// A master on `link`, on the system clock.
    pub fn new(link: Box<dyn Link>, config: BusConfig) -> Self {
        Self::with_clock(link, config, SystemClock::shared())
    }

    /// A master on `link` whose time-outs and statistics are on `clock` (a virtual clock
    /// for a test with an in-process [`crate::SimLink`] on the same clock).
    pub fn with_clock(link: Box<dyn Link>, config: BusConfig, clock: SharedClock) -> BusMaster {
        let line = link.line();
        let describe = link.describe();
        BusMaster {
            inner: ClockMutex::new(Inner { link }, Arc::clone(&clock)),
            counters: Mutex::new(Counters::new(clock.now())),
            config,
            line,
            describe,
            clock,
        }
    }

    /// The clock of the time-outs and statistics.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }

    /// The configuration.
    pub fn config(&self) -> BusConfig {
        self.config
    }

    /// The line's settings.
    pub fn line(&self) -> crate::LineSettings {
        self.line
    }

    /// Description of the link.
    pub fn describe(&self) -> &str {
        &self.describe
    }

    /// The time-out of one attempt exchanging `tx` and `rx` bytes.
    pub fn timeout_for(&self, tx: usize, rx: usize) -> Duration {
        self.line.wire_time(tx + rx) + self.config.margin
    }

    /// Takes the line; while another thread holds it, this one waits on the clock (a
    /// threaded virtual clock moves time for the holder, and hands the line over before it
    /// moves time again: [`ClockMutex`]).
    fn lock_inner(&self) -> ClockMutexGuard<'_, Inner> {
        self.inner.lock()
    }

    fn lock_counters(&self) -> MutexGuard<'_, Counters> {
        self.counters.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Runs one transaction: returns the first frame `scanner` finds that `accept` takes.
    pub fn transact<S: Scanner>(
        &self,
        request: &Request<'_>,
        scanner: &S,
        accept: impl Fn(&S::Frame) -> bool,
    ) -> Result<S::Frame, BusError> {
        let attempts = if request.idempotent { 1 + self.config.retries } else { 1 };
        let timeout = self.timeout_for(request.bytes.len(), request.reply_len);
        let idle_gap = self.line.wire_time(3) + Duration::from_millis(2);
        let mut guard = self.lock_inner();
        // Whoever holds the line runs at the device class's priority until it lets go: a web
        // or command thread kept off the CPU must not keep the line from a cyclic thread
        // (motus_realtime::ceiling).
        let ceiling = motus_realtime::ceiling::raise_to(motus_realtime::ThreadClass::Device);
        let inner = &mut *guard;
        let mut dev = DeviceStats { transactions: 1, ..DeviceStats::default() };
        let (mut tx, mut rx, mut garbage) = (0u64, 0u64, 0u64);
        let mut result = None;
        let mut io_error = None;
        for attempt in 0..attempts {
            if attempt > 0 {
                dev.retries += 1;
            }
            if let Err(e) = inner.link.discard_input().and_then(|_| inner.link.write_all(request.bytes)) {
                io_error = Some(e);
                break;
            }
            tx += request.bytes.len() as u64;
            let mut replies = Stream::new(scanner);
            let mut deadline = self.clock.now() + timeout;
            let mut chunk = [0u8; 256];
            let mut late_reads = 0;
            'attempt: loop {
                let before = self.clock.now();
                let wait = deadline.saturating_duration_since(before);
                if wait.is_zero() {
                    // Past the deadline, what has already arrived is still read (without
                    // waiting) before this is called a time-out: when the host held this
                    // thread off the CPU, the answer may be in the buffer, on time.
                    late_reads += 1;
                    if late_reads > MAX_LATE_READS {
                        dev.timeouts += 1;
                        break;
                    }
                }
                let n = match inner.link.read(&mut chunk, wait) {
                    Ok(n) => n,
                    Err(e) => {
                        io_error = Some(e);
                        break;
                    }
                };
                if n == 0 && wait.is_zero() {
                    dev.timeouts += 1;
                    break;
                }
                if n == 0 && self.clock.now() == before {
                    // The link waited without moving the clock (a real link on a virtual
                    // clock): the wait is over, so is the time on the clock.
                    self.clock.sleep_until(before + wait);
                }
                rx += n as u64;
                replies.push(chunk.get(..n).unwrap_or(&[]));
                while let Some(event) = replies.next_event() {
                    match event {
                        StreamEvent::Frame(frame) if accept(&frame) => {
                            result = Some(frame);
                            break 'attempt;
                        }
                        StreamEvent::Frame(_) => dev.unexpected_frames += 1,
                        StreamEvent::Corrupt(_) => {
                            dev.corrupt_frames += 1;
                            // The reply was damaged: retry as soon as the line is idle.
                            deadline = deadline.min(self.clock.now() + idle_gap);
                        }
                        StreamEvent::Garbage { bytes } => garbage += bytes as u64,
                    }
                }
            }
            if result.is_some() || io_error.is_some() {
                break;
            }
        }
        drop(guard);
        drop(ceiling);
        if result.is_some() {
            dev.ok = 1;
        } else {
            dev.failures = 1;
        }
        let busy = self.line.wire_time(usize::try_from(tx + rx).unwrap_or(usize::MAX));
        {
            let mut c = self.lock_counters();
            let d = c.devices.entry(request.device).or_default();
            add(d, &dev);
            c.bytes_tx += tx;
            c.bytes_rx += rx;
            c.garbage += garbage;
            c.busy += busy;
        }
        if let Some(e) = io_error {
            return Err(BusError::Io { link: self.describe.clone(), reason: e.to_string() });
        }
        result.ok_or(BusError::Timeout {
            device: request.device,
            link: self.describe.clone(),
            timeout,
            attempts: 1 + u32::try_from(dev.retries).unwrap_or(0),
            corrupt: dev.corrupt_frames,
        })
    }

    /// Statistics since creation or the last [`BusMaster::reset_stats`].
    pub fn stats(&self) -> BusStats {
        let c = self.lock_counters();
        let mut totals = DeviceStats::default();
        for d in c.devices.values() {
            add(&mut totals, d);
        }
        BusStats {
            window: self.clock.elapsed(c.since),
            totals,
            bytes_tx: c.bytes_tx,
            bytes_rx: c.bytes_rx,
            garbage_bytes: c.garbage,
            wire_busy: c.busy,
            baud: self.line.baud,
        }
    }

    /// Counters of one device.
    pub fn device_stats(&self, device: u32) -> DeviceStats {
        self.lock_counters().devices.get(&device).copied().unwrap_or_default()
    }

    /// Restarts the statistics window.
    pub fn reset_stats(&self) {
        *self.lock_counters() = Counters::new(self.clock.now());
    }
}

fn add(to: &mut DeviceStats, d: &DeviceStats) {
    to.transactions += d.transactions;
    to.ok += d.ok;
    to.timeouts += d.timeouts;
    to.retries += d.retries;
    to.corrupt_frames += d.corrupt_frames;
    to.unexpected_frames += d.unexpected_frames;
    to.failures += d.failures;
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use crate::link::LineSettings;
    use motus_clock::{Clock, VirtualClock};
    use motus_wire::Scan;
    use std::io;

    /// A link whose answer arrives in time, but whose reader is "descheduled": the first
    /// waiting read returns nothing only after the whole time-out (and then some) passed
    /// on the clock. Other reads return at once without moving the clock.
    struct LateWakeLink {
        answer: Vec<u8>,
        waited: bool,
        answered: bool,
        clock: VirtualClock,
    }

    impl Link for LateWakeLink {
        fn write_all(&mut self, _: &[u8]) -> io::Result<()> {
            Ok(())
        }
        fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
            if !self.waited && !timeout.is_zero() {
                self.waited = true;
                self.clock.sleep(timeout + Duration::from_millis(5));
                return Ok(0);
            }
            if self.waited && !self.answered {
                self.answered = true;
                buf[..self.answer.len()].copy_from_slice(&self.answer);
                return Ok(self.answer.len());
            }
            Ok(0)
        }
        fn discard_input(&mut self) -> io::Result<()> {
            Ok(())
        }
        fn line(&self) -> LineSettings {
            LineSettings::n81(115_200)
        }
        fn describe(&self) -> String {
            "late-wake".into()
        }
    }

    /// Frames `[a, a + 1]`.
    struct Pairs;

    impl Scanner for Pairs {
        type Frame = u8;
        type Error = std::convert::Infallible;
        fn scan(&self, buf: &[u8]) -> Scan<u8> {
            match buf {
                [a, b, ..] if *b == a.wrapping_add(1) => Scan::Frame { frame: *a, len: 2 },
                [_, _, ..] => Scan::Skip,
                _ => Scan::Incomplete,
            }
        }
    }

    #[test]
    fn an_answer_already_received_when_the_reader_wakes_late_is_not_a_time_out() {
        let clock = VirtualClock::new();
        let link = LateWakeLink { answer: vec![7, 8], waited: false, answered: false, clock: clock.clone() };
        let config = BusConfig { margin: Duration::from_millis(2), retries: 0 };
        let bus = BusMaster::with_clock(Box::new(link), config, clock.shared());
        let req = Request { device: 7, bytes: &[7], reply_len: 2, idempotent: true };
        assert_eq!(bus.transact(&req, &Pairs, |f| *f == 7), Ok(7));
        let d = bus.device_stats(7);
        assert_eq!((d.ok, d.timeouts), (1, 0), "{d:?}");
    }

    #[test]
    fn nothing_received_by_the_deadline_is_a_time_out_on_the_clock() {
        // The link returns at once without moving the clock (a real link on a virtual
        // clock): the master moves the clock to the deadline.
        let clock = VirtualClock::new();
        let link = LateWakeLink { answer: vec![], waited: true, answered: true, clock: clock.clone() };
        let config = BusConfig { margin: Duration::from_millis(2), retries: 1 };
        let bus = BusMaster::with_clock(Box::new(link), config, clock.shared());
        let t0 = clock.now();
        let req = Request { device: 3, bytes: &[3], reply_len: 2, idempotent: true };
        assert!(matches!(bus.transact(&req, &Pairs, |_| true), Err(BusError::Timeout { attempts: 2, .. })));
        assert_eq!(bus.device_stats(3).timeouts, 2);
        assert_eq!(clock.elapsed(t0), bus.timeout_for(1, 2) * 2);
        assert_eq!(bus.stats().window, bus.timeout_for(1, 2) * 2, "statistics on the clock");
    }
}
