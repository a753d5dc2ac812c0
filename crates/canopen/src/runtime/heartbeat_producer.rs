//! The master's own heartbeat (COB-ID 0x700 + its node id, state Operational): drives that
//! consume it (object 0x1016) stop by themselves when the master dies or its bus link breaks.
//! The period is kept on the master's clock (see [`Master::with_threaded_clock`]).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use motus_canopen_protocol::{CanFrame, NmtState};
use motus_clock::SharedClock;

use crate::error::MasterError;

use super::failure_log::FailureLog;
use super::Master;

/// A running heartbeat producer; stops on [`HeartbeatProducer::stop`] or drop (as when the
/// process dies: the consumers' time-outs run out).
pub struct HeartbeatProducer {
    node: u8,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    clock: SharedClock,
}

impl HeartbeatProducer {
    /// The node id the heartbeat is sent as.
    #[must_use]
    pub fn node(&self) -> u8 {
        self.node
    }

    /// Stops sending and waits for the thread.
    pub fn stop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(h) = self.thread.take() {
            // Ends its wait at once (it parks on the clock).
            self.clock.unpark(h.thread());
            let _ = motus_clock::while_blocked(&*self.clock, || h.join());
        }
    }
}

impl Drop for HeartbeatProducer {
    fn drop(&mut self) {
        self.stop();
    }
}

/// The consumer-time entry (object 0x1016, one sub-index) that makes a node watch `producer`
/// with time-out `time` (ms, 1..=65535).
#[must_use]
pub fn consumer_entry(producer: u8, time: Duration) -> u32 {
    let ms = u32::try_from(time.as_millis()).unwrap_or(u32::MAX).clamp(1, 0xFFFF);
    (u32::from(producer) << 16) | ms
}

impl Master {
    /// Sends this master's heartbeat as node `node` (1..=127) every `period`, the first now,
    /// on the master's clock (the system clock, or a threaded virtual one: a thread taking
    /// part, which sends at exactly every period; not a one-thread-of-control clock).
    ///
    /// # Errors
    /// An invalid node id or period, or the thread cannot start.
    pub fn start_heartbeat(&self, node: u8, period: Duration) -> Result<HeartbeatProducer, MasterError> {
        if !(1..=127).contains(&node) || period.is_zero() {
            return Err(MasterError::InvalidArgument(format!(
                "heartbeat: node {node} (1..=127) every {period:?} (> 0)"
            )));
        }
        let frame = CanFrame::new(0x700 + u32::from(node), &[NmtState::Operational.raw()])
            .map_err(|e| MasterError::InvalidArgument(e.to_string()))?;
        let stop = Arc::new(AtomicBool::new(false));
        let (inner, stop2) = (Arc::clone(&self.inner), Arc::clone(&stop));
        let clock = Arc::clone(&self.inner.clock);
        let builder = std::thread::Builder::new().name("canopen-heartbeat".into());
        let thread = motus_clock::spawn(&clock, builder, move || {
            // The cell's drives stop (EMCY 0x8130) when this heartbeat is late.
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Cyclic);
            let clock = &*inner.clock;
            let mut next = clock.now();
            // While the bus is down every heartbeat fails: logged once, then summarised.
            let mut failures = FailureLog::new("the master's heartbeat", Duration::from_secs(5));
            let bus = inner.bus.describe();
            while !stop2.load(Ordering::Acquire) {
                let now = clock.now();
                if now >= next {
                    match inner.send(&frame, || "sending the master's heartbeat".into()) {
                        Ok(()) => failures.succeed(now, &bus),
                        Err(e) => failures.fail(now, &e, &bus),
                    }
                    next += period;
                    if next < now {
                        next = now + period;
                    }
                }
                // Parked (a stop wakes it); on real time in slices, to notice a stop.
                let until =
                    if inner.threaded { next } else { next.min(clock.now() + Duration::from_millis(20)) };
                clock.park_until(until);
            }
        })
        .map_err(|e| MasterError::InvalidArgument(format!("cannot spawn the heartbeat thread: {e}")))?;
        Ok(HeartbeatProducer { node, stop, thread: Some(thread), clock })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_consumer_entry_packs_node_and_time() {
        // CiA 301 0x1016: bits 16..23 node id, bits 0..15 time in ms.
        assert_eq!(consumer_entry(126, Duration::from_millis(300)), 0x007E_012C);
        assert_eq!(consumer_entry(1, Duration::from_secs(100)), 0x0001_FFFF, "clamped to 65535 ms");
        assert_eq!(consumer_entry(5, Duration::ZERO), 0x0005_0001, "0 would disable: at least 1 ms");
    }
}
