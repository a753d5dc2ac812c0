//! The hub's model of a real bus's wire time: frames leave one after another, each
//! after its worst-case bit time at the configured bit rate.

use crate::{wire_time, CanFrame};
use std::collections::VecDeque;
use std::time::Instant;

/// Frames on the modelled bus, in the order they entered it.
pub(crate) struct BusModel {
    bitrate: u32,
    /// When the last queued frame has left the wire.
    free_at: Option<Instant>,
    /// `(deliver_at, source client, frame)`, `deliver_at` non-decreasing.
    queue: VecDeque<(Instant, u64, CanFrame)>,
}

impl BusModel {
    /// An idle bus at `bitrate` bit/s (> 0).
    pub fn new(bitrate: u32) -> BusModel {
        BusModel { bitrate, free_at: None, queue: VecDeque::new() }
    }

    /// A frame from client `source` arrives at `now`: it is delivered when the bus is
    /// free and has carried it (`max(now, free_at) + frame_time`).
    pub fn enter(&mut self, now: Instant, source: u64, frame: CanFrame) {
        let start = self.free_at.map_or(now, |f| f.max(now));
        let deliver_at = start + wire_time::frame_time(&frame, self.bitrate);
        self.free_at = Some(deliver_at);
        self.queue.push_back((deliver_at, source, frame));
    }

    /// When the next frame is due.
    pub fn next_due(&self) -> Option<Instant> {
        self.queue.front().map(|(t, _, _)| *t)
    }

    /// The frames due at `now`, in order.
    pub fn take_due(&mut self, now: Instant) -> Vec<(u64, CanFrame)> {
        let mut due = Vec::new();
        while self.queue.front().is_some_and(|(t, _, _)| *t <= now) {
            if let Some((_, source, frame)) = self.queue.pop_front() {
                due.push((source, frame));
            }
        }
        due
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn frames_queue_behind_each_other_and_an_idle_bus_starts_at_arrival() {
        let mut bus = BusModel::new(20_000);
        let t0 = Instant::now();
        let f = CanFrame::new(0x181, &[0x55; 8]).unwrap_or_else(|_| unreachable!());
        let one = wire_time::frame_time(&f, 20_000);
        bus.enter(t0, 1, f.clone());
        bus.enter(t0, 1, f.clone());
        assert_eq!(bus.next_due(), Some(t0 + one));
        assert!(bus.take_due(t0 + one - Duration::from_micros(1)).is_empty());
        assert_eq!(bus.take_due(t0 + one).len(), 1);
        assert_eq!(bus.next_due(), Some(t0 + one * 2));
        // Idle again later: the next frame starts when it arrives.
        let later = t0 + Duration::from_secs(1);
        assert_eq!(bus.take_due(later).len(), 1);
        bus.enter(later, 2, f);
        assert_eq!(bus.next_due(), Some(later + one));
    }
}
