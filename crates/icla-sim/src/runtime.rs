//! The runtime: serves several simulated nodes on one bus connection. It loops
//! `recv(1 ms)`, hands every frame to every drive, polls every drive's timers and sends what
//! they produce (the bus does not echo a frame to its sender, so nodes on one connection
//! do not see each other's frames, which CANopen slaves never need).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use motus_can::{CanBus, CanError, CanFrame};

use crate::drive::SimDrive;

/// Drives shared between the runtime and a test or world model.
pub type SharedDrives = Arc<Mutex<Vec<SimDrive>>>;

/// Locks shared drives (a poisoned lock is still usable: the drives hold no invariants
/// that a panic elsewhere could break).
pub fn lock(drives: &SharedDrives) -> MutexGuard<'_, Vec<SimDrive>> {
    drives.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Serves `drives` on `bus` until `stop` is set; returns the drives.
pub fn run(
    bus: Arc<dyn CanBus>,
    drives: Vec<SimDrive>,
    stop: Arc<AtomicBool>,
) -> Result<Vec<SimDrive>, CanError> {
    let shared = Arc::new(Mutex::new(drives));
    run_shared(bus, Arc::clone(&shared), stop)?;
    let drives = std::mem::take(&mut *lock(&shared));
    Ok(drives)
}

/// Most frames handled before the simulator answers (bounds an answer's delay under a flood).
const MAX_FRAMES_PER_BATCH: usize = 256;

/// Serves shared drives on `bus` until `stop` is set (the caller may lock them meanwhile).
pub fn run_shared(bus: Arc<dyn CanBus>, drives: SharedDrives, stop: Arc<AtomicBool>) -> Result<(), CanError> {
    let mut out = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        let mut received = bus.recv(Duration::from_millis(1))?;
        {
            let mut guard = lock(&drives);
            // Every frame already received is handled before answering, so the answers
            // leave in one batch (one write on socketcand) and no answer waits for a frame
            // still in the buffer.
            let mut handled = 0;
            while let Some(r) = received.take() {
                for d in guard.iter_mut() {
                    out.extend(d.handle(&r.frame, r.at));
                }
                handled += 1;
                if handled < MAX_FRAMES_PER_BATCH {
                    received = bus.recv(Duration::ZERO)?;
                }
            }
        }
        // The answers leave before the timers of every drive are run: with many drives
        // those cost more than the answers themselves.
        send_all(&*bus, &mut out)?;
        {
            let mut guard = lock(&drives);
            let now = Instant::now();
            for d in guard.iter_mut() {
                out.extend(d.poll(now));
            }
        }
        send_all(&*bus, &mut out)?;
    }
    Ok(())
}

/// Sends `out` in one batch (when not empty) and empties it.
fn send_all(bus: &dyn CanBus, out: &mut Vec<CanFrame>) -> Result<(), CanError> {
    if out.is_empty() {
        return Ok(());
    }
    for f in out.iter() {
        tracing::trace!(frame = %f, "sim sends");
    }
    bus.send_batch(out)?;
    out.clear();
    Ok(())
}
