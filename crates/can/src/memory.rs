//! An in-process virtual CAN bus: every port sees the frames of every other port.

use crate::{CanBus, CanError, CanFrame, Received};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

struct Member {
    id: u64,
    tx: Sender<Received>,
}

/// The hub of an in-process bus. Cheap to clone; clones share the bus.
#[derive(Clone, Default)]
pub struct MemoryHub {
    members: Arc<Mutex<(u64, Vec<Member>)>>,
}

impl MemoryHub {
    /// A new, empty bus.
    pub fn new() -> Self {
        Self::default()
    }

    /// Joins the bus.
    pub fn connect(&self) -> MemoryPort {
        let (tx, rx) = channel();
        let mut guard = self.members.lock().unwrap_or_else(|p| p.into_inner());
        guard.0 += 1;
        let id = guard.0;
        guard.1.push(Member { id, tx });
        MemoryPort { id, hub: self.clone(), rx: Mutex::new(rx) }
    }
}

/// One endpoint of a [`MemoryHub`].
pub struct MemoryPort {
    id: u64,
    hub: MemoryHub,
    rx: Mutex<Receiver<Received>>,
}

impl CanBus for MemoryPort {
    fn send(&self, frame: &CanFrame) -> Result<(), CanError> {
        let mut guard = self.hub.members.lock().unwrap_or_else(|p| p.into_inner());
        let at = Instant::now();
        // Drop members whose port is gone.
        guard.1.retain(|m| m.id == self.id || m.tx.send(Received { frame: frame.clone(), at }).is_ok());
        Ok(())
    }

    fn recv(&self, timeout: Duration) -> Result<Option<Received>, CanError> {
        let rx = self.rx.lock().unwrap_or_else(|p| p.into_inner());
        match rx.recv_timeout(timeout) {
            Ok(r) => Ok(Some(r)),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => Err(CanError::Closed("memory bus".into())),
        }
    }

    fn describe(&self) -> String {
        format!("memory bus port {}", self.id)
    }
}

impl Drop for MemoryPort {
    fn drop(&mut self) {
        let mut guard = self.hub.members.lock().unwrap_or_else(|p| p.into_inner());
        guard.1.retain(|m| m.id != self.id);
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn frames_reach_every_other_port_but_not_the_sender() {
        let hub = MemoryHub::new();
        let a = hub.connect();
        let b = hub.connect();
        let c = hub.connect();
        let f = CanFrame::new(0x605, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]).unwrap();
        a.send(&f).unwrap();
        assert_eq!(b.recv(Duration::from_millis(100)).unwrap().unwrap().frame, f);
        assert_eq!(c.recv(Duration::from_millis(100)).unwrap().unwrap().frame, f);
        assert!(a.recv(Duration::from_millis(10)).unwrap().is_none());
    }
}
