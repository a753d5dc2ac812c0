//! A passive POWERLINK monitor: decodes every frame with the codec, groups frames into cycles
//! with [`CycleTracker`], counts every node's PRes and misses, and extracts the values of a
//! [`ValueMap`] (possibly empty: a cycle-only watch) from each mapped node's PRes, reporting one
//! [`CycleSample`] per cycle with per-node freshness.
//!
//! A cycle is reported when the next SoC closes it (so a sample is at most one cycle old when
//! delivered). A node's values are the ones of its most recent PRes; `age` counts the cycles
//! since that PRes (0: this cycle), and a value whose age exceeds [`MonitorConfig::stale_after`]
//! is stale. `valid` follows `specs/powerlink.md` §7: RD set and the sender OPERATIONAL.
//!
//! **No frame is lost silently.** Every frame received is counted as decoded or undecoded
//! ([`MonitorStats`]); frames lost before the monitor got them (the kernel's drops on a raw
//! socket, a capture's drop counts) are reported with [`Monitor::note_dropped`] at the point of
//! the stream where they are missing. A cycle with lost frames is not [`CycleSample::complete`]:
//! its misses are not counted (a lost frame may have been the PRes), and after a loss the
//! cycle index skips the SoCs estimated lost (the SoC-to-SoC time, from the SoC's RelativeTime
//! when the MN fills it, over the last complete cycle's).
//!
//! **Misses.** In a complete cycle, a node is expected to answer when the monitor saw the MN
//! poll it (PReq); on a port that has never seen a PReq (a switch port, which gets no unicast
//! PReq), every node that sent a PRes in an earlier cycle is expected. An expected node without
//! a PRes in the cycle is a miss ([`CycleSample::missing`], [`NodeCounters::misses`]), mapped
//! or not.
//!
//! [`Monitor::push`] is the sans-IO core; [`Monitor::run`] reads a live [`EthLink`] (with its
//! kernel drop counters) and [`Monitor::replay`] a capture (see [`crate::replay`]).

use std::collections::{BTreeMap, BTreeSet};
use std::io;
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use motus_epl_protocol::{
    Asnd, CycleReport, CycleTracker, EplFrame, ExtractError, Message, NmtState, Value, ValueMap,
};

use crate::replay::CapturedFrame;
use crate::transport::{EthLink, KernelRxStats, MAX_FRAME};

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
    /// Cycle index: 0 for the first SoC seen, then one per SoC seen plus the SoCs estimated
    /// lost in dropped frames (see the module documentation).
    pub index: u64,
    /// The tracker's report (SoC time, polled nodes, PRes seen, SoA, ASnd); its own `index`
    /// counts the SoCs seen only.
    pub report: CycleReport,
    /// One entry per node of the map, in map order (empty for a cycle-only watch).
    pub nodes: Vec<NodeSample>,
    /// False for the last cycle, still open when monitoring ended (no SoC closed it).
    pub closed: bool,
    /// Frames lost (dropped before the monitor received them) in this cycle.
    pub lost_frames: u64,
    /// Expected nodes (see the module documentation) without a PRes in this cycle; empty when
    /// the cycle is not [`CycleSample::complete`].
    pub missing: Vec<u8>,
    /// The monitor's counters when the cycle was reported.
    pub stats: MonitorStats,
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

    /// True when every frame of the cycle was received: no frame lost in it and the next SoC
    /// closed it. Only complete cycles count misses.
    pub fn complete(&self) -> bool {
        self.closed && self.lost_frames == 0
    }
}

/// Count, minimum, maximum and sum of durations (ns).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TimingStats {
    /// Durations recorded.
    pub count: u64,
    /// Shortest (0 when none).
    pub min_ns: u64,
    /// Longest (0 when none).
    pub max_ns: u64,
    /// Sum of all (saturating).
    pub sum_ns: u64,
}

impl TimingStats {
    /// Records one duration.
    pub fn record(&mut self, ns: u64) {
        self.min_ns = if self.count == 0 { ns } else { self.min_ns.min(ns) };
        self.max_ns = self.max_ns.max(ns);
        self.sum_ns = self.sum_ns.saturating_add(ns);
        self.count += 1;
    }

    /// The mean (`None` when none recorded).
    pub fn mean_ns(&self) -> Option<u64> {
        self.sum_ns.checked_div(self.count)
    }
}

