//! The heartbeat consumer (CiA 301 object 0x1016): the drive watches one producer — the
//! controlling master — and reacts when its heartbeats stop: EMCY 0x8130 ("life guard /
//! heartbeat error", error register bit 4) and the CiA 402 fault reaction (quick stop, then
//! Fault). This is the drive's own watchdog: when the station dies, the axis stops.
//!
//! Entry 1 of 0x1016: bits 16..23 the producer's node id, bits 0..15 the time in ms (0 or
//! node 0 disables). As CiA 301 specifies, monitoring starts with the first heartbeat
//! received from the producer, and an event is reported once until heartbeats resume.

use std::time::{Duration, Instant};

/// The consumer of one producer's heartbeat.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct HeartbeatConsumer {
    entry: u32,
    last: Option<Instant>,
    fired: bool,
}

impl HeartbeatConsumer {
    /// The producer's node id and the consumer time of the configured entry (`None`:
    /// disabled).
    #[must_use]
    pub fn watched(&self) -> Option<(u8, Duration)> {
        let node = ((self.entry >> 16) & 0xFF) as u8;
        let ms = u64::from(self.entry & 0xFFFF);
        (node != 0 && node <= 127 && ms != 0).then(|| (node, Duration::from_millis(ms)))
    }

    /// Applies the value of 0x1016:1 (a new value restarts the monitoring).
    pub fn configure(&mut self, entry: u32) {
        if entry != self.entry {
            *self = Self { entry, ..Self::default() };
        }
    }

    /// A heartbeat (or boot-up) of `node` was received at `now`.
    pub fn on_heartbeat(&mut self, node: u8, now: Instant) {
        if self.watched().is_some_and(|(n, _)| n == node) {
            self.last = Some(now);
            self.fired = false;
        }
    }

    /// True once when the producer's heartbeat is overdue at `now`.
    pub fn expired(&mut self, now: Instant) -> bool {
        let Some((_, time)) = self.watched() else { return false };
        let overdue = self.last.is_some_and(|t| now.saturating_duration_since(t) > time);
        if overdue && !self.fired {
            self.fired = true;
            return true;
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fires_once_after_the_first_heartbeat_stops() {
        let t0 = Instant::now();
        let ms = |m: u64| t0 + Duration::from_millis(m);
        let mut c = HeartbeatConsumer::default();
        assert_eq!(c.watched(), None);
        c.configure(0x007E_012C); // node 126, 300 ms
        assert_eq!(c.watched(), Some((126, Duration::from_millis(300))));
        // Not armed before the first heartbeat.
        assert!(!c.expired(ms(10_000)));
        c.on_heartbeat(5, ms(0)); // another node: ignored
        assert!(!c.expired(ms(10_000)));
        c.on_heartbeat(126, ms(10_000));
        assert!(!c.expired(ms(10_300)));
        assert!(c.expired(ms(10_301)));
        assert!(!c.expired(ms(10_400)), "reported once");
        c.on_heartbeat(126, ms(11_000));
        assert!(c.expired(ms(11_301)), "armed again by a heartbeat");
        c.configure(0);
        c.on_heartbeat(126, ms(12_000));
        assert!(!c.expired(ms(20_000)));
    }
}
