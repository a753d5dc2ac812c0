//! Cycle tracking (sans-IO): feed decoded frames with their capture timestamps; each SoC
//! closes the running cycle and yields a [`CycleReport`] saying which nodes were polled
//! (PReq) and which answered with a PRes, in what NMT state and how long after the SoC.
//!
//! Frames before the first SoC (the reduced PreOp1 cycle has no SoC) are counted, not reported.
//! Timestamps are caller-supplied nanoseconds on any monotonic clock (pcap time works).

use serde::Serialize;

use crate::codes::{NmtState, RequestedService};
use crate::flags::Flags;
use crate::frame::{EplFrame, Message};

/// A PRes seen in a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct PresSeen {
    /// Source node.
    pub node: u8,
    /// NMT state byte of the PRes.
    pub nmt_state: NmtState,
    /// RD flag (payload valid).
    pub ready: bool,
    /// Nanoseconds after the SoC.
    pub after_soc_ns: u64,
    /// Payload size.
    pub payload_len: usize,
}

/// One SoC-to-SoC cycle.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct CycleReport {
    /// 0 for the first cycle seen.
    pub index: u64,
    /// Timestamp of the SoC (ns).
    pub soc_at_ns: u64,
    /// SoC RelativeTime (µs).
    pub relative_time_us: u64,
    /// SoC flags (PS, MC...).
    pub soc_flags: Flags,
    /// Time from this SoC to the next one (ns); `None` for the cycle returned by
    /// [`CycleTracker::finish`].
    pub duration_ns: Option<u64>,
    /// Nodes polled with a PReq, in order.
    pub polled: Vec<u8>,
    /// PRes seen, in order.
    pub pres: Vec<PresSeen>,
    /// The SoA invitation of the cycle: service and target.
    pub soa: Option<(RequestedService, u8)>,
    /// Source nodes of ASnd frames in the cycle.
    pub asnd_from: Vec<u8>,
}

impl CycleReport {
    /// The PRes of `node` in this cycle, if seen.
    pub fn pres_of(&self, node: u8) -> Option<&PresSeen> {
        self.pres.iter().find(|p| p.node == node)
    }

    /// True when `node` sent a PRes in this cycle.
    pub fn saw_pres(&self, node: u8) -> bool {
        self.pres_of(node).is_some()
    }

    /// Nodes polled with a PReq that did not answer with a PRes.
    pub fn missing(&self) -> Vec<u8> {
        self.polled.iter().copied().filter(|&n| !self.saw_pres(n)).collect()
    }
}

/// Groups frames into SoC cycles.
#[derive(Debug, Clone, Default)]
pub struct CycleTracker {
    current: Option<CycleReport>,
    next_index: u64,
    before_first_soc: u64,
}

impl CycleTracker {
    /// A tracker that has seen nothing.
    pub fn new() -> Self {
        Self::default()
    }

    /// Frames fed before the first SoC.
    pub fn frames_before_first_soc(&self) -> u64 {
        self.before_first_soc
    }

    /// Number of cycles started (SoCs seen).
    pub fn cycles_started(&self) -> u64 {
        self.next_index
    }

    /// Feeds one frame received at `at_ns`; returns the cycle this frame's SoC closed.
    pub fn push(&mut self, at_ns: u64, frame: &EplFrame) -> Option<CycleReport> {
        if let Message::Soc(soc) = &frame.message {
            let mut closed = self.current.take();
            if let Some(c) = closed.as_mut() {
                c.duration_ns = Some(at_ns.saturating_sub(c.soc_at_ns));
            }
            self.current = Some(CycleReport {
                index: self.next_index,
                soc_at_ns: at_ns,
                relative_time_us: soc.relative_time,
                soc_flags: soc.flags,
                duration_ns: None,
                polled: Vec::new(),
                pres: Vec::new(),
                soa: None,
                asnd_from: Vec::new(),
            });
            self.next_index += 1;
            return closed;
        }
        let Some(c) = self.current.as_mut() else {
            self.before_first_soc += 1;
            return None;
        };
        match &frame.message {
            Message::PReq(_) => c.polled.push(frame.dst_node),
            Message::PRes(p) => c.pres.push(PresSeen {
                node: frame.src_node,
                nmt_state: p.nmt_state,
                ready: p.flags.contains(Flags::RD),
                after_soc_ns: at_ns.saturating_sub(c.soc_at_ns),
                payload_len: p.payload.len(),
            }),
            Message::Soa(s) => c.soa = Some((s.requested_service, s.target)),
            Message::Asnd(_) => c.asnd_from.push(frame.src_node),
            _ => {}
        }
        None
    }

    /// Ends tracking: returns the running cycle (its `duration_ns` is `None`).
    pub fn finish(&mut self) -> Option<CycleReport> {
        self.current.take()
    }
}