/// Frame and cycle counters of a monitor. Every frame received is either decoded or
/// undecoded: `frames == decoded + undecoded`; frames lost before reception are in `dropped`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MonitorStats {
    /// Frames received.
    pub frames: u64,
    /// Frames decoded as POWERLINK.
    pub decoded: u64,
    /// Frames that were not POWERLINK or failed to decode.
    pub undecoded: u64,
    /// Frames known lost before reception ([`Monitor::note_dropped`]: the kernel's drops
    /// carried by the frames received after them, or a capture's drop counts).
    pub dropped: u64,
    /// The receiving socket's kernel counters, as last read (`None`: the link has none, e.g.
    /// a capture or a UDP link). `kernel.packets - kernel.drops - frames` frames were still
    /// queued, unread, at that moment; `kernel.drops - dropped` were dropped after the last
    /// frame received.
    pub kernel: Option<KernelRxStats>,
    /// Cycles reported.
    pub cycles: u64,
    /// Cycles reported with lost frames (their misses are not counted).
    pub cycles_with_loss: u64,
    /// SoCs estimated lost in dropped frames (never reported as cycles).
    pub cycles_lost: u64,
    /// SoC-to-SoC time of the complete cycles.
    pub cycle_time: TimingStats,
}

/// What the monitor saw of one node (every node that sent or was polled by a frame, mapped or
/// not).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeCounters {
    /// Node ID.
    pub node: u8,
    /// PReq frames to the node.
    pub polled: u64,
    /// PRes frames from the node.
    pub pres: u64,
    /// Complete cycles in which a PRes of the node was expected.
    pub expected: u64,
    /// Of those, cycles without its PRes.
    pub misses: u64,
    /// Its NMT state, as last reported (PRes, IdentResponse, StatusResponse; SoA for the MN).
    pub nmt_state: Option<NmtState>,
    /// Time from the SoC to its PRes, in cycles without lost frames.
    pub pres_after_soc: TimingStats,
}

impl NodeCounters {
    fn new(node: u8) -> Self {
        Self {
            node,
            polled: 0,
            pres: 0,
            expected: 0,
            misses: 0,
            nmt_state: None,
            pres_after_soc: TimingStats::default(),
        }
    }
}

#[derive(Debug, Clone, Default)]
struct Latest {
    cycle: Option<u64>,
    valid: bool,
    nmt_state: Option<NmtState>,
    values: Vec<(String, Value)>,
    error: Option<ExtractError>,
}

/// The SoC-to-SoC time of a complete cycle, the yardstick for the SoCs lost in a gap.
#[derive(Debug, Clone, Copy)]
struct Nominal {
    duration_ns: u64,
    /// RelativeTime step (µs), when the MN fills it.
    relative_us: Option<u64>,
}

/// The monitor (see the module documentation).
#[derive(Debug)]
pub struct Monitor {
    map: ValueMap,
    config: MonitorConfig,
    tracker: CycleTracker,
    latest: Vec<Latest>,
    stats: MonitorStats,
    counters: BTreeMap<u8, NodeCounters>,
    /// A PReq was seen on this port (unicast PReq reach it).
    preq_visible: bool,
    /// Nodes that sent a PRes in a reported cycle.
    pres_seen: BTreeSet<u8>,
    /// SoC time of the running cycle.
    soc_at_ns: Option<u64>,
    /// Frames lost in the running cycle.
    lost_in_cycle: u64,
    nominal: Option<Nominal>,
}

impl Monitor {
    /// A monitor for `map` (an empty map: a cycle-only watch).
    pub fn new(map: ValueMap, config: MonitorConfig) -> Self {
        let latest = vec![Latest::default(); map.nodes.len()];
        Self {
            map,
            config,
            tracker: CycleTracker::new(),
            latest,
            stats: MonitorStats::default(),
            counters: BTreeMap::new(),
            preq_visible: false,
            pres_seen: BTreeSet::new(),
            soc_at_ns: None,
            lost_in_cycle: 0,
            nominal: None,
        }
    }

    /// A cycle-only monitor: no value map (cycles, PRes, misses, NMT states, timing).
    pub fn cycles_only(config: MonitorConfig) -> Self {
        Self::new(ValueMap::default(), config)
    }

    /// Counters so far.
    pub fn stats(&self) -> MonitorStats {
        self.stats
    }

    /// Per-node counters of every node seen so far, by node ID.
    pub fn node_counters(&self) -> Vec<NodeCounters> {
        self.counters.values().copied().collect()
    }

