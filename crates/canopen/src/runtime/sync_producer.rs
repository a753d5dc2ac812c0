//! SYNC producer thread: sleeps to absolute deadlines (sans-IO [`SyncSchedule`]) and
//! records the instant of every send so jitter can be measured.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::error::MasterError;
use crate::sync::{sync_frame, SyncSchedule};

use super::{lock, Master};

/// A running SYNC producer; stops on [`SyncProducer::stop`] or drop.
pub struct SyncProducer {
    stop: Arc<AtomicBool>,
    sent: Arc<Mutex<Vec<Instant>>>,
    thread: Option<JoinHandle<()>>,
}

impl SyncProducer {
    /// Stops the producer and waits for its thread.
    pub fn stop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(h) = self.thread.take() {
            let _ = h.join();
        }
    }

    /// Instants at which SYNC frames were handed to the transport.
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
    /// 1..=`counter_overflow` if given (2..=240).
    pub fn start_sync(
        &self,
        period: Duration,
        counter_overflow: Option<u8>,
    ) -> Result<SyncProducer, MasterError> {
        let mut schedule = SyncSchedule::new(period, counter_overflow, Instant::now())
            .map_err(|e| MasterError::InvalidArgument(e.to_string()))?;
        let stop = Arc::new(AtomicBool::new(false));
        let sent = Arc::new(Mutex::new(Vec::new()));
        let inner = Arc::clone(&self.inner);
        let (stop2, sent2) = (Arc::clone(&stop), Arc::clone(&sent));
        let thread = std::thread::Builder::new()
            .name("canopen-sync".into())
            .spawn(move || {
                motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Cyclic);
                while !stop2.load(Ordering::Acquire) {
                    let now = Instant::now();
                    let due = schedule.next_deadline();
                    if now < due {
                        let left = due - now;
                        // Sleep in slices (to notice stop), the last 200 µs by yielding.
                        if left > Duration::from_micros(200) {
                            std::thread::sleep(
                                (left - Duration::from_micros(200)).min(Duration::from_millis(20)),
                            );
                        } else {
                            std::thread::yield_now();
                        }
                        continue;
                    }
                    if let Some(f) = schedule.poll(now) {
                        match inner.send(&f, || "sending SYNC".into()) {
                            Ok(()) => lock(&sent2).push(Instant::now()),
                            Err(e) => tracing::warn!(error = %e, "SYNC not sent"),
                        }
                    }
                }
            })
            .map_err(|e| MasterError::InvalidArgument(format!("cannot spawn the SYNC thread: {e}")))?;
        Ok(SyncProducer { stop, sent, thread: Some(thread) })
    }
}
