//! NMT slave (CiA 301 §7.3.2, specs/canopen.md 3.2): the NMT state machine and the heartbeat
//! producer (0x1017). Initialising -> boot-up message (0x700 + id, data 00) ->
//! pre-operational; start / stop / enter pre-operational; reset node (application reset)
//! and reset communication both end in a new boot-up. PDOs run only in operational; in
//! stopped only NMT, heartbeat and LSS are served.

use std::time::{Duration, Instant};

use motus_canopen_protocol::{NmtCommand, NmtState};

/// What the device must do after an NMT command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NmtAction {
    /// Nothing beyond the state change (or no change).
    None,
    /// Entered operational: send every enabled TPDO once.
    EnteredOperational,
    /// Reset node: application reset, then reset communication and boot-up.
    ResetNode,
    /// Reset communication: communication objects back to defaults, boot-up.
    ResetCommunication,
}

/// NMT state and heartbeat timer of one node.
#[derive(Debug, Clone)]
pub struct Nmt {
    state: NmtState,
    next_heartbeat: Option<Instant>,
}

impl Default for Nmt {
    fn default() -> Self {
        Self::new()
    }
}

impl Nmt {
    /// A node still initialising (no boot-up sent yet).
    pub fn new() -> Self {
        Self { state: NmtState::BootUp, next_heartbeat: None }
    }

    /// The NMT state (`BootUp` = initialising).
    pub fn state(&self) -> NmtState {
        self.state
    }

    /// Back to initialising (before a reset's boot-up, or while LSS-unconfigured).
    pub fn initialise(&mut self) {
        self.state = NmtState::BootUp;
        self.next_heartbeat = None;
    }

    /// Initialisation finished: the caller sends the boot-up frame; the node is
    /// pre-operational and the first heartbeat is due one period later.
    pub fn boot(&mut self, now: Instant, heartbeat_ms: u16) {
        self.state = NmtState::PreOperational;
        self.schedule(now, heartbeat_ms);
    }

    /// Restarts the heartbeat timer (after a write of 0x1017).
    pub fn schedule(&mut self, now: Instant, heartbeat_ms: u16) {
        self.next_heartbeat =
            (heartbeat_ms > 0).then(|| now + Duration::from_millis(u64::from(heartbeat_ms)));
    }

    /// Applies an NMT command addressed to this node.
    pub fn command(&mut self, command: NmtCommand) -> NmtAction {
        if self.state == NmtState::BootUp {
            return NmtAction::None;
        }
        match command {
            NmtCommand::Start => {
                let was = self.state;
                self.state = NmtState::Operational;
                if was == NmtState::Operational {
                    NmtAction::None
                } else {
                    NmtAction::EnteredOperational
                }
            }
            NmtCommand::Stop => {
                self.state = NmtState::Stopped;
                NmtAction::None
            }
            NmtCommand::EnterPreOperational => {
                self.state = NmtState::PreOperational;
                NmtAction::None
            }
            NmtCommand::ResetNode => NmtAction::ResetNode,
            NmtCommand::ResetCommunication => NmtAction::ResetCommunication,
            NmtCommand::Unknown(_) => NmtAction::None,
        }
    }

    /// The heartbeat state byte when a heartbeat is due at `now` (and re-arms the timer).
    pub fn heartbeat(&mut self, now: Instant, heartbeat_ms: u16) -> Option<u8> {
        let due = self.next_heartbeat?;
        if now < due || self.state == NmtState::BootUp {
            return None;
        }
        let period = Duration::from_millis(u64::from(heartbeat_ms));
        // Keep the cadence; skip missed beats after a long pause.
        let mut next = due + period;
        if next <= now {
            next = now + period;
        }
        self.next_heartbeat = (heartbeat_ms > 0).then_some(next);
        Some(self.state.raw())
    }

    /// Whether SDO is served (pre-operational and operational).
    pub fn sdo_allowed(&self) -> bool {
        matches!(self.state, NmtState::PreOperational | NmtState::Operational)
    }

    /// Whether PDOs run.
    pub fn pdo_allowed(&self) -> bool {
        self.state == NmtState::Operational
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn states_and_heartbeat_cadence() {
        let t0 = Instant::now();
        let mut n = Nmt::new();
        assert_eq!(n.command(NmtCommand::Start), NmtAction::None, "no NMT before boot-up");
        n.boot(t0, 100);
        assert_eq!(n.state(), NmtState::PreOperational);
        assert!(n.sdo_allowed() && !n.pdo_allowed());
        assert_eq!(n.heartbeat(t0 + Duration::from_millis(99), 100), None);
        // Heartbeat byte 0x7F = pre-operational (spec 3.2 table).
        assert_eq!(n.heartbeat(t0 + Duration::from_millis(100), 100), Some(0x7F));
        assert_eq!(n.command(NmtCommand::Start), NmtAction::EnteredOperational);
        assert_eq!(n.command(NmtCommand::Start), NmtAction::None);
        assert_eq!(n.heartbeat(t0 + Duration::from_millis(200), 100), Some(0x05));
        assert_eq!(n.command(NmtCommand::Stop), NmtAction::None);
        assert!(!n.sdo_allowed());
        assert_eq!(n.heartbeat(t0 + Duration::from_millis(300), 100), Some(0x04));
        assert_eq!(n.command(NmtCommand::ResetCommunication), NmtAction::ResetCommunication);
        assert_eq!(n.command(NmtCommand::ResetNode), NmtAction::ResetNode);
        n.schedule(t0, 0);
        assert_eq!(n.heartbeat(t0 + Duration::from_secs(10), 0), None, "0x1017 = 0 disables");
    }
}
