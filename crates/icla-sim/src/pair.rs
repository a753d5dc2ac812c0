//! Simulated drives as the in-process peer of a [`PairBus`]: the driver's frames reach the
//! drives synchronously, at the clock's time, and their answers come back in the same call
//! (see [`motus_can::pair`]). On a [`motus_clock::VirtualClock`] the motion model
//! integrates exactly up to the virtual time the driver has slept to.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use motus_can::{CanFrame, PairBus, PairPeer};
use motus_clock::SharedClock;

use crate::drive::SimDrive;
use crate::runtime::SharedDrives;

impl PairPeer for SimDrive {
    fn on_frame(&mut self, frame: &CanFrame, now: Instant) -> Vec<CanFrame> {
        // Timers first, so a frame is handled after everything due before it.
        let mut out = self.poll(now);
        out.extend(self.handle(frame, now));
        out
    }

    fn poll(&mut self, now: Instant) -> Vec<CanFrame> {
        SimDrive::poll(self, now)
    }
}

/// A bus to `drives` on `clock`, and the drives (shared with the bus, for a test or a world
/// model to inspect and to inject faults). For one thread of control ([`PairBus::new`]).
pub fn pair(drives: Vec<SimDrive>, clock: SharedClock) -> (Arc<PairBus<Vec<SimDrive>>>, SharedDrives) {
    let shared: SharedDrives = Arc::new(Mutex::new(drives));
    (Arc::new(PairBus::new(Arc::clone(&shared), clock)), shared)
}

/// [`pair()`] on a clock that several threads take part in ([`PairBus::threaded`]): the
/// receiver parks on the clock, and the drives' timers (motion, heartbeats, event-timer
/// PDOs, boot-up) run at the instants of the sends and of [`PairBus::poll_peer`], which a
/// simulator thread calls at its own period (see [`run_pair`]).
pub fn pair_threaded(
    drives: Vec<SimDrive>,
    clock: SharedClock,
) -> (Arc<PairBus<Vec<SimDrive>>>, SharedDrives) {
    let shared: SharedDrives = Arc::new(Mutex::new(drives));
    (Arc::new(PairBus::threaded(Arc::clone(&shared), clock)), shared)
}

/// Runs the drives of a threaded pair as their own control loop does: every `period` of
/// the bus's clock (the first one `period` after the call) their timers run
/// ([`PairBus::poll_peer`]) and `each` is called, until `stop` is set. The calling thread
/// must take part in the clock (started with [`motus_clock::spawn`]).
pub fn run_pair(
    bus: &PairBus<Vec<SimDrive>>,
    period: Duration,
    stop: &AtomicBool,
    mut each: impl FnMut(Instant),
) {
    let clock = Arc::clone(bus.clock());
    let mut next = clock.now();
    while !stop.load(Ordering::Relaxed) {
        next += period;
        clock.sleep_until(next);
        bus.poll_peer();
        each(next);
    }
}
