//! A passive POWERLINK monitor: decodes every frame with the codec, groups frames into cycles
//! with [`CycleTracker`], extracts the values of a [`ValueMap`] from each mapped node's PRes, and
//! reports one [`CycleSample`] per cycle with per-node freshness.
//!
//! A cycle is reported when the next SoC closes it (so a sample is at most one cycle old when
//! delivered). A node's values are the ones of its most recent PRes; `age` counts the cycles
//! since that PRes (0: this cycle), and a value whose age exceeds [`MonitorConfig::stale_after`]
//! is stale. `valid` follows `specs/powerlink.md` §7: RD set and the sender OPERATIONAL.
//! [`Monitor::push`] is the sans-IO core; [`Monitor::run`] reads a live [`EthLink`] and
//! [`Monitor::replay`] a capture (see [`crate::replay`]).

use std::io;
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use motus_epl_protocol::{
    CycleReport, CycleTracker, EplFrame, ExtractError, Message, NmtState, Value, ValueMap,
};

use crate::replay::CapturedFrame;
use crate::transport::{EthLink, MAX_FRAME};

/// Monitor settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MonitorConfig {
    /// A value older than this many cycles is stale (0: it must come from the reported cycle).
    pub stale_after: u64,
}

impl Default for MonitorConfig {
    fn default() -> Self {
        Self { stale_after: 1 }
    }
}

/// The values of one mapped node in a cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeSample {
    /// Node ID.
    pub node: u8,
    /// Index of the cycle of the node's most recent PRes (`None`: never seen).
    pub last_pres_cycle: Option<u64>,
    /// Cycles since that PRes (0: in this cycle); `None`: never seen.
    pub age: Option<u64>,
    /// True when never seen or older than [`MonitorConfig::stale_after`].
    pub stale: bool,
    /// RD set and NMT state OPERATIONAL in that PRes.
    pub valid: bool,
    /// NMT state in that PRes.
    pub nmt_state: Option<NmtState>,
    /// Values in map order (name, value); empty when never seen or not extractable.
    pub values: Vec<(String, Value)>,
    /// Why values could not be extracted from the latest PRes.
    pub error: Option<ExtractError>,
}

impl NodeSample {
    /// The value named `name`.
    pub fn value(&self, name: &str) -> Option<Value> {
        self.values.iter().find(|(n, _)| n == name).map(|(_, v)| *v)
    }
}

/// One cycle as the monitor saw it.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleSample {
    /// Cycle index (0 for the first SoC seen).
    pub index: u64,
    /// The tracker's report (SoC time, polled nodes, PRes seen, SoA, ASnd).
    pub report: CycleReport,
    /// One entry per node of the map, in map order.
    pub nodes: Vec<NodeSample>,
}

impl CycleSample {
    /// The sample of `node`.
    pub fn node(&self, node: u8) -> Option<&NodeSample> {
        self.nodes.iter().find(|n| n.node == node)
    }

    /// True when every mapped node has a fresh, valid value.
    pub fn all_fresh(&self) -> bool {
        self.nodes.iter().all(|n| !n.stale && n.valid && n.error.is_none())
    }
}

/// Frame counters of a monitor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MonitorStats {
    /// Frames received.
    pub frames: u64,
    /// Frames that were not POWERLINK or failed to decode.
    pub undecoded: u64,
    /// Cycles reported.
    pub cycles: u64,
}

#[derive(Debug, Clone, Default)]
struct Latest {
    cycle: Option<u64>,
    valid: bool,
    nmt_state: Option<NmtState>,
    values: Vec<(String, Value)>,
    error: Option<ExtractError>,
}

/// The monitor (see the module documentation).
#[derive(Debug)]
pub struct Monitor {
    map: ValueMap,
    config: MonitorConfig,
    tracker: CycleTracker,
    latest: Vec<Latest>,
    stats: MonitorStats,
}

impl Monitor {
    /// A monitor for `map`.
    pub fn new(map: ValueMap, config: MonitorConfig) -> Self {
        let latest = vec![Latest::default(); map.nodes.len()];
        Self { map, config, tracker: CycleTracker::new(), latest, stats: MonitorStats::default() }
    }

    /// Counters so far.
    pub fn stats(&self) -> MonitorStats {
        self.stats
    }

