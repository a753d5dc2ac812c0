//! Serving simulated devices on a link: the one loop every serial simulator runs.
//!
//! A [`SimServer`] reads what the host sends (with a short read time-out, so that the
//! devices advance while the line is idle and a stop is seen quickly), finds the requests
//! with the codec's resynchronising [`Stream`], hands each to the protocol's [`Responder`]
//! and writes its [`Answer`] on time. Options model the real line:
//!
//! * **pacing**: a request takes its wire time at the link's baud rate to arrive (it has
//!   arrived once its last byte is on the wire: its first byte's time plus the wire time
//!   of its length), and the answer leaves byte by byte at that rate ([`Paced`]);
//! * **idle flush**, for protocols whose frames end with line silence: a line quiet for
//!   three character times (at least 2 ms) ends what was received; a half-received frame
//!   is then dropped like garbage ([`Stream::flush`]);
//! * **faults** ([`FaultInjector`]): whole answers dropped, bytes corrupted in both
//!   directions, seeded.
//!
//! Simulated time is the time since the server was created, on its [`Clock`]
//! ([`SimServer::now`]; the system clock unless made with [`SimServer::with_clock`]). A
//! [`ServeThread`] runs a simulated line on its own thread until stopped.
//!
//! ## One serve step, two drivers
//! The serving itself (decoding, idle flush, arrival times, answer delays, frame counts)
//! is one step function shared by two drivers: [`SimServer::run`], a loop that reads a
//! real link (a pty) and sleeps on the clock until each instant, and [`crate::SimLink`],
//! which runs the step inline, in the host's thread, when the host writes, and queues
//! the answers stamped with the virtual instant they reach the host.

use crate::link::fault::{FaultConfig, FaultInjector, RateError};
use crate::link::paced::Paced;
use crate::link::{LineSettings, Link};
use motus_clock::{Clock, SharedClock, SystemClock};
use motus_wire::{Scanner, Stream, StreamEvent, StreamStats};
use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// How a simulated line behaves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServeOptions {
    /// Bytes take their real wire time at the link's baud rate (use on ptys only).
    pub baud_pacing: bool,
    /// Dropped answers and corrupted bytes (answers and received bytes), with their seed.
    pub faults: FaultConfig,
    /// Read time-out: how long the loop waits for bytes before advancing the devices.
    pub poll: Duration,
    /// A quiet line ends a frame (see the module documentation).
    pub flush_when_idle: bool,
}

/// A simulated line could not start.
#[derive(Debug, thiserror::Error)]
pub enum LineError<E: std::error::Error + 'static> {
    /// Bad options (addresses, fault rates outside 0..=1).
    #[error("invalid simulator options: {0}")]
    Options(String),
    /// The simulated devices' configuration or stored state.
    #[error(transparent)]
    Model(#[from] E),
}

/// An answer to a request.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Answer {
    /// The bytes to send.
    pub bytes: Vec<u8>,
    /// Time from the request's arrival until the answer starts (processing, relays).
    pub delay: Duration,
}

impl Answer {
    /// The answer an encoder gave, sent `delay` after the request arrived; an encoding
    /// error is logged and nothing is sent.
    pub fn encoded<E: std::fmt::Display>(encoded: Result<Vec<u8>, E>, delay: Duration) -> Option<Answer> {
        match encoded {
            Ok(bytes) => Some(Answer { bytes, delay }),
            Err(e) => {
                tracing::warn!(error = %e, "cannot encode an answer");
                None
            }
        }
    }
}

/// The simulated devices of one protocol behind a [`SimServer`].
pub trait Responder {
    /// The frames the devices receive.
    type Frame;
    /// What a corrupt candidate reports.
    type Error;

    /// Handles a frame that arrived at `now`; returns the answer, if any.
    fn respond(&mut self, frame: Self::Frame, now: Duration) -> Option<Answer>;

    /// Handles a corrupt candidate seen at `now` (ignored unless a device answers it).
    fn corrupt(&mut self, error: Self::Error, now: Duration) -> Option<Answer> {
        let _ = (error, now);
        None
    }

    /// Brings the devices up to `now`; called while the line is idle and after every read.
    /// The times handed to a responder never go back.
    fn tick(&mut self, now: Duration) -> io::Result<()>;

