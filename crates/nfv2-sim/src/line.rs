//! Serving one or more controllers on one serial link (the RS-485 bus, or a PC's USB to a
//! gateway module), with the serial simulators' one loop ([`SimServer`]).
//!
//! The line finds frames with the codec's resynchronising [`StreamDecoder`] (a frame is
//! `'#' n !n`, not line silence, so no idle-gap flush); a frame with a bad CRC is ignored
//! by every controller. Every controller sees every frame (broadcast set-points reach all
//! of them); the one it is addressed to answers, the others stay silent.
//!
//! Timing of an answer, from the request's last byte: the controller's processing delay
//! (`reply_delay`, default 0.2 ms: the reference answers from its receive interrupt),
//! plus, when the address plan's **gateway** is among the served addresses and the frame
//! is for another controller, the relay over the internal RS-485 bus (request and answer
//! at 57600 bps plus that controller's processing delay). With **baud pacing** the request
//! takes its wire time at the link's baud rate to arrive and the answer leaves byte by
//! byte at that rate. **Faults**: dropped answers and corrupted bytes (answers and received
//! bytes), seeded.
//!
//! The controllers are shared ([`SharedController`]) so a test can read the true state and
//! poke inputs while [`SimLine::run`] serves them on another thread; [`SimClock`] gives the
//! line's time, so a test can bring a controller up to date before poking it.
//!
//! Simulated time is on a [`motus_clock::Clock`]: the system clock for [`SimLine::new`], any clock for
//! [`SimLine::with_clock`]. On a virtual clock the line is served **in process** by
//! [`SimLine::into_sim_link`]: a [`SimLink`] is the host's link, and the same serve step of
//! [`SimServer`] runs inline in the host's thread, the answers reaching the host after
//! their wire time and delays on that clock:
//!
//! ```
//! use motus_clock::VirtualClock;
//! use motus_nfv2_protocol::{Command, CommandCode as C, Frame, FrameScanner, Revision};
//! use motus_nfv2_sim::{LineOptions, SimLine};
//! use motus_serial::{FramedLink, LineSettings, NullLink};
//! use std::time::Duration;
//!
//! let clock = VirtualClock::new();
//! let null = NullLink::new(LineSettings::n81(57_600));
//! let options = LineOptions { baud_pacing: true, ..LineOptions::default() };
//! let line = SimLine::with_clock(Box::new(null), options, clock.shared()).unwrap();
//! let link = line.into_sim_link();
//! let mut host = FramedLink::with_clock(Box::new(link), FrameScanner::new(Revision::LATEST), clock.shared());
//! let query = Frame { address: 1, commands: vec![Command::query(C::ReadDrivesPosition)] };
//! host.send(&query.encode(Revision::LATEST).unwrap()).unwrap();
//! let answer = host.receive(Duration::from_millis(100)).unwrap().unwrap();
//! assert_eq!(answer.int_values(C::ReadDrivesPosition), Some(&[0][..]));
//! // 7 + 11 bytes at 57600 Bd and the 0.2 ms processing delay, in virtual time.
//! let wire = LineSettings::n81(57_600);
//! assert_eq!(clock.since_base(), wire.wire_time(7) + wire.wire_time(11) + Duration::from_micros(200));
//! ```

use std::collections::BTreeSet;
use std::io;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use motus_clock::{SharedClock, SystemClock};
use motus_nfv2_protocol::{wire_time, AddressPlan, DecodeError, Frame, FrameScanner, Revision, RS485_BAUD};
use motus_serial::{Answer, FaultConfig, LineSettings, Link, Responder, ServeOptions, SimLink, SimServer};

use crate::config::ControllerConfig;
use crate::controller::Controller;
use crate::error::SimError;

/// A controller shared between the serving thread and a test.
pub type SharedController = Arc<Mutex<Controller>>;

/// Locks a shared controller (a panic elsewhere does not stop the simulator).
pub fn lock(controller: &SharedController) -> MutexGuard<'_, Controller> {
    controller.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Default processing delay before an answer starts.
pub const DEFAULT_REPLY_DELAY: Duration = Duration::from_micros(200);

