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

/// Every this many exchanges, the way of waiting not preferred now is tried again (the
/// host's speed drifts; what paid off a minute ago may not now).
const EXPLORE_EVERY: u64 = 16;

/// How one exchange waits for its answers (see [`AnswerLatency::plan`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct WaitPlan {
    /// How long to spin before sleeping (zero: sleep at once).
    spin: Duration,
    /// Whether the measured time counts for spinning (else for sleeping).
    spinning: bool,
}

impl WaitPlan {
    /// Sleep at once (and measure nothing).
    pub const SLEEP: WaitPlan = WaitPlan { spin: Duration::ZERO, spinning: false };
}

/// The recent answer latency of one master, and whether spinning pays off.
///
/// Spinning only helps where waking a sleeping thread costs more than the CPU the spin
/// takes from the bus and the nodes; that depends on the host and drifts with its load.
/// So both ways are measured (the caller's time from the requests to the last answer, a
/// moving average each) and the faster one is used, the other tried every
/// [`EXPLORE_EVERY`] exchanges.
#[derive(Debug)]
pub(crate) struct AnswerLatency {
    /// Moving average of the bus latency (requests to the first answer's arrival), ns
    /// (0 = nothing measured yet).
    average_ns: AtomicU64,
    /// Moving averages of the caller's exchange time when spinning and when sleeping, ns
    /// (0 = not tried yet).
    spin_ns: AtomicU64,
    sleep_ns: AtomicU64,
    /// Exchanges planned.
    exchanges: AtomicU64,
    /// A spin needs a second CPU to run the bus meanwhile.
    cpus: usize,
    /// Threads of this master spinning now (at most one fewer than the CPUs, so that
    /// the bus and the answering nodes always keep a CPU).
    spinners: AtomicUsize,
}

/// Moves the moving average `avg` (0 = empty) by one sample `x`, weight 1/8.
fn ewma(avg: &AtomicU64, x: Duration) {
    let x = u64::try_from(x.as_nanos()).unwrap_or(u64::MAX).max(1);
    let old = avg.load(Ordering::Relaxed);
    let new = if old == 0 { x } else { old.saturating_mul(7).saturating_add(x) / 8 };
    avg.store(new, Ordering::Relaxed);
}

impl AnswerLatency {
    /// Spinning is allowed unless the environment sets `MOTUS_SDO_SPIN=off` (a host
    /// whose CPUs are shared with other work may prefer to never spin).
    pub fn new() -> AnswerLatency {
        let off = std::env::var("MOTUS_SDO_SPIN").is_ok_and(|v| v.eq_ignore_ascii_case("off") || v == "0");
        let cpus = if off { 1 } else { std::thread::available_parallelism().map_or(1, |n| n.get()) };
        AnswerLatency::with_cpus(cpus)
    }

    fn with_cpus(cpus: usize) -> AnswerLatency {
        AnswerLatency {
            average_ns: AtomicU64::new(0),
            spin_ns: AtomicU64::new(0),
            sleep_ns: AtomicU64::new(0),
            exchanges: AtomicU64::new(0),
            cpus,
            spinners: AtomicUsize::new(0),
        }
    }

    /// Decides how to wait for the exchange whose requests leave now.
    pub fn plan(&self) -> WaitPlan {
        let budget = self.spin_budget();
        if budget.is_zero() {
            return WaitPlan { spin: Duration::ZERO, spinning: false };
        }
        let (spin, sleep) = (self.spin_ns.load(Ordering::Relaxed), self.sleep_ns.load(Ordering::Relaxed));
        let prefer_spin = match (spin, sleep) {
            (0, _) => true,
            (_, 0) => false,
            (s, z) => s <= z,
        };
        let explore = self.exchanges.fetch_add(1, Ordering::Relaxed) % EXPLORE_EVERY == EXPLORE_EVERY - 1;
        let spinning = prefer_spin != explore;
        WaitPlan { spin: if spinning { budget } else { Duration::ZERO }, spinning }
    }

    /// Receives an answer of an exchange whose requests left at `sent_at`: spinning as
    /// `plan` says when a CPU is free for it, then asleep until `deadline`.
    pub fn recv<T>(
        &self,
        rx: &Receiver<T>,
        plan: WaitPlan,
        sent_at: Instant,
        deadline: Instant,
    ) -> Result<T, RecvTimeoutError> {
        if plan.spin.is_zero() {
            return rx.recv_timeout(deadline.saturating_duration_since(Instant::now()));
        }
        let spinning = self.spinners.fetch_add(1, Ordering::Relaxed);
        let spin_until = if spinning + 1 < self.cpus { (sent_at + plan.spin).min(deadline) } else { sent_at };
        let r = recv_spinning(rx, spin_until, deadline);
        self.spinners.fetch_sub(1, Ordering::Relaxed);
        r
    }

    /// How long to spin for a batch whose requests have just left.
    pub fn spin_budget(&self) -> Duration {
        let avg = Duration::from_nanos(self.average_ns.load(Ordering::Relaxed));
        spin_budget(avg, self.cpus)
    }

    /// Records the time from an exchange's requests to its first answer's arrival.
    pub fn record_bus(&self, latency: Duration) {
        ewma(&self.average_ns, latency);
    }

    /// Records the caller's time from an exchange's requests to its last answer, under
    /// `plan` (exchanges that failed or timed out are not recorded).
    pub fn record_exchange(&self, plan: WaitPlan, took: Duration) {
        if self.spin_budget().is_zero() && !plan.spinning {
            return;
        }
        ewma(if plan.spinning { &self.spin_ns } else { &self.sleep_ns }, took);
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
        let l = AnswerLatency::with_cpus(2);
        assert!(!l.plan().spinning, "nothing measured yet");
        l.record_bus(Duration::from_micros(100));
        assert_eq!(l.spin_budget(), Duration::from_micros(170));
        for _ in 0..30 {
            l.record_bus(Duration::from_millis(2));
        }
        assert_eq!(l.spin_budget(), Duration::ZERO);
        assert!(!l.plan().spinning);
    }

    #[test]
    fn the_faster_way_of_waiting_is_used_and_the_other_tried_now_and_then() {
        let us = Duration::from_micros;
        let l = AnswerLatency::with_cpus(2);
        l.record_bus(us(60));
        // Untried: spinning first, then sleeping.
        let first = l.plan();
        assert!(first.spinning);
        l.record_exchange(first, us(50));
        let count = |l: &AnswerLatency, n: usize| (0..n).filter(|_| l.plan().spinning).count();
        // Sleeping not tried yet: preferred is sleep after spin was measured.
        let p = l.plan();
        assert!(!p.spinning);
        l.record_exchange(p, us(90));
        // Spinning is faster: used, except every 16th exchange.
        assert_eq!(count(&l, 160), 150);
        // The host changes: sleeping becomes faster, and wins once measured.
        for _ in 0..40 {
            let p = l.plan();
            l.record_exchange(p, if p.spinning { us(120) } else { us(40) });
        }
        assert_eq!(count(&l, 160), 10);
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
