//! A bus link that comes back by itself: [`ReconnectingBus`] wraps a transport it can
//! reopen (a URI, or any opener) and, when the transport closes (the socketcand hub or
//! daemon restarted, the adapter was unplugged), reopens it with exponential back-off
//! (100 ms doubling to 2 s by default) while its users keep calling it.
//!
//! While the link is down, [`CanBus::recv`] waits and returns `Ok(None)`, and
//! [`CanBus::send`] fails at once with [`CanError::Closed`] (a master's transfers fail
//! fast) or discards the frame ([`WhileDown::Discard`]: a simulated node on a bus whose
//! wiring is gone). Reconnection attempts are made from `recv`, which every user of a bus
//! calls in its receive loop; a `send` never waits for a connection.
//!
//! Logging is rate-limited by [`LinkMonitor`], the sans-IO state machine underneath: one
//! line when the link is lost, one when it is restored, and while it stays down at most
//! one summary every [`ReconnectPolicy::summary_every`].

use crate::{CanBus, CanError, CanFrame, Received};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// What a send does while the link is down.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WhileDown {
    /// Fail with [`CanError::Closed`] (the caller learns at once that nothing was sent).
    Fail,
    /// Drop the frame and report success (a node whose bus is gone talks to nobody).
    Discard,
}

/// How a [`ReconnectingBus`] retries and reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReconnectPolicy {
    /// Delay before the first attempt after a loss, and after the first failed attempt
    /// twice that, and so on.
    pub initial: Duration,
    /// Longest delay between attempts.
    pub max: Duration,
    /// While the link stays down, at most one summary log line per this period.
    pub summary_every: Duration,
    /// What a send does while the link is down.
    pub while_down: WhileDown,
}

impl Default for ReconnectPolicy {
    /// 100 ms doubling up to 2 s, a summary every 5 s, sends fail while down.
    fn default() -> Self {
        Self {
            initial: Duration::from_millis(100),
            max: Duration::from_secs(2),
            summary_every: Duration::from_secs(5),
            while_down: WhileDown::Fail,
        }
    }
}

impl ReconnectPolicy {
    /// Delay after `failures` consecutive failed attempts: `initial * 2^failures`, capped
    /// at `max` (0 failures: `initial`, the wait after the loss itself).
    pub fn delay(&self, failures: u32) -> Duration {
        self.initial.saturating_mul(1u32 << failures.min(31)).min(self.max)
    }
}

/// A change of the link worth one log line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkEvent {
    /// The transport failed; reconnection starts.
    Lost {
        /// Why.
        reason: String,
    },
    /// Still down (at most one per [`ReconnectPolicy::summary_every`]).
    StillDown {
        /// Down for this long.
        down_for: Duration,
        /// Failed attempts so far.
        attempts: u32,
        /// The last attempt's error.
        last_error: String,
    },
    /// Reconnected.
    Restored {
        /// It was down for this long.
        down_for: Duration,
        /// Failed attempts before this success.
        attempts: u32,
    },
}

#[derive(Debug, Clone)]
struct Down {
    since: Instant,
    attempts: u32,
    next_attempt: Instant,
    last_error: String,
    last_summary: Instant,
}

/// The link's state machine: when to retry and what to log. Time is an argument, so it is
/// tested on virtual time.
#[derive(Debug, Clone)]
pub struct LinkMonitor {
    policy: ReconnectPolicy,
    down: Option<Down>,
}

impl LinkMonitor {
    /// A monitor of a link that is up.
    pub fn new(policy: ReconnectPolicy) -> Self {
        Self { policy, down: None }
    }

    /// The policy.
    pub fn policy(&self) -> &ReconnectPolicy {
        &self.policy
    }

    /// Whether the link is up.
    pub fn is_up(&self) -> bool {
        self.down.is_none()
    }

    /// The transport failed at `now`; the first attempt is due after `initial`. Returns
    /// the event to log (none when the link was already down).
    pub fn lost(&mut self, now: Instant, reason: &str) -> Option<LinkEvent> {
        if self.down.is_some() {
            return None;
        }
        self.down = Some(Down {
            since: now,
            attempts: 0,
            next_attempt: now + self.policy.delay(0),
            last_error: reason.to_owned(),
            last_summary: now,
        });
        Some(LinkEvent::Lost { reason: reason.to_owned() })
    }

    /// Whether a reconnection attempt is due at `now` (never while up).
    pub fn attempt_due(&self, now: Instant) -> bool {
        self.down.as_ref().is_some_and(|d| now >= d.next_attempt)
    }

    /// When the next attempt is due (`None` while up).
    pub fn next_attempt(&self) -> Option<Instant> {
        self.down.as_ref().map(|d| d.next_attempt)
    }