/// Options of a simulated line (what `motus sim nfv2` sets).
#[derive(Debug, Clone)]
pub struct LineOptions {
    /// Addresses of the controllers (DIP switches), one controller each.
    pub addresses: Vec<u8>,
    /// What address 0 (or 0xFF) means: gateway or broadcast.
    pub address_plan: AddressPlan,
    /// Protocol revision of every controller (value widths, mode numbers).
    pub revision: Revision,
    /// Bytes take their wire time at the link's baud rate (use on ptys only).
    pub baud_pacing: bool,
    /// Dropped answers and corrupted bytes, with their seed.
    pub faults: FaultConfig,
    /// Processing delay between a request's last byte and its answer (`--delay-ms`).
    pub reply_delay: Duration,
    /// Every controller's configuration (the noise seed is varied by address).
    pub controller: ControllerConfig,
}

impl Default for LineOptions {
    fn default() -> Self {
        LineOptions {
            addresses: vec![1],
            address_plan: AddressPlan::default(),
            revision: Revision::LATEST,
            baud_pacing: false,
            faults: FaultConfig::default(),
            reply_delay: DEFAULT_REPLY_DELAY,
            controller: ControllerConfig::default(),
        }
    }
}

impl LineOptions {
    /// Uses `seed` for the fault injection and the controllers' measurement noise (what
    /// the CLI's `--seed` sets).
    #[must_use]
    pub fn seeded(mut self, seed: u64) -> Self {
        self.faults.seed = seed;
        self.controller.seed = seed;
        self
    }
}

/// Errors starting a simulated line.
pub type LineError = motus_serial::LineError<SimError>;

/// The line's clock: simulated time is the time since the line started, on the line's
/// [`motus_clock::Clock`].
#[derive(Debug, Clone)]
pub struct SimClock {
    start: Instant,
    clock: SharedClock,
}

impl SimClock {
    /// Simulated time now.
    #[must_use]
    pub fn now(&self) -> Duration {
        self.clock.elapsed(self.start)
    }

    /// The host instant at which simulated time is zero.
    #[must_use]
    pub fn start(&self) -> Instant {
        self.start
    }

    /// The clock simulated time is on.
    #[must_use]
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }

    /// Simulated time of `instant`.
    #[must_use]
    pub fn at(&self, instant: Instant) -> Duration {
        instant.saturating_duration_since(self.start)
    }
}

/// Simulated controllers serving one link.
pub struct SimLine {
    server: SimServer<FrameScanner>,
    served: Controllers,
    addresses: Vec<u8>,
    line: LineSettings,
}

/// The controllers as the line serves them: the line's [`Responder`] (every controller
/// sees every frame; the addressed one answers).
pub struct Controllers {
    controllers: Vec<SharedController>,
    revision: Revision,
    reply_delay: Duration,
    gateway: Option<u8>,
}

impl SimLine {
    /// Powers the controllers on, serving `link` on the system clock.
    ///
    /// # Errors
    /// [`LineError::Options`] for bad options, [`LineError::Model`] for a bad
    /// configuration.
    pub fn new(link: Box<dyn Link>, options: LineOptions) -> Result<SimLine, LineError> {
        Self::with_clock(link, options, SystemClock::shared())
    }

