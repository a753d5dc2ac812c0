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
//! Simulated time is the time since the server was created ([`SimServer::now`]). A
//! [`ServeThread`] runs a simulated line on its own thread until stopped.

use crate::link::fault::{FaultConfig, FaultInjector, RateError};
use crate::link::paced::{sleep_until, Paced};
use crate::link::Link;
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
    fn tick(&mut self, now: Duration) -> io::Result<()>;
}

/// Serves a [`Responder`] on a link (see the module documentation).
pub struct SimServer<S> {
    link: Box<dyn Link>,
    decoder: Stream<S>,
    options: ServeOptions,
    start: Instant,
    frames_served: u64,
}

impl<S: Scanner> SimServer<S> {
    /// Serves `link`, finding requests with `scanner`; wraps the link for pacing and faults.
    ///
    /// # Errors
    /// A fault rate outside 0..=1.
    pub fn new(link: Box<dyn Link>, scanner: S, options: ServeOptions) -> Result<Self, RateError> {
        options.faults.check()?;
        let mut link = link;
        if options.baud_pacing {
            link = Box::new(Paced::new(link));
        }
        if options.faults.is_active() {
            // Outside the pacing: a dropped answer is a whole answer.
            link = Box::new(FaultInjector::new(link, options.faults));
        }
        Ok(SimServer {
            link,
            decoder: Stream::new(scanner),
            options,
            start: Instant::now(),
            frames_served: 0,
        })
    }

    /// When simulated time started.
    pub fn start(&self) -> Instant {
        self.start
    }

    /// Simulated time now.
    pub fn now(&self) -> Duration {
        self.start.elapsed()
    }

    /// Answers sent so far.
    pub fn frames_served(&self) -> u64 {
        self.frames_served
    }

    /// The request decoder's totals (frames, garbage bytes, corrupt frames).
    pub fn decoder_stats(&self) -> StreamStats {
        self.decoder.stats()
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
        let idle_gap = (self.link.line().char_time() * 3).max(Duration::from_millis(2));
        let mut buf = [0u8; 256];
        let mut first_byte_at: Option<Instant> = None;
        let mut last_byte_at = Instant::now();
        while !stop.load(Ordering::Relaxed) {
            let n = self.link.read(&mut buf, self.options.poll)?;
            let now = Instant::now();
            let quiet = now.saturating_duration_since(last_byte_at) > idle_gap;
            if self.options.flush_when_idle && quiet && self.decoder.pending() > 0 {
                self.decoder.flush();
                self.serve(responder, &mut first_byte_at)?;
                self.decoder.clear();
                first_byte_at = None;
            }
            if n > 0 {
                first_byte_at.get_or_insert(now);
                last_byte_at = now;
                self.decoder.push(buf.get(..n).unwrap_or_default());
                self.serve(responder, &mut first_byte_at)?;
                if self.decoder.pending() == 0 {
                    first_byte_at = None;
                }
            }
            responder.tick(self.now())?;
        }
        responder.tick(self.now())
    }

    /// Hands every request decoded so far to `responder` and sends the answers on time. The
    /// first request takes `first_byte_at` as the time its first byte arrived.
    fn serve<R>(&mut self, responder: &mut R, first_byte_at: &mut Option<Instant>) -> io::Result<()>
    where
        R: Responder<Frame = S::Frame, Error = S::Error>,
        S::Error: std::fmt::Debug,
    {
        let line = self.link.line();
        let mut frame_bytes = self.decoder.stats().frame_bytes;
        while let Some(request) = self.decoder.next_event() {
            if let StreamEvent::Garbage { bytes } = request {
                tracing::debug!(bytes, "skipped garbage");
                continue;
            }
            // A frame has arrived once its last byte is on the wire (a corrupt one, whose
            // length is unknown, when it is seen).
            let frame_len = self.decoder.stats().frame_bytes.saturating_sub(frame_bytes);
            frame_bytes += frame_len;
            let arrived = match (self.options.baud_pacing, first_byte_at.take(), &request) {
                (true, Some(t0), StreamEvent::Frame(_)) => {
                    let at = t0 + line.wire_time(usize::try_from(frame_len).unwrap_or(usize::MAX));
                    sleep_until(at);
                    at
                }
                _ => Instant::now(),
            };
            let now = arrived.saturating_duration_since(self.start);
            let answer = match request {
                StreamEvent::Frame(frame) => responder.respond(frame, now),
                StreamEvent::Corrupt(error) => {
                    tracing::debug!(?error, "corrupt request");
                    responder.corrupt(error, now)
                }
                StreamEvent::Garbage { .. } => None,
            };
            let Some(answer) = answer else { continue };
            sleep_until(arrived + answer.delay);
            self.link.write_all(&answer.bytes)?;
            self.frames_served += 1;
        }
        Ok(())
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