    /// Feeds one Ethernet frame received at `at_ns` (any monotonic clock); returns the sample
    /// of the cycle it closed, if it was a SoC.
    pub fn push(&mut self, at_ns: u64, bytes: &[u8]) -> Option<CycleSample> {
        self.stats.frames += 1;
        let Ok(frame) = EplFrame::decode(bytes) else {
            self.stats.undecoded += 1;
            return None;
        };
        self.push_frame(at_ns, &frame)
    }

    /// Feeds one decoded frame (see [`Monitor::push`]).
    pub fn push_frame(&mut self, at_ns: u64, frame: &EplFrame) -> Option<CycleSample> {
        if let Message::PRes(p) = &frame.message {
            // The PRes belongs to the running cycle: its index is the number of SoCs seen - 1.
            let cycle = self.tracker.cycles_started().checked_sub(1);
            if let Some(i) = self.map.nodes.iter().position(|n| n.node == frame.src_node) {
                if let (Some(spec), Some(slot)) = (self.map.nodes.get(i), self.latest.get_mut(i)) {
                    slot.cycle = cycle;
                    slot.valid = p.is_valid_data();
                    slot.nmt_state = Some(p.nmt_state);
                    slot.values.clear();
                    slot.error = None;
                    for v in &spec.values {
                        match v.read(frame.src_node, &p.payload) {
                            Ok(x) => slot.values.push((v.name.clone(), x)),
                            Err(e) => {
                                slot.error = Some(e);
                                slot.values.clear();
                                break;
                            }
                        }
                    }
                }
            }
        }
        let report = self.tracker.push(at_ns, frame)?;
        Some(self.sample(report))
    }

    /// Ends monitoring: the sample of the running cycle, if any.
    pub fn finish(&mut self) -> Option<CycleSample> {
        let report = self.tracker.finish()?;
        Some(self.sample(report))
    }

    fn sample(&mut self, report: CycleReport) -> CycleSample {
        self.stats.cycles += 1;
        let index = report.index;
        let nodes = self
            .map
            .nodes
            .iter()
            .zip(&self.latest)
            .map(|(spec, l)| {
                let age = l.cycle.map(|c| index.saturating_sub(c));
                NodeSample {
                    node: spec.node,
                    last_pres_cycle: l.cycle,
                    age,
                    stale: age.map_or(true, |a| a > self.config.stale_after),
                    valid: l.valid,
                    nmt_state: l.nmt_state,
                    values: l.values.clone(),
                    error: l.error.clone(),
                }
            })
            .collect();
        CycleSample { index, report, nodes }
    }

    /// Reads frames from `link` and calls `on_cycle` for every cycle until `on_cycle` breaks or
    /// `stop` is set (checked at least every 50 ms of the link's time). Frame times count from
    /// the first frame's (on the link's clock, virtual on a [`crate::transport::MemHub`] made
    /// with one).
    pub fn run(
        &mut self,
        link: &dyn EthLink,
        stop: &AtomicBool,
        mut on_cycle: impl FnMut(&CycleSample) -> ControlFlow<()>,
    ) -> io::Result<MonitorStats> {
        let mut start: Option<Instant> = None;
        let mut buf = vec![0u8; MAX_FRAME];
        while !stop.load(Ordering::Relaxed) {
            let Some((n, at)) = link.recv(&mut buf, Duration::from_millis(50))? else { continue };
            let start = *start.get_or_insert(at);
            let at_ns = u64::try_from(at.saturating_duration_since(start).as_nanos()).unwrap_or(u64::MAX);
            if let Some(s) = self.push(at_ns, buf.get(..n).unwrap_or(&[])) {
                if on_cycle(&s).is_break() {
                    break;
                }
            }
        }
        Ok(self.stats)
    }

    /// Feeds captured frames and calls `on_cycle` for every cycle (including the last, open
    /// one) until it breaks.
    pub fn replay<'a>(
        &mut self,
        frames: impl IntoIterator<Item = &'a CapturedFrame>,
        mut on_cycle: impl FnMut(&CycleSample) -> ControlFlow<()>,
    ) -> MonitorStats {
        for f in frames {
            if let Some(s) = self.push(f.at_ns, &f.data) {
                if on_cycle(&s).is_break() {
                    return self.stats;
                }
            }
        }
        if let Some(s) = self.finish() {
            let _ = on_cycle(&s);
        }
        self.stats
    }
}
