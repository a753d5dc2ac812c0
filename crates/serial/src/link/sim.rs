//! An in-process simulated line: the host's [`Link`] runs the simulator's serve step
//! inline, on a (virtual) clock shared with the host, as smoltcp's `tests/netsim.rs` and
//! quinn-proto's test `Pair` do.
//!
//! A [`SimLink`] has no thread and never sleeps on the wall clock. When the host writes,
//! the bytes go through the same serve step as [`SimServer::run`] (decoding, idle flush,
//! arrival after the request's wire time, the answer's delay, fault injection by a
//! [`FaultInjector`] seeded as the server's); each answer byte is queued stamped with the
//! instant it is on the host's side. A read returns the bytes whose instant has come, or
//! sleeps the clock until the next one (or the time-out); the devices are brought up to
//! the clock's time ([`Responder::tick`]) on every read and write.
//!
//! On a [`motus_clock::VirtualClock`], a transaction then takes exactly its wire times and
//! delays of virtual time, and a time-out its time-out, in microseconds of wall time.

use super::fault::{FaultInjector, FaultStats};
use super::{LineSettings, Link};
use crate::serve::{Core, Port, Responder, SimServer};
use motus_clock::SharedClock;
use motus_wire::{Scanner, StreamStats};
use std::collections::VecDeque;
use std::io;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

/// A link that carries nothing: writes vanish, reads return nothing at once. The
/// placeholder link of a [`SimServer`] made for a [`SimLink`] (which serves through its
/// own in-memory line).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NullLink {
    line: LineSettings,
}

impl NullLink {
    /// A link of `line`'s settings that carries nothing.
    pub fn new(line: LineSettings) -> Self {
        NullLink { line }
    }
}

impl Link for NullLink {
    fn write_all(&mut self, _: &[u8]) -> io::Result<()> {
        Ok(())
    }
    fn read(&mut self, _: &mut [u8], _: Duration) -> io::Result<usize> {
        Ok(0)
    }
    fn discard_input(&mut self) -> io::Result<()> {
        Ok(())
    }
    fn line(&self) -> LineSettings {
        self.line
    }
    fn describe(&self) -> String {
        "null".into()
    }
}

/// The simulator's side of the in-memory line, read and written by the serve step through
/// a [`FaultInjector`].
struct Wire {
    line: LineSettings,
    pacing: bool,
    /// Bytes the host wrote that the simulator has not read.
    to_device: VecDeque<u8>,
    /// Bytes to the host, each with the instant it is on the host's side.
    to_host: VecDeque<(Instant, u8)>,
    /// When the answer being written starts (set by the serve step before it writes).
    send_at: Instant,
    /// When the device-to-host direction is free.
    line_free_at: Instant,
}

impl Wire {
    /// Moves the bytes on the host's side by `now` into `buf`.
    fn take_due(&mut self, now: Instant, buf: &mut [u8]) -> usize {
        let mut n = 0;
        for slot in buf.iter_mut() {
            match self.to_host.front() {
                Some(&(at, b)) if at <= now => {
                    *slot = b;
                    self.to_host.pop_front();
                    n += 1;
                }
                _ => break,
            }
        }
        n
    }

    /// When the next byte reaches the host.
    fn next_due(&self) -> Option<Instant> {
        self.to_host.front().map(|(at, _)| *at)
    }
}

impl Link for Wire {
    /// Queues an answer: its bytes leave one character time apart (with pacing) from
    /// `send_at`, or once the previous answer has left.
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        let start = self.send_at.max(self.line_free_at);
        let mut t = start;
        for (i, &b) in bytes.iter().enumerate() {
            if self.pacing {
                // From the start, so that the last byte is exactly the wire time late.
                t = start + self.line.wire_time(i + 1);
            }
            self.to_host.push_back((t, b));
        }
        self.line_free_at = t;
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], _: Duration) -> io::Result<usize> {
        let n = buf.len().min(self.to_device.len());
        for (slot, b) in buf.iter_mut().zip(self.to_device.drain(..n)) {
            *slot = b;
        }
        Ok(n)
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.to_device.clear();
        Ok(())
    }

    fn line(&self) -> LineSettings {
        self.line
    }

    fn describe(&self) -> String {
        "sim-wire".into()
    }
}

/// The port of the inline serve step: waiting moves a cursor, answers are queued.
struct InlinePort<'a> {
    wire: &'a mut FaultInjector<Wire>,
    cursor: Instant,
}

impl Port for InlinePort<'_> {
    fn now(&self) -> Instant {
        self.cursor
    }

    fn wait_until(&mut self, at: Instant) {
        self.cursor = self.cursor.max(at);
    }

    fn send(&mut self, at: Instant, bytes: &[u8]) -> io::Result<()> {
        let before = self.wire.inner().line_free_at;
        self.wire.inner_mut().send_at = at;
        self.wire.write_all(bytes)?;
        // As a paced write returns once its bytes have left (a dropped one at once).
        let after = self.wire.inner().line_free_at;
        self.cursor = self.cursor.max(at);
        if after != before {
            self.cursor = self.cursor.max(after);
        }
        Ok(())
    }
}

/// The host's side of an in-process simulated line (see the module documentation): a
/// [`Link`] that serves `R`'s simulated devices inline, in the caller's thread, on the
/// clock of the [`SimServer`] it was made from.
///
/// The host side (a [`crate::BusMaster`], a [`crate::FramedLink`]) must use the same
/// clock: take it from [`SimLink::clock`] (or give both the same clock). The test keeps a
/// clone of the responder's `Arc` to inspect the simulated devices.
pub struct SimLink<S, R> {
    core: Core<S>,
    responder: Arc<Mutex<R>>,
    wire: FaultInjector<Wire>,
    line: LineSettings,
    /// When the host-to-device direction is free.
    host_free_at: Instant,
}

