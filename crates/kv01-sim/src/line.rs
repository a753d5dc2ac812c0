//! Serving the arm on one serial link (the RS-485 line behind the interface box).
//!
//! The line decodes host messages with the resynchronising [`StreamDecoder`] (strict CRC:
//! a module ignores a message with a bad CRC); the module whose address matches answers,
//! the others stay silent. When the line has been quiet for three character times (at least
//! 2 ms) the decoder is flushed: a half-received message is dropped like garbage.
//! Options model the real line: **pacing** (a request takes its wire time to arrive and the
//! reply leaves byte by byte at the baud rate), the modules' own **delays** (turnaround and
//! the controller exchange, applied always), and **faults** (dropped replies, corrupted bytes
//! in both directions, a slow controller).
//!
//! The arm is shared ([`SharedArm`]) so a test can poke it (push a joint onto its switch,
//! power-cycle) while [`SimLine::run`] serves it on another thread.

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use motus_kv01_protocol::{CrcMode, Message, StreamDecoder, StreamEvent, StreamStats};
use motus_serial::{sleep_until, FaultConfig, FaultInjector, Link, Paced};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use crate::arm::Arm;
use crate::config::ArmConfig;
use crate::error::SimError;

/// The arm shared between the serving thread and a test.
pub type SharedArm = Arc<Mutex<Arm>>;

/// Locks a shared arm (a panic elsewhere does not stop the simulator).
pub fn lock(arm: &SharedArm) -> MutexGuard<'_, Arm> {
    arm.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Options of a simulated line (what `motus sim kv01` sets).
#[derive(Debug, Clone, Default)]
pub struct LineOptions {
    /// Bytes take their real wire time at the link's baud rate (use on ptys only).
    pub baud_pacing: bool,
    /// Dropped replies and corrupted bytes (replies and received bytes), with their seed.
    pub faults: FaultConfig,
    /// Every controller answers this much later than normal (beyond the module's wait, D0
    /// is answered "TIMEOUT").
    pub slow_controller: Option<Duration>,
    /// The simulated arm.
    pub arm: ArmConfig,
}

impl LineOptions {
    /// Uses `seed` for the fault injection and for the arm's measurement noise (what the
    /// CLI's `--seed` sets).
    #[must_use]
    pub fn seeded(mut self, seed: u64) -> Self {
        self.faults.seed = seed;
        self.arm.seed = seed;
        self
    }
}

/// Errors starting a simulated line.
#[derive(Debug, thiserror::Error)]
pub enum LineError {
    /// Bad options (rates outside 0..=1).
    #[error("invalid simulator options: {0}")]
    Options(String),
    /// Bad arm configuration.
    #[error(transparent)]
    Arm(#[from] SimError),
}

/// The simulated arm serving one link.
pub struct SimLine {
    arm: SharedArm,
    link: Box<dyn Link>,
    stream: StreamDecoder,
    options: LineOptions,
    start: Instant,
    rx_rng: SmallRng,
    frames_served: u64,
}

impl SimLine {
    /// Powers the arm on, serving `link`.
    pub fn new(link: Box<dyn Link>, options: LineOptions) -> Result<SimLine, LineError> {
        for (name, rate) in
            [("drop rate", options.faults.drop_rate), ("corrupt rate", options.faults.corrupt_rate)]
        {
            if !(0.0..=1.0).contains(&rate) {
                return Err(LineError::Options(format!("{name} must be within 0..=1, got {rate}")));
            }
        }
        let mut arm = Arm::new(&options.arm)?;
        if let Some(delay) = options.slow_controller {
            arm.set_controller_delay(delay);
        }
        let mut link = link;
        if options.faults.drop_rate > 0.0 || options.faults.corrupt_rate > 0.0 {
            link = Box::new(FaultInjector::new(link, options.faults));
        }
        if options.baud_pacing {
            link = Box::new(Paced::new(link));
        }
        Ok(SimLine {
            arm: Arc::new(Mutex::new(arm)),
            link,
            stream: StreamDecoder::requests(CrcMode::Strict),
            rx_rng: SmallRng::seed_from_u64(options.faults.seed ^ 0x5eed),
            options,
            start: Instant::now(),
            frames_served: 0,
        })
    }