    /// Powers the controllers on, serving `link` with simulated time on `clock` (see the
    /// module documentation; for an in-process line, [`SimLine::into_sim_link`]).
    ///
    /// # Errors
    /// As [`SimLine::new`].
    pub fn with_clock(
        link: Box<dyn Link>,
        options: LineOptions,
        clock: SharedClock,
    ) -> Result<SimLine, LineError> {
        check(&options)?;
        let controllers = options
            .addresses
            .iter()
            .map(|&a| {
                Controller::with_protocol(a, options.address_plan, options.revision, &options.controller)
                    .map(|c| Arc::new(Mutex::new(c)))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let serve = ServeOptions {
            baud_pacing: options.baud_pacing,
            faults: options.faults,
            poll: Duration::from_millis(2),
            flush_when_idle: false,
        };
        let line = link.line();
        let server = SimServer::with_clock(link, FrameScanner::new(options.revision), serve, clock)
            .map_err(|e| LineError::Options(e.to_string()))?;
        let gateway = options.address_plan.gateway.filter(|g| options.addresses.contains(g));
        let served = Controllers {
            controllers,
            revision: options.revision,
            reply_delay: options.reply_delay,
            gateway,
        };
        Ok(SimLine { server, served, addresses: options.addresses, line })
    }

    /// The controllers with their addresses, in the order of the options.
    #[must_use]
    pub fn controllers(&self) -> Vec<(u8, SharedController)> {
        self.addresses.iter().copied().zip(self.served.controllers.iter().cloned()).collect()
    }

    /// The controller at `address`, if served.
    #[must_use]
    pub fn controller(&self, address: u8) -> Option<SharedController> {
        let i = self.addresses.iter().position(|&a| a == address)?;
        self.served.controllers.get(i).cloned()
    }

    /// The line's clock.
    #[must_use]
    pub fn clock(&self) -> SimClock {
        SimClock { start: self.server.start(), clock: Arc::clone(self.server.clock()) }
    }

    /// The serve loop (answers sent, the request decoder's statistics, simulated time).
    #[must_use]
    pub fn server(&self) -> &SimServer<FrameScanner> {
        &self.server
    }

    /// The line served in process instead (see the module documentation): the host's
    /// link, at the line settings of the link the line was made with (a
    /// [`motus_serial::NullLink`] will do), serving the controllers inline on the line's
    /// clock with the same options (pacing, delays, faults and their seed). The host's
    /// bus master or framed link must wait on the same clock ([`SimLink::clock`]); the
    /// controllers stay shared ([`SimLine::controllers`], [`SimLink::responder`]).
    #[must_use]
    pub fn into_sim_link(self) -> SimLink<FrameScanner, Controllers> {
        SimLink::new(self.server, Arc::new(Mutex::new(self.served)), self.line)
    }

    /// Serves the line until `stop` is set.
    ///
    /// # Errors
    /// An IO error of the link.
    pub fn run(&mut self, stop: &AtomicBool) -> io::Result<()> {
        self.server.run(&mut self.served, stop)
    }
}

impl Controllers {
    /// The controllers, in the order of the line's addresses.
    #[must_use]
    pub fn controllers(&self) -> &[SharedController] {
        &self.controllers
    }
}

impl Responder for Controllers {
    type Frame = Frame;
    type Error = DecodeError;

    /// Hands one frame to every controller; the answer, if any, is due after the
    /// processing delay (and the relay over the gateway).
    /// A frame with a bad CRC is ignored by every controller (the default
    /// [`Responder::corrupt`]).
    fn respond(&mut self, frame: Frame, now: Duration) -> Option<Answer> {
        let mut reply = None;
        for c in &self.controllers {
            if let Some(r) = lock(c).handle(&frame, now) {
                reply = Some(r);
            }
        }
        let mut answer = Answer::encoded(reply?.encode(self.revision), self.reply_delay)?;
        if self.gateway.is_some_and(|g| g != frame.address) {
            let request_len = frame.encoded_len(self.revision).unwrap_or(0);
            answer.delay += wire_time(request_len, RS485_BAUD)
                + self.reply_delay
                + wire_time(answer.bytes.len(), RS485_BAUD);
        }
        Some(answer)
    }

    /// Brings every controller up to the line's time.
    fn tick(&mut self, now: Duration) -> io::Result<()> {
        for c in &self.controllers {
            lock(c).advance_to(now);
        }
        Ok(())
    }
}

fn check(options: &LineOptions) -> Result<(), LineError> {
    let bad = |m: String| Err(LineError::Options(m));
    if options.addresses.is_empty() {
        return bad("at least one controller address is needed".into());
    }
    let mut seen = BTreeSet::new();
    if let Some(dup) = options.addresses.iter().find(|a| !seen.insert(**a)) {
        return bad(format!("address {dup} is given twice"));
    }
    if let Some(b) = options.address_plan.broadcast.filter(|b| options.addresses.contains(b)) {
        return bad(format!("address {b} is the broadcast address of the plan"));
    }
    options.faults.check().or_else(|e| bad(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_are_checked() {
        let with = |addresses: Vec<u8>, plan: AddressPlan| LineOptions {
            addresses,
            address_plan: plan,
            ..LineOptions::default()
        };
        assert!(check(&with(vec![], AddressPlan::default())).is_err());
        assert!(check(&with(vec![1, 1], AddressPlan::default())).is_err());
        assert!(check(&with(vec![0, 1], AddressPlan::REFERENCE_BROADCAST_0)).is_err());
        assert!(check(&with(vec![0, 1], AddressPlan::SEED_1209A)).is_ok());
        let mut o = LineOptions::default().seeded(7);
        assert_eq!((o.faults.seed, o.controller.seed), (7, 7));
        o.faults.drop_rate = 1.5;
        assert!(check(&o).is_err());
    }
}
