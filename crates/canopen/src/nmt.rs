//! NMT master side (CiA 301 §7.2.8): module control commands per node or broadcast,
//! and a node table fed by boot-up and heartbeat frames (COB-ID 0x700 + node).

use std::collections::BTreeMap;
use std::time::Instant;

use motus_canopen_protocol::{CanFrame, FrameError, NmtCommand, NmtState};

/// COB-ID base of heartbeat / boot-up frames.
pub const HEARTBEAT_BASE: u32 = 0x700;

/// The NMT command frame (COB-ID 0x000, 2 bytes: command specifier, node; node 0 = all).
pub fn command_frame(node: u8, command: NmtCommand) -> Result<CanFrame, FrameError> {
    CanFrame::new(0x000, &[command.raw(), node])
}

/// A heartbeat-like frame classified: `Some(Ok((node, state)))` for a valid heartbeat or
/// boot-up, `Some(Err(()))` for a frame in the heartbeat range that is malformed
/// (DLC != 1, RTR), `None` for frames outside 0x701..=0x77F.
#[allow(clippy::result_unit_err)]
pub fn parse_heartbeat(frame: &CanFrame) -> Option<Result<(u8, NmtState), ()>> {
    let id = frame.id();
    if frame.is_extended() || !(HEARTBEAT_BASE + 1..=HEARTBEAT_BASE + 0x7F).contains(&id) {
        return None;
    }
    let node = u8::try_from(id - HEARTBEAT_BASE).ok()?;
    match (frame.is_remote(), frame.data()) {
        // Bit 7 is the node-guarding toggle; heartbeats send it as 0.
        (false, [state]) if state & 0x80 == 0 => Some(Ok((node, NmtState::from_raw(*state)))),
        _ => Some(Err(())),
    }
}

/// What the node table learnt from a heartbeat.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeChange {
    /// The node sent a boot-up message (state 0x00).
    Booted {
        /// Node id.
        node: u8,
    },
    /// The node's reported state differs from the one it reported before (or is the first).
    StateChanged {
        /// Node id.
        node: u8,
        /// Previous state (None = never seen).
        from: Option<NmtState>,
        /// New state.
        to: NmtState,
    },
}

/// Last known NMT state of one node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeEntry {
    /// Last reported state.
    pub state: NmtState,
    /// When it was last heard.
    pub last_seen: Instant,
    /// Boot-up messages seen so far.
    pub boots: u64,
}

/// Node table: the last state each node reported.
#[derive(Debug, Clone, Default)]
pub struct NodeTable {
    nodes: BTreeMap<u8, NodeEntry>,
}

impl NodeTable {
    /// An empty table.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records a heartbeat / boot-up of `node`; returns what changed.
    pub fn on_heartbeat(&mut self, node: u8, state: NmtState, now: Instant) -> Option<NodeChange> {
        let previous = self.nodes.get(&node).copied();
        let boots = previous.map_or(0, |p| p.boots) + u64::from(state == NmtState::BootUp);
        self.nodes.insert(node, NodeEntry { state, last_seen: now, boots });
        if state == NmtState::BootUp {
            return Some(NodeChange::Booted { node });
        }
        let from = previous.map(|p| p.state);
        (from != Some(state)).then_some(NodeChange::StateChanged { node, from, to: state })
    }

    /// The entry of `node`.
    pub fn get(&self, node: u8) -> Option<&NodeEntry> {
        self.nodes.get(&node)
    }

    /// The last state `node` reported.
    pub fn state(&self, node: u8) -> Option<NmtState> {
        self.nodes.get(&node).map(|e| e.state)
    }

    /// Every node heard so far, in id order.
    pub fn iter(&self) -> impl Iterator<Item = (u8, &NodeEntry)> {
        self.nodes.iter().map(|(n, e)| (*n, e))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn command_frames() {
        // specs/canopen.md: NMT = COB-ID 0x000, byte 0 command (01 start, 80 pre-op), byte 1 node.
        assert_eq!(command_frame(5, NmtCommand::Start).unwrap().to_string(), "000#0105");
        assert_eq!(command_frame(0, NmtCommand::EnterPreOperational).unwrap().to_string(), "000#8000");
        assert_eq!(command_frame(0x7F, NmtCommand::ResetCommunication).unwrap().to_string(), "000#827F");
    }

    #[test]
    fn heartbeat_parsing_and_table() {
        let t0 = Instant::now();
        let f = |s: &str| s.parse::<CanFrame>().unwrap();
        // 705#00 = boot-up of node 5.
        assert_eq!(parse_heartbeat(&f("705#00")), Some(Ok((5, NmtState::BootUp))));
        // DLC 2 and RTR are malformed heartbeats; 0x185 is not a heartbeat.
        assert_eq!(parse_heartbeat(&f("705#0500")), Some(Err(())));
        assert_eq!(parse_heartbeat(&f("705#R")), Some(Err(())));
        assert_eq!(parse_heartbeat(&f("185#05")), None);
        let mut t = NodeTable::new();
        assert_eq!(t.on_heartbeat(5, NmtState::BootUp, t0), Some(NodeChange::Booted { node: 5 }));
        // 0x7F = pre-operational.
        assert_eq!(
            t.on_heartbeat(5, NmtState::PreOperational, t0),
            Some(NodeChange::StateChanged {
                node: 5,
                from: Some(NmtState::BootUp),
                to: NmtState::PreOperational
            })
        );
        assert_eq!(t.on_heartbeat(5, NmtState::PreOperational, t0), None);
        assert_eq!(t.state(5), Some(NmtState::PreOperational));
        assert_eq!(t.get(5).unwrap().boots, 1);
        assert_eq!(t.state(6), None);
    }
}
