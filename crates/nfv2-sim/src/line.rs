//! Serving one or more controllers on one serial link (the RS-485 bus, or a PC's USB to a
//! gateway module).
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

use std::collections::BTreeSet;
use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use motus_nfv2_protocol::{wire_time, AddressPlan, Frame, Revision, StreamDecoder, StreamStats, RS485_BAUD};
use motus_serial::{sleep_until, FaultConfig, FaultInjector, Link, Paced};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

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
#[derive(Debug, thiserror::Error)]
pub enum LineError {
    /// Bad options (no address, a duplicate, the broadcast address, rates outside 0..=1).
    #[error("invalid simulator options: {0}")]
    Options(String),
    /// Bad controller configuration.
    #[error(transparent)]
    Controller(#[from] SimError),
}

/// The line's clock: simulated time is the time since the line started.
#[derive(Debug, Clone, Copy)]
pub struct SimClock {
    start: Instant,
}

impl SimClock {
    /// Simulated time now.
    #[must_use]
    pub fn now(&self) -> Duration {
        self.start.elapsed()
    }

    /// Simulated time of `instant`.
    #[must_use]
    pub fn at(&self, instant: Instant) -> Duration {
        instant.saturating_duration_since(self.start)
    }
}

/// Simulated controllers serving one link.
pub struct SimLine {
    controllers: Vec<SharedController>,
    link: Box<dyn Link>,
    decoder: StreamDecoder,
    options: LineOptions,
    gateway: Option<u8>,
    clock: SimClock,
    rx_rng: SmallRng,
    frames_served: u64,
}

impl SimLine {
    /// Powers the controllers on, serving `link`.
    ///
    /// # Errors
    /// [`LineError::Options`] for bad options, [`LineError::Controller`] for a bad
    /// configuration.
    pub fn new(link: Box<dyn Link>, options: LineOptions) -> Result<SimLine, LineError> {
        check(&options)?;
        let controllers = options
            .addresses
            .iter()
            .map(|&a| {
                Controller::with_protocol(a, options.address_plan, options.revision, &options.controller)
                    .map(|c| Arc::new(Mutex::new(c)))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut link = link;
        if options.faults.drop_rate > 0.0 || options.faults.corrupt_rate > 0.0 {
            link = Box::new(FaultInjector::new(link, options.faults));
        }
        if options.baud_pacing {
            link = Box::new(Paced::new(link));
        }
        let gateway = options.address_plan.gateway.filter(|g| options.addresses.contains(g));
        Ok(SimLine {
            controllers,
            link,
            decoder: StreamDecoder::new(options.revision),
            gateway,
            rx_rng: SmallRng::seed_from_u64(options.faults.seed ^ 0x5eed),
            options,
            clock: SimClock { start: Instant::now() },
            frames_served: 0,
        })
    }

    /// The controllers with their addresses, in the order of the options.
    #[must_use]
    pub fn controllers(&self) -> Vec<(u8, SharedController)> {
        self.options.addresses.iter().copied().zip(self.controllers.iter().cloned()).collect()
    }

    /// The controller at `address`, if served.
    #[must_use]
    pub fn controller(&self, address: u8) -> Option<SharedController> {
        let i = self.options.addresses.iter().position(|&a| a == address)?;
        self.controllers.get(i).cloned()
    }

    /// The line's clock.
    #[must_use]
    pub fn clock(&self) -> SimClock {
        self.clock
    }

    /// Answers sent so far.
    #[must_use]
    pub fn frames_served(&self) -> u64 {
        self.frames_served
    }

    /// The request decoder's totals (frames, garbage bytes, CRC failures).
    #[must_use]
    pub fn decoder_stats(&self) -> StreamStats {
        self.decoder.stats()
    }

    /// Serves the line until `stop` is set.
    ///
    /// # Errors
    /// An IO error of the link.
    pub fn run(&mut self, stop: &AtomicBool) -> io::Result<()> {
        let mut buf = [0u8; 256];
        let mut first_byte_at: Option<Instant> = None;
        while !stop.load(Ordering::Relaxed) {
            let n = self.link.read(&mut buf, Duration::from_millis(2))?;
            if n == 0 {
                self.tick();
                continue;
            }
            let received_at = Instant::now();
            first_byte_at.get_or_insert(received_at);
            let data = buf.get_mut(..n).unwrap_or_default();
            let rate = self.options.faults.corrupt_rate;
            if rate > 0.0 {
                for b in data.iter_mut() {
                    if self.rx_rng.gen_bool(rate) {
                        *b ^= self.rx_rng.gen_range(1..=255u8);
                    }
                }
            }
            let mut frames = Vec::new();
            self.decoder.push_with(data, |item| match item {
                Ok(frame) => frames.push(frame),
                Err(e) => tracing::debug!(error = %e, "ignored a malformed frame"),
            });
            for frame in frames {
                self.serve(&frame, first_byte_at.take())?;
            }
            if self.decoder.pending() == 0 {
                first_byte_at = None;
            }
            self.tick();
        }
        self.tick();
        Ok(())
    }

    /// Hands one frame to every controller and sends the answer, if any, on time.
    fn serve(&mut self, frame: &Frame, first_byte_at: Option<Instant>) -> io::Result<()> {
        let rev = self.options.revision;
        let line = self.link.line();
        let request_len = frame.encoded_len(rev).unwrap_or(0);
        // The request has arrived once its last byte is on the wire.
        let arrived = match (self.options.baud_pacing, first_byte_at) {
            (true, Some(t0)) => {
                let at = t0 + line.wire_time(request_len);
                sleep_until(at);
                at
            }
            _ => Instant::now(),
        };
        let now = self.clock.at(arrived);
        let mut reply = None;
        for c in &self.controllers {
            if let Some(r) = lock(c).handle(frame, now) {
                reply = Some(r);
            }
        }
        let Some(reply) = reply else { return Ok(()) };
        let bytes = match reply.encode(rev) {
            Ok(b) => b,
            Err(e) => {
                tracing::warn!(error = %e, "cannot encode an answer");
                return Ok(());
            }
        };
        let mut due = arrived + self.options.reply_delay;
        if self.gateway.is_some_and(|g| g != frame.address) {
            due += wire_time(request_len, RS485_BAUD)
                + self.options.reply_delay
                + wire_time(bytes.len(), RS485_BAUD);
        }
        sleep_until(due);
        self.link.write_all(&bytes)?;
        self.frames_served += 1;
        Ok(())
    }

    /// Brings every controller up to the line's time.
    fn tick(&mut self) {
        let now = self.clock.now();
        for c in &self.controllers {
            lock(c).advance_to(now);
        }
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
    for (name, rate) in
        [("drop rate", options.faults.drop_rate), ("corrupt rate", options.faults.corrupt_rate)]
    {
        if !(0.0..=1.0).contains(&rate) {
            return bad(format!("{name} must be within 0..=1, got {rate}"));
        }
    }
    Ok(())
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
