//! Anticipatory polling: how a CN thread waits for the next PReq of its cycle.
//!
//! A CN that sleeps in `recv` is woken by the kernel when the PReq arrives. On a multi-core
//! host that wake-up crosses CPUs (the frame is delivered on the CPU that sent it), and on
//! the 2-core development VM such a wake-up was sometimes not delivered until the sleeping
//! CPU's next timer interrupt: the CN's thread slept 5-8 ms with the PReq in its socket, and
//! openPOWERLINK's 1 ms MN reset the node for the lost PRes (`perf` trace in
//! `docs/decisions.md`, issue 20). Busy polling all the time avoids wake-ups but takes a
//! whole core. Anticipation does what soft real-time POWERLINK nodes do: it sleeps until
//! shortly before the PReq is due, woken by the thread's own timer on its own CPU, then
//! polls the socket until the PReq is there or a grace time after it was due has passed,
//! and sleeps again. The PReq is due one cycle (0x1006) after the last one; a PReq that does
//! not come moves the expectation on by whole cycles, for at most [`MAX_MISSED_CYCLES`].
//!
//! Sans-IO: [`Anticipation::plan`] takes `now`; the runtime does the waiting.

use std::time::{Duration, Instant};

/// After this many cycles without a PReq, the node waits asleep until the next one.
pub const MAX_MISSED_CYCLES: u32 = 4;

/// How long to wait next, and how.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WaitStep {
    /// Sleep in `recv` for at most this long.
    Sleep(Duration),
    /// Poll the link without sleeping for at most this long.
    Poll(Duration),
}

/// When the next PReq is due, from the last one (see the module documentation).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Anticipation {
    /// Polling starts this long before the PReq is due.
    lead: Duration,
    /// Polling goes on this long after the PReq was due.
    grace: Duration,
    /// When the last PReq for the node was received.
    last_preq: Option<Instant>,
}

impl Anticipation {
    /// Polls from `lead` before each PReq is due until `grace` after.
    pub fn new(lead: Duration, grace: Duration) -> Self {
        Self { lead, grace, last_preq: None }
    }

    /// The default for a CN on a host: from 150 µs before to 250 µs after (an MN's SoC
    /// jitter and the PReq's place in the cycle fit in this window).
    pub fn host_default() -> Self {
        Self::new(Duration::from_micros(150), Duration::from_micros(250))
    }

    /// A PReq for the node was received at `at`.
    pub fn on_preq(&mut self, at: Instant) {
        self.last_preq = Some(at);
    }

    /// The node left the states with PReq (a reset, a cycle error): nothing is due.
    pub fn forget(&mut self) {
        self.last_preq = None;
    }

    /// How to wait at `now` with a cycle of `cycle`, for at most `max_wait`.
    pub fn plan(&self, now: Instant, cycle: Duration, max_wait: Duration) -> WaitStep {
        let Some(last) = self.last_preq else { return WaitStep::Sleep(max_wait) };
        if cycle.is_zero() {
            return WaitStep::Sleep(max_wait);
        }
        // The first PReq due after `last` whose polling window has not ended at `now`.
        let since = now.saturating_duration_since(last);
        let cycles = since.saturating_sub(self.grace).as_nanos() / cycle.as_nanos() + 1;
        if cycles > u128::from(MAX_MISSED_CYCLES) {
            return WaitStep::Sleep(max_wait);
        }
        let due = last + cycle * u32::try_from(cycles).unwrap_or(MAX_MISSED_CYCLES);
        let from = due.checked_sub(self.lead).unwrap_or(due);
        if now < from {
            WaitStep::Sleep((from - now).min(max_wait))
        } else {
            WaitStep::Poll((due + self.grace - now).min(max_wait))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);
    const MAX: Duration = Duration::from_millis(5);

    fn us(n: u64) -> Duration {
        Duration::from_micros(n)
    }

    #[test]
    fn without_a_preq_the_node_sleeps() {
        let a = Anticipation::host_default();
        assert_eq!(a.plan(Instant::now(), MS, MAX), WaitStep::Sleep(MAX));
    }

    #[test]
    fn sleeps_until_the_lead_then_polls_until_the_grace() {
        let mut a = Anticipation::host_default();
        let t0 = Instant::now();
        a.on_preq(t0);
        assert_eq!(a.plan(t0 + us(10), MS, MAX), WaitStep::Sleep(us(840)));
        assert_eq!(a.plan(t0 + us(850), MS, MAX), WaitStep::Poll(us(400)));
        assert_eq!(a.plan(t0 + us(1100), MS, MAX), WaitStep::Poll(us(150)));
        // The PReq did not come: the next one is expected a cycle later.
        assert_eq!(a.plan(t0 + us(1250), MS, MAX), WaitStep::Sleep(us(600)));
        assert_eq!(a.plan(t0 + us(1900), MS, MAX), WaitStep::Poll(us(350)));
    }

    #[test]
    fn a_new_preq_moves_the_window() {
        let mut a = Anticipation::host_default();
        let t0 = Instant::now();
        a.on_preq(t0);
        a.on_preq(t0 + us(1030));
        assert_eq!(a.plan(t0 + us(1040), MS, MAX), WaitStep::Sleep(us(840)));
    }

    #[test]
    fn after_missed_cycles_or_forget_the_node_sleeps() {
        let mut a = Anticipation::host_default();
        let t0 = Instant::now();
        a.on_preq(t0);
        assert!(matches!(a.plan(t0 + us(3900), MS, MAX), WaitStep::Poll(_)));
        assert_eq!(a.plan(t0 + us(4300), MS, MAX), WaitStep::Sleep(MAX));
        a.on_preq(t0 + us(4500));
        a.forget();
        assert_eq!(a.plan(t0 + us(5400), MS, MAX), WaitStep::Sleep(MAX));
    }

    #[test]
    fn waits_never_exceed_the_bound() {
        let mut a = Anticipation::host_default();
        let t0 = Instant::now();
        a.on_preq(t0);
        let cycle = Duration::from_millis(50);
        assert_eq!(a.plan(t0 + us(10), cycle, MAX), WaitStep::Sleep(MAX));
        assert_eq!(a.plan(t0 + cycle, cycle, MAX), WaitStep::Poll(us(250)));
    }
}
