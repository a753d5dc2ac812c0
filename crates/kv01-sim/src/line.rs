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

use std::io;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use motus_kv01_protocol::{CrcFailure, CrcMode, Decoded, Message, MessageScanner};
use motus_serial::{Answer, FaultConfig, Link, Responder, ServeOptions, SimServer};

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

/// The arm as the line serves it.
struct ServedArm {
    arm: SharedArm,
}

impl SimLine {
    /// Powers the arm on, serving `link`.
    pub fn new(link: Box<dyn Link>, options: LineOptions) -> Result<SimLine, LineError> {
        let serve = ServeOptions {
            baud_pacing: options.baud_pacing,
            faults: options.faults,
            poll: Duration::from_millis(5),
            flush_when_idle: true,
        };
        let server = SimServer::new(link, MessageScanner::requests(CrcMode::Strict), serve)
            .map_err(|e| LineError::Options(e.to_string()))?;
        let mut arm = Arm::new(&options.arm)?;
        if let Some(delay) = options.slow_controller {
            arm.set_controller_delay(delay);
        }
        Ok(SimLine { server, served: ServedArm { arm: Arc::new(Mutex::new(arm)) } })
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
}