    /// An attempt failed at `now`: the next one is due after the doubled delay. Returns a
    /// summary when the last one is [`ReconnectPolicy::summary_every`] old.
    pub fn attempt_failed(&mut self, now: Instant, error: &str) -> Option<LinkEvent> {
        let d = self.down.as_mut()?;
        d.attempts = d.attempts.saturating_add(1);
        d.next_attempt = now + self.policy.delay(d.attempts);
        d.last_error = error.to_owned();
        if now.saturating_duration_since(d.last_summary) < self.policy.summary_every {
            return None;
        }
        d.last_summary = now;
        Some(LinkEvent::StillDown {
            down_for: now.saturating_duration_since(d.since),
            attempts: d.attempts,
            last_error: d.last_error.clone(),
        })
    }

    /// The link is up again at `now` (none when it was not down).
    pub fn restored(&mut self, now: Instant) -> Option<LinkEvent> {
        let d = self.down.take()?;
        Some(LinkEvent::Restored { down_for: now.saturating_duration_since(d.since), attempts: d.attempts })
    }
}

/// Opens the transport (again).
pub type Opener = Box<dyn Fn() -> Result<Arc<dyn CanBus>, CanError> + Send + Sync>;

/// A [`CanBus`] that reopens its transport when it closes (see the module documentation).
pub struct ReconnectingBus {
    name: String,
    opener: Opener,
    current: Mutex<Option<(u64, Arc<dyn CanBus>)>>,
    monitor: Mutex<LinkMonitor>,
    /// Held while an attempt runs (only one at a time; other callers do not wait).
    connecting: Mutex<()>,
    connections: AtomicU64,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Whether an error means the transport is gone (rather than one bad frame).
fn is_link_failure(e: &CanError) -> bool {
    matches!(e, CanError::Closed(_) | CanError::Io(_))
}

/// Longest a `recv` sleeps while the link is down before it checks again.
const DOWN_POLL: Duration = Duration::from_millis(20);

impl ReconnectingBus {
    /// Opens the bus `uri` names ([`crate::open_bus`]); the first connection must succeed,
    /// later ones are retried per `policy`.
    pub fn open(uri: &str, policy: ReconnectPolicy) -> Result<Self, CanError> {
        let u = uri.to_owned();
        Self::with_opener(uri, Box::new(move || crate::open_bus(&u)), policy)
    }

    /// A bus reopened by `opener` (described as `name` in logs); the first connection
    /// must succeed.
    pub fn with_opener(name: &str, opener: Opener, policy: ReconnectPolicy) -> Result<Self, CanError> {
        let bus = opener()?;
        Ok(Self {
            name: name.to_owned(),
            opener,
            current: Mutex::new(Some((1, bus))),
            monitor: Mutex::new(LinkMonitor::new(policy)),
            connecting: Mutex::new(()),
            connections: AtomicU64::new(1),
        })
    }

    /// Whether the transport is connected now.
    pub fn is_up(&self) -> bool {
        lock(&self.current).is_some()
    }

    /// How many times the transport was opened (1 after [`Self::open`], +1 per reconnection).
    pub fn connections(&self) -> u64 {
        self.connections.load(Ordering::Relaxed)
    }

    fn current(&self) -> Option<(u64, Arc<dyn CanBus>)> {
        lock(&self.current).clone()
    }

    fn policy(&self) -> ReconnectPolicy {
        *lock(&self.monitor).policy()
    }

    /// The connection `generation` failed with `e`: drop it (unless a newer one replaced it).
    fn mark_lost(&self, generation: u64, e: &CanError) {
        {
            let mut cur = lock(&self.current);
            match cur.as_ref() {
                Some((g, _)) if *g == generation => *cur = None,
                _ => return,
            }
        }
        let event = lock(&self.monitor).lost(Instant::now(), &e.to_string());
        if let Some(event) = event {
            self.log(&event);
        }
    }

    /// One attempt, if due and no other caller is making one. True when connected after it.
    fn try_reconnect(&self) -> bool {
        if !lock(&self.monitor).attempt_due(Instant::now()) {
            return false;
        }
        let Ok(_attempt) = self.connecting.try_lock() else { return false };
        let result = (self.opener)();
        let now = Instant::now();
        match result {
            Ok(bus) => {
                let generation = self.connections.fetch_add(1, Ordering::Relaxed) + 1;
                *lock(&self.current) = Some((generation, bus));
                let event = lock(&self.monitor).restored(now);
                if let Some(event) = event {
                    self.log(&event);
                }
                true
            }
            Err(e) => {
                let event = lock(&self.monitor).attempt_failed(now, &e.to_string());
                if let Some(event) = event {
                    self.log(&event);
                }
                false
            }
        }
    }

