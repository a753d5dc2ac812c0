//! Heartbeat consumer (CiA 301 §7.2.8.3.2.2): per-node expected period, loss and
//! recovery detection, boot-up detection. Sans-IO: `now` is passed in.
//!
//! Monitoring of a node starts when [`HeartbeatConsumer::monitor`] is called: a node that
//! never sends a heartbeat within the consumer time is reported lost too (with
//! `last_seen` = the time monitoring started).

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use motus_canopen_protocol::NmtState;

/// An event of the heartbeat consumer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeartbeatEvent {
    /// No heartbeat for longer than the consumer time (reported once).
    NodeLost {
        /// Node id.
        node: u8,
        /// Last heartbeat (or the start of monitoring).
        last_seen: Instant,
    },
    /// A heartbeat arrived after a loss.
    NodeRecovered {
        /// Node id.
        node: u8,
        /// Reported state.
        state: NmtState,
    },
    /// A boot-up message (state 0x00) arrived.
    NodeBooted {
        /// Node id.
        node: u8,
    },
}

#[derive(Debug, Clone, Copy)]
struct Monitor {
    consumer_time: Duration,
    last: Instant,
    lost: bool,
}

/// Heartbeat consumer for any number of nodes.
#[derive(Debug, Clone, Default)]
pub struct HeartbeatConsumer {
    monitors: BTreeMap<u8, Monitor>,
}

impl HeartbeatConsumer {
    /// A consumer that monitors nothing yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Monitors `node`, expecting a heartbeat at least every `consumer_time` from `now`.
    /// A zero time stops monitoring.
    pub fn monitor(&mut self, node: u8, consumer_time: Duration, now: Instant) {
        if consumer_time.is_zero() {
            self.monitors.remove(&node);
        } else {
            self.monitors.insert(node, Monitor { consumer_time, last: now, lost: false });
        }
    }

    /// Stops monitoring `node`.
    pub fn unmonitor(&mut self, node: u8) {
        self.monitors.remove(&node);
    }

    /// Feeds a heartbeat or boot-up of `node`; returns up to two events
    /// (recovered, then booted).
    pub fn on_heartbeat(&mut self, node: u8, state: NmtState, now: Instant) -> Vec<HeartbeatEvent> {
        let mut events = Vec::new();
        if let Some(m) = self.monitors.get_mut(&node) {
            m.last = now;
            if m.lost {
                m.lost = false;
                events.push(HeartbeatEvent::NodeRecovered { node, state });
            }
        }
        if state == NmtState::BootUp {
            events.push(HeartbeatEvent::NodeBooted { node });
        }
        events
    }

    /// Reports every monitored node whose consumer time has expired (each loss once).
    pub fn poll(&mut self, now: Instant) -> Vec<HeartbeatEvent> {
        let mut events = Vec::new();
        for (node, m) in &mut self.monitors {
            if !m.lost && now.saturating_duration_since(m.last) > m.consumer_time {
                m.lost = true;
                events.push(HeartbeatEvent::NodeLost { node: *node, last_seen: m.last });
            }
        }
        events
    }

    /// The earliest instant at which [`Self::poll`] may report a loss.
    pub fn next_deadline(&self) -> Option<Instant> {
        self.monitors.values().filter(|m| !m.lost).map(|m| m.last + m.consumer_time).min()
    }

    /// Whether `node` is monitored and currently lost.
    pub fn is_lost(&self, node: u8) -> bool {
        self.monitors.get(&node).is_some_and(|m| m.lost)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn lost_once_then_recovered() {
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut c = HeartbeatConsumer::new();
        c.monitor(5, ms(100), t0);
        assert!(c.on_heartbeat(5, NmtState::Operational, t0 + ms(50)).is_empty());
        // 50 + 100 = 150: not yet lost at exactly the consumer time (strictly greater).
        assert!(c.poll(t0 + ms(150)).is_empty());
        assert_eq!(c.poll(t0 + ms(151)), vec![HeartbeatEvent::NodeLost { node: 5, last_seen: t0 + ms(50) }]);
        // Reported once only.
        assert!(c.poll(t0 + ms(400)).is_empty());
        assert!(c.is_lost(5));
        assert_eq!(
            c.on_heartbeat(5, NmtState::Operational, t0 + ms(500)),
            vec![HeartbeatEvent::NodeRecovered { node: 5, state: NmtState::Operational }]
        );
        assert!(c.poll(t0 + ms(550)).is_empty());
        assert_eq!(c.next_deadline(), Some(t0 + ms(600)));
    }

    #[test]
    fn boot_up_is_reported_for_any_node() {
        let t0 = Instant::now();
        let mut c = HeartbeatConsumer::new();
        assert_eq!(c.on_heartbeat(9, NmtState::BootUp, t0), vec![HeartbeatEvent::NodeBooted { node: 9 }]);
        // An unmonitored node is never lost.
        assert!(c.poll(t0 + Duration::from_secs(10)).is_empty());
    }

    #[test]
    fn silent_from_the_start_is_lost() {
        let t0 = Instant::now();
        let mut c = HeartbeatConsumer::new();
        c.monitor(3, Duration::from_millis(10), t0);
        assert_eq!(
            c.poll(t0 + Duration::from_millis(11)),
            vec![HeartbeatEvent::NodeLost { node: 3, last_seen: t0 }]
        );
    }
}
