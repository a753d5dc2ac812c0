//! SYNC producer thread: sleeps to absolute deadlines (sans-IO [`SyncSchedule`]) on the
//! master's clock and records the instant of every send so jitter can be measured.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_clock::SharedClock;

use crate::error::MasterError;
use crate::sync::{sync_frame, SyncSchedule};

use super::{lock, Master};

/// A running SYNC producer; stops on [`SyncProducer::stop`] or drop.
pub struct SyncProducer {
    stop: Arc<AtomicBool>,
    sent: Arc<Mutex<Vec<Instant>>>,
    thread: Option<JoinHandle<()>>,
    clock: SharedClock,
}

impl SyncProducer {
    /// Stops the producer and waits for its thread.
    pub fn stop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(h) = self.thread.take() {
            // Ends a parked wait at once.
            self.clock.unpark(h.thread());
            let _ = motus_clock::while_blocked(&*self.clock, || h.join());
        }
    }

    /// Instants (of the master's clock) at which SYNC frames were handed to the transport.
    pub fn send_instants(&self) -> Vec<Instant> {
        lock(&self.sent).clone()
    }

    /// Intervals between consecutive SYNC frames.
    pub fn periods(&self) -> Vec<Duration> {
        let s = lock(&self.sent);
        s.windows(2)
            .filter_map(|w| match w {
                [a, b] => Some(b.saturating_duration_since(*a)),
                _ => None,
            })
            .collect()
    }
}

impl Drop for SyncProducer {
    fn drop(&mut self) {
        self.stop();
    }
}

impl Master {
    /// Sends one SYNC frame now (without counter).
    pub fn send_sync(&self) -> Result<(), MasterError> {
        let f = sync_frame(None).map_err(|e| MasterError::InvalidArgument(e.to_string()))?;
        self.inner.send(&f, || "sending SYNC".into())
    }

    /// Starts producing SYNC every `period` (first one now), with a counter
    /// 1..=`counter_overflow` if given (2..=240), on the master's clock (the system clock, or
    /// a threaded virtual one: a thread taking part, which sends at exactly every period;
    /// not a one-thread-of-control clock).
    pub fn start_sync(
        &self,
        period: Duration,
        counter_overflow: Option<u8>,
    ) -> Result<SyncProducer, MasterError> {
        let clock = Arc::clone(&self.inner.clock);
        let mut schedule = SyncSchedule::new(period, counter_overflow, clock.now())
            .map_err(|e| MasterError::InvalidArgument(e.to_string()))?;
        let stop = Arc::new(AtomicBool::new(false));
        let sent = Arc::new(Mutex::new(Vec::new()));
        let inner = Arc::clone(&self.inner);
        let (stop2, sent2) = (Arc::clone(&stop), Arc::clone(&sent));
        let builder = std::thread::Builder::new().name("canopen-sync".into());
        let thread = motus_clock::spawn(&clock, builder, move || {
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Cyclic);
            let clock = &*inner.clock;
            while !stop2.load(Ordering::Acquire) {
                let now = clock.now();
                let due = schedule.next_deadline();
                if now < due {
                    if inner.threaded {
                        // Parked to the deadline exactly (a stop wakes it).
                        clock.park_until(due);
                        continue;
                    }
                    // Asleep to the deadline, in slices of at most 20 ms (to notice stop). No
                    // spinning: under SCHED_FIFO a spinning thread keeps every normal thread
                    // off its CPU, the kernel's workers that carry pty and loopback data
                    // included (docs/decisions.md).
                    clock.sleep((due - now).min(Duration::from_millis(20)));
                    continue;
                }
                if let Some(f) = schedule.poll(now) {
                    match inner.send(&f, || "sending SYNC".into()) {
                        Ok(()) => lock(&sent2).push(clock.now()),
                        Err(e) => tracing::warn!(error = %e, "SYNC not sent"),
                    }
                }
            }
        })
        .map_err(|e| MasterError::InvalidArgument(format!("cannot spawn the SYNC thread: {e}")))?;
        Ok(SyncProducer { stop, sent, thread: Some(thread), clock })
    }
}