    fn log(&self, event: &LinkEvent) {
        let bus = self.name.as_str();
        match event {
            LinkEvent::Lost { reason } => {
                let p = self.policy();
                tracing::warn!(
                    bus,
                    %reason,
                    "CAN link lost; reconnecting every {:?} doubling up to {:?}",
                    p.initial,
                    p.max
                );
            }
            LinkEvent::StillDown { down_for, attempts, last_error } => {
                tracing::warn!(bus, ?down_for, attempts, %last_error, "CAN link still down; reconnecting");
            }
            LinkEvent::Restored { down_for, attempts } => {
                tracing::info!(bus, ?down_for, attempts, "CAN link restored");
            }
        }
    }

    fn down_error(&self) -> CanError {
        CanError::Closed(format!("{}: link down, reconnecting", self.name))
    }

    fn send_with(&self, f: impl FnOnce(&dyn CanBus) -> Result<(), CanError>) -> Result<(), CanError> {
        let result = match self.current() {
            Some((generation, bus)) => match f(&*bus) {
                Err(e) if is_link_failure(&e) => {
                    self.mark_lost(generation, &e);
                    Err(e)
                }
                other => return other,
            },
            None => Err(self.down_error()),
        };
        match self.policy().while_down {
            WhileDown::Fail => result,
            WhileDown::Discard => Ok(()),
        }
    }
}

impl CanBus for ReconnectingBus {
    fn send(&self, frame: &CanFrame) -> Result<(), CanError> {
        self.send_with(|bus| bus.send(frame))
    }

    fn send_batch(&self, frames: &[CanFrame]) -> Result<(), CanError> {
        self.send_with(|bus| bus.send_batch(frames))
    }

    fn recv(&self, timeout: Duration) -> Result<Option<Received>, CanError> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some((generation, bus)) = self.current() {
                let left = deadline.saturating_duration_since(Instant::now());
                match bus.recv(left) {
                    Err(e) if is_link_failure(&e) => self.mark_lost(generation, &e),
                    other => return other,
                }
            }
            if self.try_reconnect() {
                continue;
            }
            let now = Instant::now();
            let left = deadline.saturating_duration_since(now);
            if left.is_zero() {
                return Ok(None);
            }
            let until_attempt = lock(&self.monitor)
                .next_attempt()
                .map_or(DOWN_POLL, |t| t.saturating_duration_since(now).max(Duration::from_millis(1)));
            std::thread::sleep(left.min(until_attempt).min(DOWN_POLL));
            if Instant::now() >= deadline {
                return Ok(None);
            }
        }
    }

    fn describe(&self) -> String {
        self.name.clone()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn backoff_doubles_from_100_ms_to_2_s() {
        let p = ReconnectPolicy::default();
        let ms: Vec<u128> = (0..8).map(|n| p.delay(n).as_millis()).collect();
        assert_eq!(ms, vec![100, 200, 400, 800, 1600, 2000, 2000, 2000]);
        assert_eq!(p.delay(u32::MAX), Duration::from_secs(2));
    }

    #[test]
    fn one_line_per_state_change_and_a_summary_every_5_s() {
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut m = LinkMonitor::new(ReconnectPolicy::default());
        assert!(m.is_up() && !m.attempt_due(t0));
        assert_eq!(m.lost(t0, "closed"), Some(LinkEvent::Lost { reason: "closed".into() }));
        assert_eq!(m.lost(t0 + ms(5), "closed again"), None, "already down: no second line");
        // Attempts at 100, 300 (100 + 200), 700, 1500, 3100, 5100, 7100, ... ms; every 20 ms
        // of virtual time the loop asks whether one is due, as the receive loop does.
        let mut attempts = Vec::new();
        let mut lines = Vec::new();
        for step in 0..=600u64 {
            let now = t0 + ms(step * 20);
            if m.attempt_due(now) {
                attempts.push(step * 20);
                lines.extend(m.attempt_failed(now, "refused"));
            }
        }
        assert_eq!(&attempts[..7], &[100, 300, 700, 1500, 3100, 5100, 7100]);
        // 12 s down: 9 attempts (the last at 11100 ms), but only summaries at >= 5 s intervals.
        let summaries: Vec<(u128, u32)> = lines
            .iter()
            .map(|l| match l {
                LinkEvent::StillDown { down_for, attempts, last_error } => {
                    assert_eq!(last_error, "refused");
                    (down_for.as_millis(), *attempts)
                }
                other => panic!("{other:?}"),
            })
            .collect();
        assert_eq!(attempts.len(), 9);
        assert_eq!(summaries, vec![(5100, 6), (11100, 9)]);
        assert_eq!(
            m.restored(t0 + ms(12_200)),
            Some(LinkEvent::Restored { down_for: ms(12_200), attempts: 9 })
        );
        assert!(m.is_up() && m.restored(t0 + ms(12_300)).is_none());
        assert!(!m.attempt_due(t0 + ms(20_000)));
    }
}