    /// The shared arm (lock it with [`lock`]).
    #[must_use]
    pub fn arm(&self) -> SharedArm {
        Arc::clone(&self.arm)
    }

    /// Requests answered so far.
    #[must_use]
    pub fn frames_served(&self) -> u64 {
        self.frames_served
    }

    /// The request decoder's totals (frames, garbage bytes, CRC failures).
    #[must_use]
    pub fn decoder_stats(&self) -> StreamStats {
        self.stream.stats()
    }

    /// Simulated time: time since the line started.
    #[must_use]
    pub fn now(&self) -> Duration {
        self.start.elapsed()
    }

    /// Serves the line until `stop` is set.
    pub fn run(&mut self, stop: &AtomicBool) -> io::Result<()> {
        let line = self.link.line();
        let idle_gap = (line.char_time() * 3).max(Duration::from_millis(2));
        let mut buf = [0u8; 256];
        let mut first_byte_at: Option<Instant> = None;
        let mut last_byte_at = Instant::now();
        while !stop.load(Ordering::Relaxed) {
            let n = self.link.read(&mut buf, Duration::from_millis(5))?;
            let now_i = Instant::now();
            let quiet = now_i.saturating_duration_since(last_byte_at) > idle_gap;
            if quiet && self.stream.buffered() > 0 {
                self.stream.flush();
                self.serve(first_byte_at)?;
                self.stream.clear();
                first_byte_at = None;
            }
            if n == 0 {
                self.tick();
                continue;
            }
            if first_byte_at.is_none() {
                first_byte_at = Some(now_i);
            }
            last_byte_at = now_i;
            let data = buf.get_mut(..n).unwrap_or_default();
            let rate = self.options.faults.corrupt_rate;
            if rate > 0.0 {
                for b in data.iter_mut() {
                    if self.rx_rng.gen_bool(rate) {
                        *b ^= self.rx_rng.gen_range(1..=255u8);
                    }
                }
            }
            self.stream.push(data);
            if self.serve(first_byte_at)? {
                first_byte_at = None;
            }
            if self.stream.buffered() == 0 {
                first_byte_at = None;
            }
        }
        self.tick();
        Ok(())
    }

    /// Answers every message decoded so far; true if any was decoded.
    fn serve(&mut self, first_byte_at: Option<Instant>) -> io::Result<bool> {
        let line = self.link.line();
        let mut any = false;
        while let Some(event) = self.stream.next_event() {
            let decoded = match event {
                StreamEvent::Frame(d) => d,
                StreamEvent::Garbage { bytes } => {
                    tracing::debug!(bytes, "skipped garbage");
                    continue;
                }
                StreamEvent::CrcFailure { address, mismatch } => {
                    tracing::debug!(address, ?mismatch, "ignored a message with a bad CRC");
                    continue;
                }
            };
            any = true;
            let Message::Request(request) = decoded.message else { continue };
            // The request has arrived once its last byte is on the wire.
            let arrived = match (self.options.baud_pacing, first_byte_at) {
                (true, Some(t0)) => {
                    let len = Message::Request(request.clone()).encode().map_or(0, |b| b.len());
                    let at = t0 + line.wire_time(len);
                    sleep_until(at);
                    at
                }
                _ => Instant::now(),
            };
            let now = arrived.saturating_duration_since(self.start);
            let timed = lock(&self.arm).respond(&request, now);
            let Some(timed) = timed else { continue };
            let bytes = match Message::Reply(timed.reply).encode() {
                Ok(b) => b,
                Err(e) => {
                    tracing::warn!(error = %e, "cannot encode a reply");
                    continue;
                }
            };
            sleep_until(arrived + timed.delay);
            self.link.write_all(&bytes)?;
            self.frames_served += 1;
        }
        Ok(any)
    }

    fn tick(&mut self) {
        let now = self.now();
        lock(&self.arm).advance_to(now);
    }
}
