//! Simulated drives as the in-process peer of a [`PairBus`]: the driver's frames reach the
//! drives synchronously, at the clock's time, and their answers come back in the same call
//! (see [`motus_can::pair`]). On a [`motus_clock::VirtualClock`] the motion model
//! integrates exactly up to the virtual time the driver has slept to.

use std::sync::{Arc, Mutex};
use std::time::Instant;

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
/// model to inspect and to inject faults).
pub fn pair(drives: Vec<SimDrive>, clock: SharedClock) -> (Arc<PairBus<Vec<SimDrive>>>, SharedDrives) {
    let shared: SharedDrives = Arc::new(Mutex::new(drives));
    (Arc::new(PairBus::new(Arc::clone(&shared), clock)), shared)
}
