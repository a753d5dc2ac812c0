//! Serving the arm on one serial link (the RS-485 line behind the interface box), with the
//! serial simulators' one loop ([`SimServer`]).
//!
//! The line decodes host messages with the codec's resynchronising [`StreamDecoder`]
//! (strict CRC: a module ignores a message with a bad CRC); the module whose address
//! matches answers, the others stay silent. When the line has been quiet for three
//! character times (at least 2 ms) the decoder is flushed: a half-received message is
//! dropped like garbage.
//!
//! [`StreamDecoder`]: motus_kv01_protocol::StreamDecoder
//! Options model the real line: **pacing** (a request takes its wire time to arrive and the
//! reply leaves byte by byte at the baud rate), the modules' own **delays** (turnaround and
//! the controller exchange, applied always), and **faults** (dropped replies, corrupted bytes
//! in both directions, a slow controller).
//!
//! The arm is shared ([`SharedArm`]) so a test can poke it (push a joint onto its switch,
//! power-cycle) while [`SimLine::run`] serves it on another thread.
//!
//! In-process, on a virtual clock: [`SimLine::sim_link`] gives the host a
//! [`motus_serial::SimLink`] that runs the same serve step inline in the host's thread
//! (answers after their wire time and delays, faults seeded), so a driver and the arm run
//! in one test on virtual time.

use std::io;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use motus_clock::{SharedClock, SystemClock};
use motus_kv01_protocol::{CrcFailure, CrcMode, Decoded, Message, MessageScanner};
use motus_serial::{
    Answer, FaultConfig, LineSettings, Link, NullLink, Responder, ServeOptions, SimLink, SimServer,
};

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
pub type LineError = motus_serial::LineError<SimError>;

/// The simulated arm serving one link.
pub struct SimLine {
    server: SimServer<MessageScanner>,
    served: ServedArm,
}

/// The arm as the line serves it (the [`Responder`] of its serve step).
pub struct ServedArm {
    arm: SharedArm,
}

impl ServedArm {
    /// The served arm.
    #[must_use]
    pub fn arm(&self) -> SharedArm {
        Arc::clone(&self.arm)
    }
}

/// The host's side of a simulated arm served in-process ([`SimLine::sim_link`]).
pub type ArmSimLink = SimLink<MessageScanner, ServedArm>;

impl SimLine {
    /// Powers the arm on, serving `link` on the system clock.
    pub fn new(link: Box<dyn Link>, options: LineOptions) -> Result<SimLine, LineError> {
        let (server, arm) = Self::parts(link, options, SystemClock::shared())?;
        Ok(SimLine { server, served: ServedArm { arm } })
    }

    /// Powers the arm on and serves it in-process on `clock`: the returned link is the
    /// host's end of a line of `line`'s settings, running the serve step (pacing, idle
    /// flush, seeded faults: `options`) inline in the caller's thread. Give the host's bus
    /// master the same clock ([`SimLink::clock`]). The shared arm is for the test to
    /// inspect and poke.
    pub fn sim_link(
        options: LineOptions,
        line: LineSettings,
        clock: SharedClock,
    ) -> Result<(ArmSimLink, SharedArm), LineError> {
        let (server, arm) = Self::parts(Box::new(NullLink::new(line)), options, clock)?;
        let served = Arc::new(Mutex::new(ServedArm { arm: Arc::clone(&arm) }));
        Ok((SimLink::new(server, served, line), arm))
    }

    /// The serve loop of `options` on `link` and `clock`, and the arm powered on.
    fn parts(
        link: Box<dyn Link>,
        options: LineOptions,
        clock: SharedClock,
    ) -> Result<(SimServer<MessageScanner>, SharedArm), LineError> {
        let serve = ServeOptions {
            baud_pacing: options.baud_pacing,
            faults: options.faults,
            poll: Duration::from_millis(5),
            flush_when_idle: true,
        };
        let server = SimServer::with_clock(link, MessageScanner::requests(CrcMode::Strict), serve, clock)
            .map_err(|e| LineError::Options(e.to_string()))?;
        let mut arm = Arm::new(&options.arm)?;
        if let Some(delay) = options.slow_controller {
            arm.set_controller_delay(delay);
        }
        Ok((server, Arc::new(Mutex::new(arm))))
    }

    /// The shared arm (lock it with [`lock`]).
    #[must_use]
    pub fn arm(&self) -> SharedArm {
        Arc::clone(&self.served.arm)
    }

    /// The serve loop (requests answered, the request decoder's statistics, simulated
    /// time).
    #[must_use]
    pub fn server(&self) -> &SimServer<MessageScanner> {
        &self.server
    }

    /// Serves the line until `stop` is set.
    pub fn run(&mut self, stop: &AtomicBool) -> io::Result<()> {
        self.server.run(&mut self.served, stop)
    }
}

impl Responder for ServedArm {
    type Frame = Decoded;
    type Error = CrcFailure;

    /// A module ignores a message with a bad CRC (the default [`Responder::corrupt`]).
    fn respond(&mut self, decoded: Decoded, now: Duration) -> Option<Answer> {
        let Message::Request(request) = decoded.message else { return None };
        let timed = lock(&self.arm).respond(&request, now)?;
        Answer::encoded(Message::Reply(timed.reply).encode(), timed.delay)
    }

    fn tick(&mut self, now: Duration) -> io::Result<()> {
        lock(&self.arm).advance_to(now);
        Ok(())
    }

    /// The modules' 700 ms watch does not count the simulator's own stall.
    fn simulator_stalled(&mut self, gap: Duration) {
        lock(&self.arm).excuse_silence(gap);
    }
}