    /// The simulator's own thread did not run for `gap` (it was not scheduled: a loaded
    /// host), so bytes the host sent meanwhile waited in the line instead of reaching the
    /// devices as they came. A device that watches its line for silence (a communication
    /// time-out) must not count that gap against the host. Called before those bytes are
    /// handed over; nothing by default.
    fn simulator_stalled(&mut self, gap: Duration) {
        let _ = gap;
    }
}

/// A serve loop that wakes this much later than its read time-out was not running (see
/// [`Responder::simulator_stalled`]).
pub const STALL: Duration = Duration::from_millis(50);

/// How the serve step waits and where its answers go: the threaded loop sleeps on its
/// clock and writes to its (paced, faulty) link; an inline [`crate::SimLink`] moves a
/// cursor and queues stamped bytes.
pub(crate) trait Port {
    /// The serve step's current instant.
    fn now(&self) -> Instant;
    /// Waits until `at` (a request has arrived).
    fn wait_until(&mut self, at: Instant);
    /// Sends an answer whose first byte starts at `at`.
    fn send(&mut self, at: Instant, bytes: &[u8]) -> io::Result<()>;
}

/// The port of [`SimServer::run`]: real waits on the clock, the server's link.
struct ThreadedPort<'a> {
    link: &'a mut dyn Link,
    clock: &'a dyn Clock,
}

impl Port for ThreadedPort<'_> {
    fn now(&self) -> Instant {
        self.clock.now()
    }

    fn wait_until(&mut self, at: Instant) {
        self.clock.sleep_until(at);
    }

    fn send(&mut self, at: Instant, bytes: &[u8]) -> io::Result<()> {
        self.clock.sleep_until(at);
        self.link.write_all(bytes)
    }
}

/// The serving state and the one serve step, shared by [`SimServer::run`] and
/// [`crate::SimLink`].
pub(crate) struct Core<S> {
    decoder: Stream<S>,
    options: ServeOptions,
    clock: SharedClock,
    start: Instant,
    frames_served: u64,
    line: LineSettings,
    idle_gap: Duration,
    /// When the first byte of what the decoder holds arrived, and how many bytes the
    /// decoder had resolved (in frames or as garbage) before it.
    first_byte_at: Option<(Instant, u64)>,
    /// When the last byte received was on the wire.
    last_byte_at: Instant,
    /// The latest simulated time handed to the responder.
    device_time: Duration,
}

/// A quiet line of three character times (at least 2 ms) ends a frame.
fn idle_gap(line: LineSettings) -> Duration {
    line.wire_time(3).max(Duration::from_millis(2))
}

impl<S: Scanner> Core<S> {
    fn new(scanner: S, options: ServeOptions, clock: SharedClock, line: LineSettings) -> Self {
        let start = clock.now();
        Core {
            decoder: Stream::new(scanner),
            options,
            clock,
            start,
            frames_served: 0,
            line,
            idle_gap: idle_gap(line),
            first_byte_at: None,
            last_byte_at: start,
            device_time: Duration::ZERO,
        }
    }

    pub(crate) fn options(&self) -> &ServeOptions {
        &self.options
    }

    pub(crate) fn clock(&self) -> &SharedClock {
        &self.clock
    }

    pub(crate) fn start(&self) -> Instant {
        self.start
    }

    pub(crate) fn frames_served(&self) -> u64 {
        self.frames_served
    }

    pub(crate) fn decoder_stats(&self) -> StreamStats {
        self.decoder.stats()
    }

    /// Serves on a line of `line`'s settings from now on.
    pub(crate) fn set_line(&mut self, line: LineSettings) {
        self.line = line;
        self.idle_gap = idle_gap(line);
    }

    /// When the line's silence ends what the decoder holds, if it holds anything and
    /// frames end with silence.
    pub(crate) fn idle_flush_at(&self) -> Option<Instant> {
        (self.options.flush_when_idle && self.decoder.pending() > 0)
            .then_some(self.last_byte_at + self.idle_gap)
    }

    /// The simulated time of `at`, never earlier than one already handed to the responder.
    fn device_now(&mut self, at: Instant) -> Duration {
        let now = at.saturating_duration_since(self.start).max(self.device_time);
        self.device_time = now;
        now
    }

    /// Brings the responder up to `at`.
    pub(crate) fn tick<R: Responder + ?Sized>(&mut self, at: Instant, responder: &mut R) -> io::Result<()> {
        let now = self.device_now(at);
        responder.tick(now)
    }