    /// Reports `frames` frames lost between the frame pushed last and the next one (a kernel
    /// drop, a capture's drop count): the running cycle is marked incomplete.
    pub fn note_dropped(&mut self, frames: u64) {
        if frames == 0 {
            return;
        }
        self.stats.dropped += frames;
        if self.tracker.cycles_started() > 0 {
            self.lost_in_cycle += frames;
        }
    }

    /// Records the receiving socket's kernel counters (cumulative), for the reports.
    pub fn set_kernel_stats(&mut self, kernel: KernelRxStats) {
        self.stats.kernel = Some(kernel);
    }

    fn counters_of(&mut self, node: u8) -> &mut NodeCounters {
        self.counters.entry(node).or_insert_with(|| NodeCounters::new(node))
    }

    /// Feeds one Ethernet frame received at `at_ns` (any monotonic clock); returns the sample
    /// of the cycle it closed, if it was a SoC.
    pub fn push(&mut self, at_ns: u64, bytes: &[u8]) -> Option<CycleSample> {
        self.stats.frames += 1;
        let Ok(frame) = EplFrame::decode(bytes) else {
            self.stats.undecoded += 1;
            return None;
        };
        self.stats.decoded += 1;
        self.push_frame(at_ns, &frame)
    }

    /// Feeds one decoded frame (see [`Monitor::push`]; the frame counters are [`Monitor::push`]'s).
    pub fn push_frame(&mut self, at_ns: u64, frame: &EplFrame) -> Option<CycleSample> {
        let lost_so_far = self.stats.cycles_lost;
        let cycle_running = self.tracker.cycles_started() > 0;
        match &frame.message {
            Message::Soc(_) => {
                self.counters_of(frame.src_node);
            }
            Message::PReq(_) => {
                self.preq_visible = true;
                self.counters_of(frame.dst_node).polled += 1;
            }
            Message::PRes(p) => {
                let timing = match self.soc_at_ns {
                    Some(soc) if cycle_running && self.lost_in_cycle == 0 => Some(at_ns.saturating_sub(soc)),
                    _ => None,
                };
                let c = self.counters_of(frame.src_node);
                c.pres += 1;
                c.nmt_state = Some(p.nmt_state);
                if let Some(t) = timing {
                    c.pres_after_soc.record(t);
                }
            }
            Message::Soa(soa) => self.counters_of(frame.src_node).nmt_state = Some(soa.nmt_state),
            Message::Asnd(Asnd::IdentResponse(r)) => {
                self.counters_of(frame.src_node).nmt_state = Some(r.nmt_state)
            }
            Message::Asnd(Asnd::StatusResponse(r)) => {
                self.counters_of(frame.src_node).nmt_state = Some(r.nmt_state)
            }
            _ => {}
        }
        if let Message::PRes(p) = &frame.message {
            // The PRes belongs to the running cycle: its index is the number of SoCs seen - 1
            // (plus the SoCs lost so far).
            let cycle = self.tracker.cycles_started().checked_sub(1).map(|c| c + lost_so_far);
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
        let next_relative_us = match &frame.message {
            Message::Soc(soc) => {
                self.soc_at_ns = Some(at_ns);
                Some(soc.relative_time)
            }
            _ => None,
        };
        let report = self.tracker.push(at_ns, frame)?;
        Some(self.sample(report, next_relative_us))
    }

    /// Ends monitoring: the sample of the running cycle, if any (not closed: no misses counted).
    pub fn finish(&mut self) -> Option<CycleSample> {
        let report = self.tracker.finish()?;
        Some(self.sample(report, None))
    }

    /// Builds the sample of a cycle the tracker reported; `next_relative_us` is the RelativeTime
    /// of the SoC that closed it (`None`: still open).
    fn sample(&mut self, report: CycleReport, next_relative_us: Option<u64>) -> CycleSample {
        let closed = next_relative_us.is_some();
        let lost_frames = std::mem::take(&mut self.lost_in_cycle);
        let index = report.index + self.stats.cycles_lost;
        self.stats.cycles += 1;
        let complete = closed && lost_frames == 0;
        let relative_step =
            next_relative_us.and_then(|next| next.checked_sub(report.relative_time_us)).filter(|&d| d > 0);
        let mut missing = Vec::new();
        if complete {
            if let Some(d) = report.duration_ns {
                self.stats.cycle_time.record(d);
                self.nominal = Some(Nominal { duration_ns: d, relative_us: relative_step });
            }
            let expected: BTreeSet<u8> = if self.preq_visible {
                report.polled.iter().copied().collect()
            } else {
                self.pres_seen.clone()
            };
            for node in expected {
                let answered = report.saw_pres(node);
                let c = self.counters_of(node);
                c.expected += 1;
                if !answered {
                    c.misses += 1;
                    missing.push(node);
                }
            }
        } else if lost_frames > 0 {
            self.stats.cycles_with_loss += 1;
            if closed {
                self.stats.cycles_lost += self.socs_lost(&report, relative_step);
            }
        }
        self.pres_seen.extend(report.pres.iter().map(|p| p.node));
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
        CycleSample { index, report, nodes, closed, lost_frames, missing, stats: self.stats }
    }

    /// SoCs lost in a closed cycle with lost frames: its SoC-to-SoC time over the last complete
    /// cycle's, rounded, minus one (0 without a complete cycle to compare with).
    fn socs_lost(&self, report: &CycleReport, relative_step: Option<u64>) -> u64 {
        let Some(nominal) = self.nominal else { return 0 };
        let (span, unit) = match (relative_step, nominal.relative_us) {
            (Some(step), Some(unit)) => (step, unit),
            _ => (report.duration_ns.unwrap_or(0), nominal.duration_ns),
        };
        if unit == 0 {
            return 0;
        }
        (span.saturating_add(unit / 2) / unit).saturating_sub(1)
    }

    /// Reads frames from `link` and calls `on_cycle` for every cycle until `on_cycle` breaks or
    /// `stop` is set (checked at least every 50 ms of the link's time). Frame times count from
    /// the first frame's (on the link's clock, virtual on a [`crate::transport::MemHub`] made
    /// with one).
    ///
    /// Frames the link lost are noted where they are missing ([`EthLink::rx_drops`]; a link
    /// that only has [`EthLink::kernel_rx_stats`] places its new drops at the frame that
    /// follows their discovery); the kernel counters are read at every cycle and at the end.
    pub fn run(
        &mut self,
        link: &dyn EthLink,
        stop: &AtomicBool,
        mut on_cycle: impl FnMut(&CycleSample) -> ControlFlow<()>,
    ) -> io::Result<MonitorStats> {
        let mut start: Option<Instant> = None;
        let mut buf = vec![0u8; MAX_FRAME];
        // Drops carried by the frames (cumulative, as of the last frame read before this run).
        let mut frame_drops = link.rx_drops();
        // Kernel drops already noted (used only by a link without per-frame counts).
        let mut placed_kernel_drops = 0u64;
        while !stop.load(Ordering::Relaxed) {
            let Some((n, at)) = link.recv(&mut buf, Duration::from_millis(50))? else { continue };
            match (frame_drops, link.rx_drops()) {
                (Some(before), Some(now)) => {
                    self.note_dropped(now.saturating_sub(before));
                    frame_drops = Some(now);
                }
                _ => {
                    if let Some(k) = self.stats.kernel {
                        self.note_dropped(k.drops.saturating_sub(placed_kernel_drops));
                        placed_kernel_drops = placed_kernel_drops.max(k.drops);
                    }
                }
            }
            let start = *start.get_or_insert(at);
            let at_ns = u64::try_from(at.saturating_duration_since(start).as_nanos()).unwrap_or(u64::MAX);
            if let Some(mut s) = self.push(at_ns, buf.get(..n).unwrap_or(&[])) {
                self.read_kernel_stats(link);
                s.stats = self.stats;
                if on_cycle(&s).is_break() {
                    break;
                }
            }
        }
        self.read_kernel_stats(link);
        Ok(self.stats)
    }

    fn read_kernel_stats(&mut self, link: &dyn EthLink) {
        match link.kernel_rx_stats() {
            Ok(Some(k)) => self.set_kernel_stats(k),
            Ok(None) => {}
            Err(e) => tracing::warn!(link = %link.describe(), "kernel receive counters: {e}"),
        }
    }

    /// Feeds captured frames and calls `on_cycle` for every cycle (including the last, open
    /// one) until it breaks.
    pub fn replay<'a>(
        &mut self,
        frames: impl IntoIterator<Item = &'a CapturedFrame>,
        mut on_cycle: impl FnMut(&CycleSample) -> ControlFlow<()>,
    ) -> MonitorStats {
        for f in frames {
            self.note_dropped(f.dropped_before);
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

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

    use motus_epl_protocol::{Flags, MacAddr, NetTime, PReq, PRes, PrRs, RequestedService, Soa, Soc};

    use super::*;

    const MN: MacAddr = MacAddr([2, 0, 0, 0, 0, 240]);

    /// One frame with its capture time.
    type Frame = (u64, Vec<u8>);

    /// Cycle `k` of a 1 ms segment polling `polled` (PReq visible when `with_preq`), where the
    /// nodes in `answer` send their PRes; the SoC's RelativeTime is `k` ms when `relative`.
    fn cycle(k: u64, polled: &[u8], answer: &[u8], with_preq: bool, relative: bool) -> Vec<Frame> {
        let t0 = 1_000_000 * k;
        let soc = Soc {
            flags: Flags::empty(),
            net_time: NetTime::default(),
            relative_time: if relative { 1000 * k } else { 0 },
            reserved1: 0,
            reserved2: 0,
        };
        let mut out =
            vec![(t0, EplFrame::new(MN, MacAddr::SOC, 255, 240, Message::Soc(soc)).encode().unwrap())];
        for (i, &n) in polled.iter().enumerate() {
            let t = t0 + 100_000 * (i as u64 + 1);
            let cn = MacAddr([2, 0, 0, 0, 0, n]);
            if with_preq {
                let preq = PReq { flags: Flags::RD, payload: vec![0; 4], ..PReq::default() };
                out.push((t, EplFrame::new(MN, cn, n, 240, Message::PReq(preq)).encode().unwrap()));
            }
            if answer.contains(&n) {
                let pres = PRes {
                    nmt_state: NmtState::Operational,
                    flags: Flags::RD,
                    pr_rs: PrRs::default(),
                    pdo_version: 0,
                    payload: vec![n, 0, 0, 0],
                    reserved: 0,
                };
                out.push((
                    t + 20_000,
                    EplFrame::new(cn, MacAddr::PRES, 255, n, Message::PRes(pres)).encode().unwrap(),
                ));
            }
        }
        let soa = Soa::new(NmtState::Operational, RequestedService::NoService, 0);
        out.push((
            t0 + 500_000,
            EplFrame::new(MN, MacAddr::SOA, 255, 240, Message::Soa(soa)).encode().unwrap(),
        ));
        out
    }

    fn map_of(node: u8) -> ValueMap {
        ValueMap::from_toml(&format!(
            "[[node]]\nnode = {node}\nvalues = [{{ name = \"b\", offset = 0, type = \"u8\" }}]\n"
        ))
        .unwrap()
    }

    /// Pushes `frames`, noting `drops` (frames lost before the frame at that position).
    fn feed(m: &mut Monitor, frames: &[Frame], drops: &[(usize, u64)]) -> Vec<CycleSample> {
        let mut out = Vec::new();
        for (i, (t, bytes)) in frames.iter().enumerate() {
            for (_, n) in drops.iter().filter(|(at, _)| *at == i) {
                m.note_dropped(*n);
            }
            out.extend(m.push(*t, bytes));
        }
        out.extend(m.finish());
        out
    }

    /// A stream of 20 cycles with an undecodable frame and a gap of 16 frames from cycle 8's
    /// second PRes to cycle 11's first PReq (cycles 9 and 10 and three SoCs lost).
    fn gap_run(relative: bool) -> (Monitor, Vec<CycleSample>) {
        let mut frames = Vec::new();
        let mut gap_at = 0;
        for k in 0..20 {
            let mut c = cycle(k, &[1, 2], &[1, 2], true, relative);
            if k == 3 {
                c.insert(2, (c[1].0 + 1, vec![0xFF; 20]));
            }
            match k {
                // SoC, PReq 1, PRes 1, PReq 2 kept; PRes 2 and SoA lost.
                8 => c.truncate(4),
                9 | 10 => c.clear(),
                // SoC and PReq 1 lost.
                11 => {
                    c.drain(..2);
                    gap_at = frames.len();
                }
                _ => {}
            }
            frames.extend(c);
        }
        let mut m = Monitor::new(map_of(2), MonitorConfig { stale_after: 0 });
        let samples = feed(&mut m, &frames, &[(gap_at, 16)]);
        (m, samples)
    }

    #[test]
    fn every_frame_is_counted_and_a_gap_marks_its_cycle_without_misses() {
        for relative in [true, false] {
            let (m, samples) = gap_run(relative);
            let st = m.stats();
            assert_eq!(st.frames, 20 * 6 + 1 - 16, "relative {relative}");
            assert_eq!(st.frames, st.decoded + st.undecoded);
            assert_eq!(st.undecoded, 1);
            assert_eq!(st.dropped, 16);
            assert_eq!(st.kernel, None);
            // SoCs 0..=8 and 12..=19 seen; the three lost ones estimated from the SoC-to-SoC
            // time (RelativeTime, else the capture time) over the last complete cycle's.
            assert_eq!(st.cycles, 17);
            assert_eq!(st.cycles_lost, 3, "relative {relative}");
            assert_eq!(st.cycles_with_loss, 1);
            let idx: Vec<u64> = samples.iter().map(|s| s.index).collect();
            assert_eq!(idx, (0..=8).chain(12..20).collect::<Vec<_>>());
            let gap = &samples[8];
            assert_eq!((gap.lost_frames, gap.complete(), gap.missing.clone()), (16, false, vec![]));
            // The drop is not a miss: no node missed a cycle.
            assert!(samples.iter().all(|s| s.missing.is_empty()));
            for c in m.node_counters().iter().filter(|c| c.node != 240) {
                // 17 reported cycles less the one with lost frames and the last, still open.
                assert_eq!((c.node, c.expected, c.misses), (c.node, 15, 0));
            }
            // After the gap, node 2's value is fresh again, counted in the segment's cycles.
            let after = &samples[9];
            assert!(after.complete());
            assert_eq!(after.node(2).unwrap().age, Some(0));
            assert_eq!(after.node(2).unwrap().last_pres_cycle, Some(12));
            assert_eq!(st.cycle_time.count, 15);
            assert_eq!(st.cycle_time.mean_ns(), Some(1_000_000));
        }
    }

    #[test]
    fn a_missing_pres_is_a_miss_of_that_node_mapped_or_not() {
        let mut frames = Vec::new();
        for k in 0..6 {
            let answer: &[u8] = if k == 3 { &[1] } else { &[1, 2] };
            frames.extend(cycle(k, &[1, 2], answer, true, true));
        }
        // Only node 1 is mapped.
        let mut m = Monitor::new(map_of(1), MonitorConfig::default());
        let samples = feed(&mut m, &frames, &[]);
        let missing: Vec<(u64, Vec<u8>)> =
            samples.iter().filter(|s| !s.missing.is_empty()).map(|s| (s.index, s.missing.clone())).collect();
        assert_eq!(missing, vec![(3, vec![2])]);
        let c: BTreeMap<u8, NodeCounters> = m.node_counters().into_iter().map(|c| (c.node, c)).collect();
        assert_eq!((c[&1].polled, c[&1].pres, c[&1].expected, c[&1].misses), (6, 6, 5, 0));
        assert_eq!((c[&2].polled, c[&2].pres, c[&2].expected, c[&2].misses), (6, 5, 5, 1));
        assert_eq!(c[&2].nmt_state, Some(NmtState::Operational));
        assert_eq!(c[&240].nmt_state, Some(NmtState::Operational), "the MN's state, from its SoA");
        assert_eq!(c[&1].pres_after_soc.min_ns, 120_000);
        assert_eq!(c[&2].pres_after_soc.max_ns, 220_000);
    }

    #[test]
    fn without_visible_preq_nodes_seen_before_are_expected() {
        // A switch port: no unicast PReq reaches the monitor.
        let mut frames = Vec::new();
        for k in 0..6 {
            let answer: &[u8] = match k {
                0 => &[1],
                4 => &[2],
                _ => &[1, 2],
            };
            frames.extend(cycle(k, &[1, 2], answer, false, true));
        }
        let mut m = Monitor::cycles_only(MonitorConfig::default());
        let samples = feed(&mut m, &frames, &[]);
        let missing: Vec<(u64, Vec<u8>)> =
            samples.iter().filter(|s| !s.missing.is_empty()).map(|s| (s.index, s.missing.clone())).collect();
        // Node 2 is not expected before its first PRes (cycle 1); node 1 misses cycle 4.
        assert_eq!(missing, vec![(4, vec![1])]);
        assert!(samples.iter().all(|s| s.nodes.is_empty()));
    }

    #[test]
    fn drops_before_the_first_soc_are_counted_and_mark_no_cycle() {
        let mut m = Monitor::cycles_only(MonitorConfig::default());
        m.note_dropped(5);
        let samples =
            feed(&mut m, &[cycle(0, &[1], &[1], true, true), cycle(1, &[1], &[1], true, true)].concat(), &[]);
        assert_eq!(m.stats().dropped, 5);
        assert_eq!(m.stats().cycles_with_loss, 0);
        assert!(samples[0].complete());
        m.set_kernel_stats(KernelRxStats { packets: 20, drops: 5 });
        assert_eq!(m.stats().kernel, Some(KernelRxStats { packets: 20, drops: 5 }));
    }
}