impl<S, R> SimLink<S, R>
where
    S: Scanner,
    S::Error: std::fmt::Debug,
    R: Responder<Frame = S::Frame, Error = S::Error>,
{
    /// Serves `responder` with `server`'s serve step, options (pacing, idle flush, faults
    /// and their seed) and clock, on an in-memory line of `line`'s settings (the server's
    /// own link is not used).
    pub fn new(server: SimServer<S>, responder: Arc<Mutex<R>>, line: LineSettings) -> SimLink<S, R> {
        let mut core = server.into_core();
        core.set_line(line);
        let now = core.clock().now();
        let wire = Wire {
            line,
            pacing: core.options().baud_pacing,
            to_device: VecDeque::new(),
            to_host: VecDeque::new(),
            send_at: now,
            line_free_at: now,
        };
        let faults = core.options().faults;
        SimLink { core, responder, wire: FaultInjector::new(wire, faults), line, host_free_at: now }
    }

    /// The clock of the simulation (the server's), for the host side.
    pub fn clock(&self) -> &SharedClock {
        self.core.clock()
    }

    /// The simulated devices.
    pub fn responder(&self) -> &Arc<Mutex<R>> {
        &self.responder
    }

    /// When simulated time started.
    pub fn start(&self) -> Instant {
        self.core.start()
    }

    /// Simulated time now: the clock's time since the start.
    pub fn now(&self) -> Duration {
        self.core.clock().elapsed(self.core.start())
    }

    /// Answers sent so far (dropped ones included).
    pub fn frames_served(&self) -> u64 {
        self.core.frames_served()
    }

    /// The request decoder's totals (frames, garbage bytes, corrupt frames).
    pub fn decoder_stats(&self) -> StreamStats {
        self.core.decoder_stats()
    }

    /// What the fault injection did so far.
    pub fn fault_stats(&self) -> FaultStats {
        self.wire.stats()
    }

    /// Answer bytes not yet read by the host (on their way, or arrived).
    pub fn in_flight(&self) -> usize {
        self.wire.inner().to_host.len()
    }

    fn lock(responder: &Mutex<R>) -> MutexGuard<'_, R> {
        responder.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Runs what is due by `now`: an idle flush (at its own instant), then the devices'
    /// tick.
    fn advance(&mut self, now: Instant) -> io::Result<()> {
        let mut responder = Self::lock(&self.responder);
        if let Some(at) = self.core.idle_flush_at().filter(|at| *at <= now) {
            let mut port = InlinePort { wire: &mut self.wire, cursor: at };
            self.core.flush(&mut *responder, &mut port)?;
        }
        self.core.tick(now, &mut *responder)
    }
}

impl<S, R> Link for SimLink<S, R>
where
    S: Scanner + Send,
    S::Error: std::fmt::Debug,
    R: Responder<Frame = S::Frame, Error = S::Error> + Send,
{
    /// Hands the bytes to the serve step at once: they are on the wire from now (or from
    /// when the host's previous bytes have left), one character time each with pacing.
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        let now = self.core.clock().now();
        self.advance(now)?;
        if bytes.is_empty() {
            return Ok(());
        }
        let first = now.max(self.host_free_at);
        let last =
            if self.core.options().baud_pacing { first + self.line.wire_time(bytes.len()) } else { first };
        self.host_free_at = last;
        self.wire.inner_mut().to_device.extend(bytes);
        // The simulator reads them through the fault injector (received bytes corrupted).
        let mut received = vec![0u8; bytes.len()];
        let n = self.wire.read(&mut received, Duration::ZERO)?;
        let mut responder = Self::lock(&self.responder);
        let mut port = InlinePort { wire: &mut self.wire, cursor: last };
        self.core.receive(received.get(..n).unwrap_or_default(), first, last, &mut *responder, &mut port)
    }

    /// Returns the answer bytes on the host's side by now; otherwise sleeps the clock until
    /// the next one arrives (or an idle flush is due) or `timeout` has passed (`Ok(0)`).
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let clock = Arc::clone(self.core.clock());
        let now = clock.now();
        let deadline = now.checked_add(timeout).unwrap_or(now + Duration::from_secs(86_400 * 365));
        loop {
            let now = clock.now();
            self.advance(now)?;
            let n = self.wire.inner_mut().take_due(now, buf);
            if n > 0 || now >= deadline || buf.is_empty() {
                return Ok(n);
            }
            let next = [self.wire.inner().next_due(), self.core.idle_flush_at()]
                .into_iter()
                .flatten()
                .fold(deadline, Instant::min);
            clock.sleep_until(next);
        }
    }

    /// Drops the answer bytes on the host's side by now (bytes still on the wire arrive
    /// later, as on a real line).
    fn discard_input(&mut self) -> io::Result<()> {
        let now = self.core.clock().now();
        self.advance(now)?;
        let wire = self.wire.inner_mut();
        while wire.to_host.front().is_some_and(|(at, _)| *at <= now) {
            wire.to_host.pop_front();
        }
        Ok(())
    }

    fn line(&self) -> LineSettings {
        self.line
    }

    fn describe(&self) -> String {
        format!("sim({} Bd)", self.line.baud)
    }
}