    /// The line went quiet: ends what the decoder holds (a half-received frame is
    /// dropped like garbage) and serves it.
    pub(crate) fn flush<R>(&mut self, responder: &mut R, port: &mut dyn Port) -> io::Result<()>
    where
        R: Responder<Frame = S::Frame, Error = S::Error> + ?Sized,
        S::Error: std::fmt::Debug,
    {
        self.decoder.flush();
        self.serve(responder, port)?;
        self.decoder.clear();
        self.first_byte_at = None;
        Ok(())
    }

    /// Bytes received: the first was on the wire at `first_at`, the last at `last_at`.
    pub(crate) fn receive<R>(
        &mut self,
        bytes: &[u8],
        first_at: Instant,
        last_at: Instant,
        responder: &mut R,
        port: &mut dyn Port,
    ) -> io::Result<()>
    where
        R: Responder<Frame = S::Frame, Error = S::Error> + ?Sized,
        S::Error: std::fmt::Debug,
    {
        if bytes.is_empty() {
            return Ok(());
        }
        if self.first_byte_at.is_none() {
            self.first_byte_at = Some((first_at, self.resolved()));
        }
        self.last_byte_at = last_at;
        self.decoder.push(bytes);
        self.serve(responder, port)?;
        if self.decoder.pending() == 0 {
            self.first_byte_at = None;
        }
        Ok(())
    }

    /// Bytes the decoder has resolved so far, in frames or as garbage.
    fn resolved(&self) -> u64 {
        let stats = self.decoder.stats();
        stats.frame_bytes + stats.garbage_bytes
    }

    /// Hands every request decoded so far to `responder` and sends the answers on time.
    fn serve<R>(&mut self, responder: &mut R, port: &mut dyn Port) -> io::Result<()>
    where
        R: Responder<Frame = S::Frame, Error = S::Error> + ?Sized,
        S::Error: std::fmt::Debug,
    {
        while let Some(request) = self.decoder.next_event() {
            if let StreamEvent::Garbage { bytes } = request {
                tracing::debug!(bytes, "skipped garbage");
                continue;
            }
            // With pacing, a frame has arrived once its last byte is on the wire: the
            // bytes from the first one received (garbage and earlier frames included)
            // through its end take their wire time. A corrupt one, whose length is
            // unknown, has arrived when it is seen.
            let arrived = match (self.options.baud_pacing, self.first_byte_at, &request) {
                (true, Some((t0, base)), StreamEvent::Frame(_)) => {
                    let through = self.resolved().saturating_sub(base);
                    let at = t0 + self.line.wire_time(usize::try_from(through).unwrap_or(usize::MAX));
                    port.wait_until(at);
                    at
                }
                _ => port.now(),
            };
            let now = self.device_now(arrived);
            let answer = match request {
                StreamEvent::Frame(frame) => responder.respond(frame, now),
                StreamEvent::Corrupt(error) => {
                    tracing::debug!(?error, "corrupt request");
                    responder.corrupt(error, now)
                }
                StreamEvent::Garbage { .. } => None,
            };
            let Some(answer) = answer else { continue };
            port.send(arrived + answer.delay, &answer.bytes)?;
            self.frames_served += 1;
        }
        Ok(())
    }
}

/// Serves a [`Responder`] on a link (see the module documentation).
pub struct SimServer<S> {
    link: Box<dyn Link>,
    core: Core<S>,
}

impl<S: Scanner> SimServer<S> {
    /// Serves `link` on the system clock, finding requests with `scanner`; wraps the link
    /// for pacing and faults.
    ///
    /// # Errors
    /// A fault rate outside 0..=1.
    pub fn new(link: Box<dyn Link>, scanner: S, options: ServeOptions) -> Result<Self, RateError> {
        Self::with_clock(link, scanner, options, SystemClock::shared())
    }

