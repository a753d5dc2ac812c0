//! Waiting for a batch of SDO answers: on a bus that answers within microseconds (the
//! virtual bus, a simulator on the same machine) a short spin catches the answer sooner
//! than putting the thread to sleep and waking it again, which on a virtual machine costs
//! tens of microseconds. On a slow bus (a real CAN bus: a round trip takes hundreds of
//! microseconds) no spin is made, so no CPU is burnt waiting.
//!
//! The decision follows the answers' measured latency (from the request leaving to the
//! first answer reaching the receive thread, so the waiting thread's own wake-up does not
//! count), an exponential moving average over the last few batches.

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, TryRecvError};
use std::time::{Duration, Instant};

/// Answers usually slower than this are waited for asleep only.
pub const SPIN_LATENCY_LIMIT: Duration = Duration::from_micros(300);
/// The longest spin before sleeping.
pub const SPIN_CAP: Duration = Duration::from_micros(400);
/// Spins between two `yield_now` (lets a thread runnable on this CPU answer meanwhile).
const SPINS_PER_YIELD: u32 = 256;

/// The recent answer latency of one master, and whether spinning can pay off at all.
#[derive(Debug)]
pub(crate) struct AnswerLatency {
    /// Moving average, ns (0 = nothing measured yet).
    average_ns: AtomicU64,
    /// A spin needs a second CPU to run the bus meanwhile.
    cpus: usize,
    /// Threads of this master spinning now (at most one fewer than the CPUs, so that
    /// the bus and the answering nodes always keep a CPU).
    spinners: AtomicUsize,
}

impl AnswerLatency {
    /// Spinning is allowed unless the environment sets `MOTUS_SDO_SPIN=off` (a host
    /// whose CPUs are shared with other work may prefer to never spin).
    pub fn new() -> AnswerLatency {
        let off = std::env::var("MOTUS_SDO_SPIN").is_ok_and(|v| v.eq_ignore_ascii_case("off") || v == "0");
        AnswerLatency {
            average_ns: AtomicU64::new(0),
            cpus: if off { 1 } else { std::thread::available_parallelism().map_or(1, |n| n.get()) },
            spinners: AtomicUsize::new(0),
        }
    }

    /// Receives the answer to a request sent at `sent_at`: spinning for the budget when
    /// a CPU is free for it, then asleep until `deadline`. Without a request just sent
    /// (`None`), asleep only.
    pub fn recv<T>(
        &self,
        rx: &Receiver<T>,
        sent_at: Option<Instant>,
        deadline: Instant,
    ) -> Result<T, RecvTimeoutError> {
        let budget = self.spin_budget();
        let Some(sent_at) = sent_at.filter(|_| !budget.is_zero()) else {
            return rx.recv_timeout(deadline.saturating_duration_since(Instant::now()));
        };
        let spinning = self.spinners.fetch_add(1, Ordering::Relaxed);
        let spin_until = if spinning + 1 < self.cpus { (sent_at + budget).min(deadline) } else { sent_at };
        let r = recv_spinning(rx, spin_until, deadline);
        self.spinners.fetch_sub(1, Ordering::Relaxed);
        r
    }

    /// How long to spin for a batch whose requests have just left.
    pub fn spin_budget(&self) -> Duration {
        let avg = Duration::from_nanos(self.average_ns.load(Ordering::Relaxed));
        spin_budget(avg, self.cpus)
    }

    /// Records the time from a batch's requests to its first answer.
    pub fn record(&self, latency: Duration) {
        let x = u64::try_from(latency.as_nanos()).unwrap_or(u64::MAX);
        let old = self.average_ns.load(Ordering::Relaxed);
        let new = if old == 0 { x } else { (old.saturating_mul(7)).saturating_add(x) / 8 };
        self.average_ns.store(new, Ordering::Relaxed);
    }
}

/// The spin for answers that usually take `average` (zero: not known yet) on a machine
/// with `cpus` CPUs: none on one CPU, none for a slow bus, else 1.5 times the average plus
/// 20 us, at most [`SPIN_CAP`].
pub fn spin_budget(average: Duration, cpus: usize) -> Duration {
    if cpus < 2 || average.is_zero() || average > SPIN_LATENCY_LIMIT {
        return Duration::ZERO;
    }
    (average * 3 / 2 + Duration::from_micros(20)).min(SPIN_CAP)
}

/// Receives from `rx`: spinning until `spin_until`, then asleep until `deadline`.
fn recv_spinning<T>(rx: &Receiver<T>, spin_until: Instant, deadline: Instant) -> Result<T, RecvTimeoutError> {
    let mut spins = 0u32;
    loop {
        match rx.try_recv() {
            Ok(v) => return Ok(v),
            Err(TryRecvError::Disconnected) => return Err(RecvTimeoutError::Disconnected),
            Err(TryRecvError::Empty) => {}
        }
        let now = Instant::now();
        if now >= spin_until {
            return rx.recv_timeout(deadline.saturating_duration_since(now));
        }
        spins += 1;
        if spins == SPINS_PER_YIELD {
            spins = 0;
            std::thread::yield_now();
        } else {
            std::hint::spin_loop();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc::channel;

    #[test]
    fn spins_only_for_a_fast_bus_with_a_second_cpu() {
        let us = Duration::from_micros;
        assert_eq!(spin_budget(us(80), 2), us(140));
        assert_eq!(spin_budget(us(290), 8), SPIN_CAP);
        assert_eq!(spin_budget(us(80), 1), Duration::ZERO, "one CPU: the answerer needs it");
        assert_eq!(spin_budget(us(350), 2), Duration::ZERO, "slow bus: sleep");
        assert_eq!(spin_budget(Duration::ZERO, 2), Duration::ZERO, "nothing measured yet");
    }

    #[test]
    fn the_average_follows_the_bus_and_stops_spinning_when_it_slows() {
        let l = AnswerLatency { average_ns: AtomicU64::new(0), cpus: 2, spinners: AtomicUsize::new(0) };
        l.record(Duration::from_micros(100));
        assert_eq!(l.spin_budget(), Duration::from_micros(170));
        for _ in 0..30 {
            l.record(Duration::from_millis(2));
        }
        assert_eq!(l.spin_budget(), Duration::ZERO);
    }

    #[test]
    fn an_answer_during_the_spin_or_the_sleep_is_received_and_silence_times_out() {
        let (tx, rx) = channel();
        let now = Instant::now();
        tx.send(1).unwrap_or_default();
        assert_eq!(recv_spinning(&rx, now + Duration::from_millis(1), now + Duration::from_millis(5)), Ok(1));
        let sender = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(20));
            tx.send(2).unwrap_or_default();
            tx
        });
        let now = Instant::now();
        assert_eq!(recv_spinning(&rx, now + Duration::from_micros(100), now + Duration::from_secs(2)), Ok(2));
        let _tx = sender.join();
        let start = Instant::now();
        let r = recv_spinning(&rx, start, start + Duration::from_millis(30));
        assert_eq!(r, Err(RecvTimeoutError::Timeout));
        assert!(start.elapsed() >= Duration::from_millis(30));
    }
}