    /// Serves `link` with simulated time on `clock`, finding requests with `scanner`;
    /// wraps the link for pacing and faults. A server for an in-process
    /// [`crate::SimLink`] takes the host's clock (a [`motus_clock::VirtualClock`]); its
    /// link is then not used (e.g. [`crate::NullLink`]).
    ///
    /// # Errors
    /// A fault rate outside 0..=1.
    pub fn with_clock(
        link: Box<dyn Link>,
        scanner: S,
        options: ServeOptions,
        clock: SharedClock,
    ) -> Result<Self, RateError> {
        options.faults.check()?;
        let line = link.line();
        let mut link = link;
        if options.baud_pacing {
            link = Box::new(Paced::with_clock(link, Arc::clone(&clock)));
        }
        if options.faults.is_active() {
            // Outside the pacing: a dropped answer is a whole answer.
            link = Box::new(FaultInjector::new(link, options.faults));
        }
        Ok(SimServer { link, core: Core::new(scanner, options, clock, line) })
    }

    /// When simulated time started.
    pub fn start(&self) -> Instant {
        self.core.start
    }

    /// Simulated time now: the clock's time since the start.
    pub fn now(&self) -> Duration {
        self.core.clock.elapsed(self.core.start)
    }

    /// The clock of simulated time.
    pub fn clock(&self) -> &SharedClock {
        &self.core.clock
    }

    /// How the line behaves.
    pub fn options(&self) -> &ServeOptions {
        &self.core.options
    }

    /// The settings of the line served (the link's when the server was made).
    pub fn line(&self) -> LineSettings {
        self.core.line
    }

    /// Answers sent so far.
    pub fn frames_served(&self) -> u64 {
        self.core.frames_served
    }

    /// The request decoder's totals (frames, garbage bytes, corrupt frames).
    pub fn decoder_stats(&self) -> StreamStats {
        self.core.decoder.stats()
    }

    /// The serving state, without the link (for an inline [`crate::SimLink`]).
    pub(crate) fn into_core(self) -> Core<S> {
        self.core
    }

    /// Serves until `stop` is set.
    ///
    /// # Errors
    /// An IO error of the link, or of the responder's `tick`.
    pub fn run<R>(&mut self, responder: &mut R, stop: &AtomicBool) -> io::Result<()>
    where
        R: Responder<Frame = S::Frame, Error = S::Error>,
        S::Error: std::fmt::Debug,
    {
        let clock = Arc::clone(&self.core.clock);
        let mut buf = [0u8; 256];
        let poll = self.core.options.poll;
        let mut looked = clock.now();
        while !stop.load(Ordering::Relaxed) {
            let n = self.link.read(&mut buf, poll)?;
            let now = clock.now();
            // Woken far later than the read's time-out: this thread was not running.
            let late = now.saturating_duration_since(looked).saturating_sub(poll);
            if late >= STALL {
                tracing::debug!(late_ms = late.as_millis(), "simulator thread stalled");
                responder.simulator_stalled(late);
            }
            let mut port = ThreadedPort { link: &mut *self.link, clock: &*clock };
            if self.core.idle_flush_at().is_some_and(|at| now >= at) {
                self.core.flush(responder, &mut port)?;
            }
            self.core.receive(buf.get(..n).unwrap_or_default(), now, now, responder, &mut port)?;
            self.core.tick(clock.now(), responder)?;
            looked = clock.now();
        }
        self.core.tick(clock.now(), responder)
    }
}

/// A simulated line served on its own thread (at simulator priority) until
/// [`ServeThread::stop`] or drop.
pub struct ServeThread<L> {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<io::Result<L>>>,
}

impl<L: Send + 'static> ServeThread<L> {
    /// Starts `serve(line, stop)` on a thread named `name`, e.g.
    /// `ServeThread::spawn("sim", line, SimLine::run)`.
    ///
    /// # Errors
    /// The thread could not be spawned.
    pub fn spawn<F>(name: &str, mut line: L, serve: F) -> io::Result<Self>
    where
        F: FnOnce(&mut L, &AtomicBool) -> io::Result<()> + Send + 'static,
    {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&stop);
        let thread = std::thread::Builder::new().name(name.into()).spawn(move || {
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Simulator);
            serve(&mut line, &flag).map(|()| line)
        })?;
        Ok(ServeThread { stop, thread: Some(thread) })
    }

    /// Stops serving and returns the line (its devices can then be inspected).
    ///
    /// # Errors
    /// The line's IO error, or the thread panicked.
    pub fn stop(mut self) -> io::Result<L> {
        self.stop.store(true, Ordering::Relaxed);
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            Some(Err(_)) | None => Err(io::Error::other("the simulator thread panicked")),
        }
    }
}

impl<L> Drop for ServeThread<L> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
