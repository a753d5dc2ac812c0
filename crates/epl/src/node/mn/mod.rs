//! A Managing Node for foreign Controlled Nodes (openPOWERLINK's among them), configured by a
//! concise DCF ([`Cdc`]): the boot-up of `specs/powerlink.md` §6 with SDO configuration, then
//! the isochronous cycle with process data by the CNs' PDO mappings.
//!
//! [`CdcMn`] is sans-IO: frames in ([`CdcMn::on_frame`]), frames out, and time is an input
//! (`now` on every call). A runtime ([`runtime::spawn`]) drives it on an
//! [`crate::EthLink`] and a clock; tests drive it directly on virtual time. One cycle:
//!
//! 1. [`CdcMn::start_cycle`]: `true` for a full cycle (then send [`CdcMn::soc`]), `false` for
//!    the reduced PRE_OPERATIONAL_1 cycle (SoA only).
//! 2. Full cycle: for each node of [`CdcMn::poll_list`], send [`CdcMn::preq`], wait for its
//!    PRes up to [`CdcMn::pres_timeout`] (feeding every frame to [`CdcMn::on_frame`]); when it
//!    does not come, [`CdcMn::pres_missed`].
//! 3. [`CdcMn::async_slot`]: the SoA and the MN's own ASnd, if any; when it names a node,
//!    wait for that node's ASnd up to the async time-out (0x1F8A/2).
//! 4. [`CdcMn::end_cycle`]: boot-up steps for the next cycle.
//!
//! What the MN does, after openPOWERLINK V2.7.2's MN as captured in
//! `shared/fixtures/powerlink/oplk_mn_cn_veth_merged.pcapng` (frame numbers cited):
//!
//! * PRE_OPERATIONAL_1: [`MnConfig::preop1_start_cycles`] SoAs without invitation (frames
//!   1-10), then SoA NMTRequestInvite to itself with a broadcast NMTResetNode (11, 12), then
//!   one IdentRequest per SoA to the unidentified CNs in turn (443...) until every CN answered
//!   or [`MnConfig::preop1_cycles`] passed; then the full cycle (862: SoC), the MN going
//!   PRE_OPERATIONAL_2, READY_TO_OPERATE, OPERATIONAL on its own (the demo's CNs are not
//!   mandatory: 868, 870).
//! * A CN's IdentResponse (866) gives its MAC and identity. The identity is checked against the
//!   CDC's expected values (0x1F84 device type, 0x1F85 vendor, 0x1F86 product, 0x1F87 revision,
//!   0x1F88 serial number of the node; 0 or absent: not checked). A mismatch is reported and
//!   the CN is asked again after [`MnConfig::retry_cycles`].
//! * Error signalling is initialised by a StatusRequest with the ER flag (881; the CN answers
//!   EC, 882); further StatusRequests until the CN reports PRE_OPERATIONAL_2, from when it is
//!   polled by PReq (886). A PRes whose EN differs from the EA the MN sends asks for a
//!   StatusRequest; the EN of the StatusResponse is then acknowledged by EA in the PReqs.
//! * Configuration (when the IdentResponse's VerifyConfiguration date and time differ from the
//!   CDC's 0x1F26/0x1F27 for the node, or these are absent): the SDO client writes the node's
//!   `node_config` entries in order (936..1409), the MN's frames after a SoA UnspecifiedInvite
//!   to itself (935), the CN's after a SoA UnspecifiedInvite to the CN (944), which the MN sends
//!   while a transfer waits for the CN or the CN signals pending frames (RS in PRes or
//!   StatusResponse). A failed write is reported and the next one follows. Then
//!   NMTResetConfiguration (1415, 1416): the CN resets its communication with the new values
//!   and is identified again (1434..1451), without configuration this time.
//! * PRE_OPERATIONAL_2 -> NMTEnableReadyToOperate (1463); READY_TO_OPERATE -> NMTStartNode
//!   (1496, when the node assignment allows the MN to start it); OPERATIONAL (1499). Commands
//!   are repeated every [`MnConfig::retry_cycles`] until the CN follows.
//! * Process data: the PReq carries the MN's outputs laid out by the CN's RPDO mapping
//!   (0x1600+k as the CDC configured it, channel 0x1400+k/1 = 0), RD set once the MN is
//!   OPERATIONAL (1455); the PRes payload is decoded by the CN's TPDO mapping (0x1A00+k). An
//!   output is a running counter (incremented every [`MnConfig::counter_every`] cycles) unless
//!   [`MnConfig::overrides`] sets it; an override of an object that is not mapped is written by
//!   SDO at the end of the configuration.
//! * Supervision: a CN whose PRes is missed [`MnConfig::lost_after`] times in a row, or that
//!   reports a state other than the one it was brought to (e.g. back in PRE_OPERATIONAL_2
//!   after a loss of SoC, or reset), is booted again from the IdentRequest; the
//!   VerifyConfiguration date and time decide whether it is configured again (a restarted
//!   process has lost its configuration).
//!
//! Per-node state, counters, values and events: [`CdcMn::nodes`], [`CdcMn::pop_event`].

pub mod runtime;

use std::collections::VecDeque;
use std::fmt;
use std::time::{Duration, Instant};

use motus_epl_protocol::cdc::NodeAssignment;
use motus_epl_protocol::od::MappingEntry;
use motus_epl_protocol::sdo_transfer::TransferKind;
use motus_epl_protocol::{
    Asnd, Cdc, CdcEntry, EplFrame, Flags, IdentResponse, MacAddr, Message, NetTime, NmtCommand, NmtCommandId,
    NmtState, PReq, RequestedService, SdoClient, SdoConfig, SdoFrame, Soa, Soc, BROADCAST_NODE_ID,
    MN_NODE_ID,
};
use thiserror::Error;

/// 0x1F92 NMT_MNCNPResTimeout_AU32: PRes time-out per node, in ns.
pub const PRES_TIMEOUT: u16 = 0x1F92;
/// 0x1F8A NMT_MNCycleTiming_REC: subindex 2 is the async slot time-out, in ns.
pub const MN_CYCLE_TIMING: u16 = 0x1F8A;
/// 0x1F8B NMT_MNPReqPayloadLimitList_AU16: PReq payload limit per node.
pub const PREQ_PAYLOAD_LIMIT: u16 = 0x1F8B;
/// 0x1F8D NMT_PResPayloadLimitList_AU16: PRes payload limit per node.
pub const PRES_PAYLOAD_LIMIT: u16 = 0x1F8D;
/// 0x1F98 NMT_CycleTiming_REC (in a CN's configuration): subindex 4 PReq, 5 PRes payload limit.
pub const CYCLE_TIMING: u16 = 0x1F98;
/// 0x1F26 CFM_ExpConfDateList_AU32: the configuration date expected in 0x1020/1.
pub const EXP_CONF_DATE: u16 = 0x1F26;
/// 0x1F27 CFM_ExpConfTimeList_AU32: the configuration time expected in 0x1020/2.
pub const EXP_CONF_TIME: u16 = 0x1F27;
/// 0x1F84..=0x1F88: expected device type, vendor ID, product code, revision, serial number.
pub const EXP_IDENTITY: [u16; 5] = [0x1F84, 0x1F85, 0x1F86, 0x1F87, 0x1F88];

/// Why a CDC cannot drive the MN.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum MnError {
    /// No cycle length (0x1006) or zero.
    #[error("the CDC has no cycle length (0x1006/0)")]
    NoCycleLength,
    /// No CN assigned (0x1F81).
    #[error("the CDC assigns no CN (0x1F81)")]
    NoNodes,
    /// An override names a node the CDC does not assign.
    #[error("--set names node {0}, which the CDC does not assign")]
    UnknownNode(u8),
}

/// Settings of the MN that the CDC does not give.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MnConfig {
    /// The MN's MAC (source of every frame).
    pub mac: MacAddr,
    /// SoAs without invitation at the start of PRE_OPERATIONAL_1 (openPOWERLINK: 10).
    pub preop1_start_cycles: u32,
    /// Reduced cycles at most before the full cycle starts (unidentified CNs are then invited
    /// in the async slot).
    pub preop1_cycles: u32,
    /// Cycles between repetitions of an NMT command, and before an identity mismatch is
    /// checked again.
    pub retry_cycles: u64,
    /// PRes missed in a row before a CN is booted again.
    pub lost_after: u32,
    /// In OPERATIONAL, one StatusRequest to each CN every this many cycles (0: never).
    pub status_every: u64,
    /// A running-counter output is incremented every this many cycles.
    pub counter_every: u64,
    /// A lower bound for the PRes time-out (the CDC's 0x1F92 is used when larger).
    pub min_pres_timeout: Duration,
    /// Fixed output values: (node, index, subindex, value).
    pub overrides: Vec<(u8, u16, u8, u64)>,
    /// The SDO client's time-outs.
    pub sdo: SdoConfig,
}

impl Default for MnConfig {
    fn default() -> Self {
        Self {
            mac: MacAddr([0x02, 0, 0, 0, 0, MN_NODE_ID]),
            preop1_start_cycles: 10,
            preop1_cycles: 500,
            retry_cycles: 100,
            lost_after: 20,
            status_every: 1000,
            counter_every: 100,
            min_pres_timeout: Duration::ZERO,
            overrides: Vec::new(),
            sdo: SdoConfig::default(),
        }
    }
}

/// Where a CN is in its boot-up, as the MN sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BootPhase {
    /// Not identified: invited by IdentRequest.
    Unidentified,
    /// Its identity does not match the CDC's; asked again later.
    IdentityMismatch,
    /// Identified; StatusRequests until it reports PRE_OPERATIONAL_2.
    Identified,
    /// The SDO client writes its configuration.
    Configuring,
    /// Configured: NMTResetConfiguration sent, waiting to identify it again.
    ResetConfiguration,
    /// Polled; NMT commands bring it to OPERATIONAL.
    Starting,
    /// OPERATIONAL.
    Operational,
}

impl fmt::Display for BootPhase {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            BootPhase::Unidentified => "unidentified",
            BootPhase::IdentityMismatch => "identity mismatch",
            BootPhase::Identified => "identified",
            BootPhase::Configuring => "configuring",
            BootPhase::ResetConfiguration => "reset configuration",
            BootPhase::Starting => "starting",
            BootPhase::Operational => "operational",
        })
    }
}

/// Something that happened to a CN.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum EventKind {
    /// The CN reported a new NMT state.
    State(NmtState),
    /// The MN's view of its boot-up changed.
    Phase(BootPhase),
    /// Identified (IdentResponse) with this identity.
    Identified {
        /// Vendor ID.
        vendor_id: u32,
        /// Product code.
        product_code: u32,
        /// Revision number.
        revision: u32,
        /// Serial number.
        serial: u32,
    },
    /// The identity differs from the CDC's expectation.
    IdentityMismatch(String),
    /// Configuration skipped: the CN's VerifyConfiguration date and time match the CDC.
    ConfigurationCurrent,
    /// One configuration write done (`done` of `total`).
    Configured {
        /// Object index.
        index: u16,
        /// Object subindex.
        subindex: u8,
        /// Writes done.
        done: usize,
        /// Writes in all.
        total: usize,
    },
    /// A configuration write failed.
    ConfigurationError {
        /// Object index.
        index: u16,
        /// Object subindex.
        subindex: u8,
        /// Why.
        error: String,
    },
    /// An NMT command was sent to the CN.
    Command(NmtCommandId),
    /// The CN left the state it was brought to, or stopped answering: booted again.
    Lost(String),
}

/// An event of one CN.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MnEvent {
    /// The cycle it happened in.
    pub cycle: u64,
    /// The CN.
    pub node: u8,
    /// What happened.
    pub kind: EventKind,
}

/// One mapped object of a PReq or PRes payload and its value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PdoValue {
    /// Object index (on the CN).
    pub index: u16,
    /// Object subindex.
    pub subindex: u8,
    /// Offset in bits from the start of the payload.
    pub bit_offset: u16,
    /// Length in bits (at most 64 are carried).
    pub bit_length: u16,
    /// The value (the last received for an input; `None` before the first PRes with RD).
    pub value: Option<u64>,
}

/// What the MN knows of one CN.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeReport {
    /// Node ID.
    pub node: u8,
    /// The CN's last reported NMT state.
    pub state: NmtState,
    /// Its boot-up phase.
    pub phase: BootPhase,
    /// The CN's MAC once identified.
    pub mac: Option<MacAddr>,
    /// Times it was booted (identified from scratch).
    pub boots: u64,
    /// Times it reached OPERATIONAL.
    pub operational_entries: u64,
    /// PRes received.
    pub pres_received: u64,
    /// PRes missed (not received within the PRes time-out).
    pub pres_missed: u64,
    /// PRes received after their time-out (also counted in `pres_received` and
    /// `pres_missed`).
    pub pres_late: u64,
    /// Configuration writes that failed, in all.
    pub config_errors: u64,
    /// Outputs (PReq payload, the CN's RPDO mapping).
    pub outputs: Vec<PdoValue>,
    /// Inputs (PRes payload, the CN's TPDO mapping).
    pub inputs: Vec<PdoValue>,
}

#[derive(Debug)]
struct Slot {
    node: u8,
    assignment: NodeAssignment,
    pres_timeout: Duration,
    expected_identity: [Option<u32>; 5],
    expected_conf: Option<(u32, u32)>,
    config: Vec<CdcEntry>,
    preq_limit: Option<usize>,
    outputs: Vec<PdoValue>,
    inputs: Vec<PdoValue>,
    mac: Option<MacAddr>,
    state: NmtState,
    phase: BootPhase,
    /// Set after the configuration: the next identification skips it.
    configured: bool,
    sdo: Option<SdoClient>,
    sdo_total: usize,
    sdo_done: usize,
    sdo_out: VecDeque<SdoFrame>,
    /// The CN has ASnd frames to send (RS in PRes/StatusResponse) or an answer is due.
    wants_invite: bool,
    error_signalling: bool,
    /// EA sent in the PReq: the EN last reported in a StatusResponse (the MN has read the
    /// CN's new errors).
    ea: bool,
    /// EN in the PRes differs from EA: a StatusRequest is due.
    status_due: bool,
    last_command: Option<(u64, NmtCommandId)>,
    /// Cycle of the last IdentRequest/StatusRequest/phase change (for retries).
    since: u64,
    missed_in_row: u32,
    boots: u64,
    operational_entries: u64,
    pres_received: u64,
    pres_missed: u64,
    pres_late: u64,
    config_errors: u64,
}

impl Slot {
    fn report(&self) -> NodeReport {
        NodeReport {
            node: self.node,
            state: self.state,
            phase: self.phase,
            mac: self.mac,
            boots: self.boots,
            operational_entries: self.operational_entries,
            pres_received: self.pres_received,
            pres_missed: self.pres_missed,
            pres_late: self.pres_late,
            config_errors: self.config_errors,
            outputs: self.outputs.clone(),
            inputs: self.inputs.clone(),
        }
    }

    fn polled(&self) -> bool {
        self.mac.is_some()
            && matches!(self.phase, BootPhase::Configuring | BootPhase::Starting | BootPhase::Operational)
            && !self.assignment.contains(NodeAssignment::ASYNC_ONLY)
    }

    fn preq_len(&self) -> usize {
        let len = payload_len(&self.outputs);
        self.preq_limit.map_or(len, |l| len.min(l))
    }
}

/// The bytes a mapping covers.
fn payload_len(values: &[PdoValue]) -> usize {
    let bits = values.iter().map(|v| u32::from(v.bit_offset) + u32::from(v.bit_length)).max().unwrap_or(0);
    usize::try_from(bits.div_ceil(8)).unwrap_or(0)
}

/// Reads `len` bits (at most 64) at `offset`, little-endian; `None` when the payload is short.
pub fn get_bits(payload: &[u8], offset: u16, len: u16) -> Option<u64> {
    let len = len.min(64);
    let mut v = 0u64;
    for i in 0..len {
        let bit = usize::from(offset) + usize::from(i);
        let byte = payload.get(bit / 8)?;
        if byte >> (bit % 8) & 1 == 1 {
            v |= 1 << i;
        }
    }
    Some(v)
}

/// Writes the low `len` bits (at most 64) of `value` at `offset`, little-endian; bits past the
/// payload's end are dropped.
pub fn set_bits(payload: &mut [u8], offset: u16, len: u16, value: u64) {
    for i in 0..len.min(64) {
        let bit = usize::from(offset) + usize::from(i);
        if let Some(byte) = payload.get_mut(bit / 8) {
            let mask = 1u8 << (bit % 8);
            if value >> i & 1 == 1 {
                *byte |= mask;
            } else {
                *byte &= !mask;
            }
        }
    }
}

/// The objects a node's configuration maps into one direction: the last value of each
/// 0x1600+k (or 0x1A00+k) entry, the first `subindex 0` entries of each channel whose
/// communication object's node ID (0x1400+k/1, 0x1800+k/1) is 0 (the PReq to the node, or its
/// own PRes).
fn mapped_objects(config: &[CdcEntry], mapping_base: u16, comm_base: u16) -> Vec<PdoValue> {
    let last = |index: u16, sub: u8| config.iter().rev().find(|e| e.index == index && e.subindex == sub);
    let mut out = Vec::new();
    for k in 0..=0xFFu16 {
        let map = mapping_base + k;
        let Some(count) = last(map, 0).and_then(CdcEntry::unsigned) else { continue };
        if last(comm_base + k, 1).and_then(CdcEntry::unsigned).is_some_and(|n| n != 0) {
            continue;
        }
        for sub in 1..=u8::try_from(count.min(254)).unwrap_or(0) {
            let Some(raw) = last(map, sub).and_then(CdcEntry::unsigned) else { continue };
            let e = MappingEntry::from_raw(raw);
            if e.bit_length == 0 {
                continue;
            }
            out.push(PdoValue {
                index: e.index,
                subindex: e.subindex,
                bit_offset: e.bit_offset,
                bit_length: e.bit_length,
                value: None,
            });
        }
    }
    out
}

/// The sans-IO Managing Node; see the module documentation.
#[derive(Debug)]
pub struct CdcMn {
    config: MnConfig,
    cycle: Duration,
    async_timeout: Duration,
    slots: Vec<Slot>,
    state: NmtState,
    cycle_index: u64,
    reduced_index: u64,
    full_cycles: u64,
    ident_rr: usize,
    status_rr: usize,
    invite_rr: usize,
    commands: VecDeque<(u8, NmtCommandId)>,
    events: VecDeque<MnEvent>,
    first_soc: Option<Instant>,
    net_epoch: Option<(Instant, Duration)>,
    /// The node whose ASnd the current async slot waits for.
    awaited: Option<u8>,
    /// The last async slot invited a CN.
    invited_last: bool,
}

/// Cycles after an NMTResetConfiguration before the CN is asked to identify itself again.
const RESET_SETTLE_CYCLES: u64 = 20;

/// Events kept at most (the oldest are dropped).
const MAX_EVENTS: usize = 4096;

impl CdcMn {
    /// An MN for the CNs the CDC assigns (0x1F81), with the CDC's cycle length (0x1006), PRes
    /// time-outs (0x1F92), async time-out (0x1F8A/2), payload limits (0x1F8B, or the CN's
    /// 0x1F98/4), expected identities and configuration dates, and each CN's configuration
    /// (0x1F22) and mappings.
    ///
    /// # Errors
    /// [`MnError`] when the CDC has no cycle length or no CN, or an override names a node the
    /// CDC does not assign.
    pub fn new(cdc: &Cdc, config: MnConfig) -> Result<Self, MnError> {
        let cycle_us = cdc.cycle_length().filter(|&c| c > 0).ok_or(MnError::NoCycleLength)?;
        let cycle = Duration::from_micros(u64::from(cycle_us));
        let nodes = cdc.assigned_nodes();
        if nodes.is_empty() {
            return Err(MnError::NoNodes);
        }
        if let Some(&(n, ..)) = config.overrides.iter().find(|o| !nodes.contains(&o.0)) {
            return Err(MnError::UnknownNode(n));
        }
        let u32_of = |index: u16, sub: u8| cdc.value(index, sub).and_then(CdcEntry::unsigned);
        let async_timeout =
            u32_of(MN_CYCLE_TIMING, 2).map_or(Duration::from_micros(500), Duration::from_nanos).min(cycle);
        let mut slots = Vec::new();
        for node in nodes {
            let node_config = cdc.node_config(node).unwrap_or_default();
            let pres_timeout = u32_of(PRES_TIMEOUT, node)
                .map_or(Duration::from_micros(200), Duration::from_nanos)
                .max(config.min_pres_timeout);
            let expected_identity =
                EXP_IDENTITY.map(|i| u32_of(i, node).and_then(|v| u32::try_from(v).ok()).filter(|&v| v != 0));
            let expected_conf = match (u32_of(EXP_CONF_DATE, node), u32_of(EXP_CONF_TIME, node)) {
                (Some(d), Some(t)) if d != 0 || t != 0 => {
                    Some((u32::try_from(d).unwrap_or(0), u32::try_from(t).unwrap_or(0)))
                }
                _ => None,
            };
            let preq_limit = u32_of(PREQ_PAYLOAD_LIMIT, node)
                .or_else(|| {
                    node_config
                        .iter()
                        .rev()
                        .find(|e| e.index == CYCLE_TIMING && e.subindex == 4)
                        .and_then(CdcEntry::unsigned)
                })
                .and_then(|v| usize::try_from(v).ok());
            let mut outputs = mapped_objects(&node_config, 0x1600, 0x1400);
            let inputs = mapped_objects(&node_config, 0x1A00, 0x1800);
            let mut config_entries = node_config;
            for &(n, index, subindex, value) in &config.overrides {
                if n != node {
                    continue;
                }
                match outputs.iter_mut().find(|o| o.index == index && o.subindex == subindex) {
                    Some(o) => o.value = Some(value),
                    None => {
                        // Not mapped: written by SDO (4 bytes, little-endian).
                        let data = u32::try_from(value)
                            .map_or_else(|_| value.to_le_bytes().to_vec(), |v| v.to_le_bytes().to_vec());
                        config_entries.push(CdcEntry { index, subindex, data });
                    }
                }
            }
            slots.push(Slot {
                node,
                assignment: cdc.node_assignment(node).unwrap_or_default(),
                pres_timeout,
                expected_identity,
                expected_conf,
                config: config_entries,
                preq_limit,
                outputs,
                inputs,
                mac: None,
                state: NmtState::NotActive,
                phase: BootPhase::Unidentified,
                configured: false,
                sdo: None,
                sdo_total: 0,
                sdo_done: 0,
                sdo_out: VecDeque::new(),
                wants_invite: false,
                error_signalling: false,
                ea: false,
                status_due: false,
                last_command: None,
                since: 0,
                missed_in_row: 0,
                boots: 0,
                operational_entries: 0,
                pres_received: 0,
                pres_missed: 0,
                pres_late: 0,
                config_errors: 0,
            });
        }
        tracing::info!(
            cycle_us,
            nodes = ?slots.iter().map(|s| s.node).collect::<Vec<_>>(),
            "MN configured from the CDC"
        );
        Ok(Self {
            config,
            cycle,
            async_timeout,
            slots,
            state: NmtState::PreOperational1,
            cycle_index: 0,
            reduced_index: 0,
            full_cycles: 0,
            ident_rr: 0,
            status_rr: 0,
            invite_rr: 0,
            commands: VecDeque::new(),
            events: VecDeque::new(),
            first_soc: None,
            net_epoch: None,
            awaited: None,
            invited_last: false,
        })
    }

    /// The cycle length (0x1006).
    pub fn cycle(&self) -> Duration {
        self.cycle
    }

    /// How long the async slot waits for an invited node's ASnd (0x1F8A/2, at most a cycle).
    pub fn async_timeout(&self) -> Duration {
        self.async_timeout
    }

    /// The MN's own NMT state.
    pub fn state(&self) -> NmtState {
        self.state
    }

    /// Cycles begun (reduced and full).
    pub fn cycles(&self) -> u64 {
        self.cycle_index
    }

    /// Every CN's state, counters and values.
    pub fn nodes(&self) -> Vec<NodeReport> {
        self.slots.iter().map(Slot::report).collect()
    }

    /// The next event, oldest first.
    pub fn pop_event(&mut self) -> Option<MnEvent> {
        self.events.pop_front()
    }

    /// Sets the value of an output object (`index`/`subindex` mapped in `node`'s PReq) from
    /// now on; `false` when it is not mapped.
    pub fn set_output(&mut self, node: u8, index: u16, subindex: u8, value: u64) -> bool {
        let Some(o) = self
            .slots
            .iter_mut()
            .find(|s| s.node == node)
            .and_then(|s| s.outputs.iter_mut().find(|o| o.index == index && o.subindex == subindex))
        else {
            return false;
        };
        o.value = Some(value);
        self.config.overrides.retain(|x| !(x.0 == node && x.1 == index && x.2 == subindex));
        self.config.overrides.push((node, index, subindex, value));
        true
    }

    fn event(&mut self, node: u8, kind: EventKind) {
        tracing::debug!(node, ?kind, "CN event");
        if self.events.len() >= MAX_EVENTS {
            self.events.pop_front();
        }
        self.events.push_back(MnEvent { cycle: self.cycle_index, node, kind });
    }

    fn set_phase(&mut self, i: usize, phase: BootPhase) {
        let cycle = self.cycle_index;
        let Some(s) = self.slots.get_mut(i) else { return };
        if s.phase == phase {
            return;
        }
        s.phase = phase;
        s.since = cycle;
        s.last_command = None;
        if phase == BootPhase::Operational {
            s.operational_entries += 1;
        }
        let node = s.node;
        tracing::info!(node, %phase, "CN boot phase");
        self.event(node, EventKind::Phase(phase));
    }

    fn frame(&self, dst_mac: MacAddr, dst_node: u8, message: Message) -> EplFrame {
        EplFrame::new(self.config.mac, dst_mac, dst_node, MN_NODE_ID, message)
    }

    fn soa(&self, service: RequestedService, target: u8) -> EplFrame {
        self.frame(MacAddr::SOA, BROADCAST_NODE_ID, Message::Soa(Soa::new(self.state, service, target)))
    }

    /// Begins a cycle at `now`: `true` for a full cycle (SoC, PReqs, SoA), `false` for a
    /// reduced PRE_OPERATIONAL_1 cycle (only [`CdcMn::async_slot`]).
    pub fn start_cycle(&mut self, now: Instant) -> bool {
        self.net_epoch.get_or_insert((
            now,
            std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default(),
        ));
        self.cycle_index += 1;
        self.awaited = None;
        if self.state == NmtState::PreOperational1 {
            let all = self.slots.iter().all(|s| s.mac.is_some());
            let past = self.reduced_index
                >= u64::from(self.config.preop1_start_cycles) + u64::from(self.config.preop1_cycles);
            if (all && self.reduced_index > u64::from(self.config.preop1_start_cycles)) || past {
                self.set_mn_state(NmtState::PreOperational2);
            } else {
                self.reduced_index += 1;
                return false;
            }
        }
        self.full_cycles += 1;
        true
    }

    fn set_mn_state(&mut self, s: NmtState) {
        tracing::info!(from = %self.state, to = %s, "MN state");
        self.state = s;
    }

    /// The SoC of a full cycle started at `now`.
    pub fn soc(&mut self, now: Instant) -> EplFrame {
        let first = *self.first_soc.get_or_insert(now);
        let wall = self
            .net_epoch
            .map_or(Duration::ZERO, |(start, wall)| wall + now.saturating_duration_since(start));
        let soc = Soc {
            flags: Flags::empty(),
            net_time: NetTime {
                seconds: u32::try_from(wall.as_secs()).unwrap_or(0),
                nanoseconds: wall.subsec_nanos(),
            },
            relative_time: u64::try_from(now.saturating_duration_since(first).as_micros())
                .unwrap_or(u64::MAX),
            reserved1: 0,
            reserved2: 0,
        };
        self.frame(MacAddr::SOC, BROADCAST_NODE_ID, Message::Soc(soc))
    }

    /// The CNs to poll by PReq this cycle, in order.
    pub fn poll_list(&self) -> Vec<u8> {
        self.slots.iter().filter(|s| s.polled()).map(|s| s.node).collect()
    }

    /// How long to wait for `node`'s PRes after its PReq (0x1F92/node).
    pub fn pres_timeout(&self, node: u8) -> Duration {
        self.slots.iter().find(|s| s.node == node).map_or(Duration::from_micros(200), |s| s.pres_timeout)
    }

    /// The PReq to `node` with the MN's outputs laid out by its RPDO mapping; `None` when the
    /// node is not polled.
    pub fn preq(&mut self, node: u8) -> Option<EplFrame> {
        let counter = self.full_cycles / self.config.counter_every.max(1);
        let rd = self.state == NmtState::Operational;
        let s = self.slots.iter_mut().find(|s| s.node == node && s.polled())?;
        let mac = s.mac?;
        let mut payload = vec![0u8; s.preq_len()];
        for o in &mut s.outputs {
            let value = *o.value.get_or_insert(0);
            let v =
                if self.config.overrides.iter().any(|x| x.0 == node && x.1 == o.index && x.2 == o.subindex) {
                    value
                } else {
                    counter
                };
            let v = if o.bit_length >= 64 { v } else { v & ((1u64 << o.bit_length) - 1) };
            o.value = Some(v);
            set_bits(&mut payload, o.bit_offset, o.bit_length, v);
        }
        let mut flags = if rd { Flags::RD } else { Flags::empty() };
        if s.ea {
            flags |= Flags::EA;
        }
        let preq = PReq { flags, payload, ..PReq::default() };
        Some(self.frame(mac, node, Message::PReq(preq)))
    }

    /// `node`'s PRes did not come in time.
    pub fn pres_missed(&mut self, node: u8) {
        let lost_after = self.config.lost_after.max(1);
        let Some(i) = self.slots.iter().position(|s| s.node == node) else { return };
        let missed = {
            let Some(s) = self.slots.get_mut(i) else { return };
            s.pres_missed += 1;
            s.missed_in_row += 1;
            s.missed_in_row
        };
        if missed >= lost_after {
            self.lose(i, format!("no PRes {missed} times in a row"));
        }
    }

    /// Boots node `i` again from the IdentRequest.
    fn lose(&mut self, i: usize, why: String) {
        let Some(s) = self.slots.get_mut(i) else { return };
        let node = s.node;
        tracing::warn!(node, %why, "CN lost: booting it again");
        s.mac = None;
        s.missed_in_row = 0;
        s.configured = false;
        s.sdo = None;
        s.sdo_out.clear();
        s.wants_invite = false;
        s.state = NmtState::NotActive;
        self.commands.retain(|c| c.0 != node);
        self.event(node, EventKind::Lost(why));
        self.set_phase(i, BootPhase::Unidentified);
    }

    /// Handles a received frame (any: PRes, IdentResponse, StatusResponse, SDO, others are
    /// ignored). Returns whether it is the answer the current slot waits for: a PRes of
    /// `expect_pres`, or an ASnd of the node invited in the async slot.
    pub fn on_frame(&mut self, now: Instant, frame: &EplFrame, expect_pres: Option<u8>) -> bool {
        let src = frame.src_node;
        let Some(i) = self.slots.iter().position(|s| s.node == src) else { return false };
        match &frame.message {
            Message::PRes(p) => {
                if let Some(s) = self.slots.get_mut(i) {
                    s.pres_received += 1;
                    s.missed_in_row = 0;
                    if expect_pres != Some(src) {
                        s.pres_late += 1;
                    }
                    if p.pr_rs.rs > 0 {
                        s.wants_invite = true;
                    }
                    if p.flags.contains(Flags::EN) != s.ea {
                        // New errors on the CN: read them with a StatusRequest.
                        s.status_due = true;
                    }
                    if p.flags.contains(Flags::RD) {
                        for v in &mut s.inputs {
                            if let Some(x) = get_bits(&p.payload, v.bit_offset, v.bit_length) {
                                v.value = Some(x);
                            }
                        }
                    }
                }
                self.observe_state(i, p.nmt_state);
                expect_pres == Some(src)
            }
            Message::Asnd(Asnd::IdentResponse(r)) => {
                self.on_ident(i, frame.ethernet.src, r);
                self.awaited == Some(src)
            }
            Message::Asnd(Asnd::StatusResponse(r)) => {
                if let Some(s) = self.slots.get_mut(i) {
                    if r.flags.contains(Flags::EC) {
                        s.error_signalling = true;
                    }
                    // Acknowledged by EA in the next PReqs.
                    s.ea = r.flags.contains(Flags::EN);
                    s.status_due = false;
                    if !r.entries.is_empty() {
                        tracing::info!(node = s.node, entries = ?r.entries, "CN error entries");
                    }
                    if r.pr_rs.rs > 0 {
                        s.wants_invite = true;
                    }
                }
                self.observe_state(i, r.nmt_state);
                self.awaited == Some(src)
            }
            Message::Asnd(Asnd::Sdo(sdo)) if frame.dst_node == MN_NODE_ID => {
                if let Some(s) = self.slots.get_mut(i) {
                    s.wants_invite = false;
                    if let Some(client) = s.sdo.as_mut() {
                        let answers = client.on_frame(now, sdo);
                        s.sdo_out.extend(answers);
                    }
                }
                self.collect_sdo(i, now);
                self.awaited == Some(src)
            }
            Message::Asnd(_) => self.awaited == Some(src),
            _ => false,
        }
    }

    fn on_ident(&mut self, i: usize, mac: MacAddr, r: &IdentResponse) {
        let Some(s) = self.slots.get_mut(i) else { return };
        let node = s.node;
        if !matches!(
            s.phase,
            BootPhase::Unidentified | BootPhase::ResetConfiguration | BootPhase::IdentityMismatch
        ) {
            s.mac = Some(mac);
            return;
        }
        let actual = [r.device_type, r.vendor_id, r.product_code, r.revision_number, r.serial_number];
        let names = ["device type", "vendor ID", "product code", "revision", "serial number"];
        let mismatch: Vec<String> = s
            .expected_identity
            .iter()
            .zip(actual)
            .zip(names)
            .filter_map(|((e, a), n)| e.filter(|&e| e != a).map(|e| format!("{n} {a:#x}, expected {e:#x}")))
            .collect();
        let identity = EventKind::Identified {
            vendor_id: r.vendor_id,
            product_code: r.product_code,
            revision: r.revision_number,
            serial: r.serial_number,
        };
        if !mismatch.is_empty() {
            let why = mismatch.join(", ");
            tracing::warn!(node, %why, "CN identity mismatch");
            self.event(node, EventKind::IdentityMismatch(why));
            self.set_phase(i, BootPhase::IdentityMismatch);
            // Asked again after MnConfig::retry_cycles from now.
            let cycle = self.cycle_index;
            if let Some(s) = self.slots.get_mut(i) {
                s.since = cycle;
            }
            return;
        }
        let Some(s) = self.slots.get_mut(i) else { return };
        let conf_current = s.expected_conf.is_some_and(|c| c == (r.verify_conf_date, r.verify_conf_time));
        if s.phase != BootPhase::ResetConfiguration {
            s.boots += 1;
            if !s.configured {
                s.configured = conf_current;
            }
        }
        s.mac = Some(mac);
        s.state = r.nmt_state;
        s.error_signalling = false;
        s.ea = false;
        s.status_due = false;
        let configured = s.configured;
        tracing::info!(node, %mac, vendor = r.vendor_id, product = r.product_code, "CN identified");
        self.event(node, identity);
        if configured && conf_current {
            self.event(node, EventKind::ConfigurationCurrent);
        }
        self.set_phase(i, BootPhase::Identified);
    }

    fn observe_state(&mut self, i: usize, state: NmtState) {
        let Some(s) = self.slots.get_mut(i) else { return };
        let node = s.node;
        let old = s.state;
        s.state = state;
        let phase = s.phase;
        if old != state {
            tracing::info!(node, from = %old, to = %state, "CN state");
            self.event(node, EventKind::State(state));
        }
        match (phase, state) {
            (
                BootPhase::Identified,
                NmtState::PreOperational2 | NmtState::ReadyToOperate | NmtState::Operational,
            ) => {
                let configured = self.slots.get(i).is_some_and(|s| s.configured);
                if configured {
                    self.set_phase(i, BootPhase::Starting);
                } else {
                    self.start_configuration(i);
                }
            }
            (BootPhase::Starting, NmtState::Operational) => self.set_phase(i, BootPhase::Operational),
            (BootPhase::Operational, s) if s != NmtState::Operational => {
                self.lose(i, format!("left OPERATIONAL for {s}"));
            }
            (BootPhase::Starting | BootPhase::Configuring, s)
                if !matches!(
                    s,
                    NmtState::PreOperational2 | NmtState::ReadyToOperate | NmtState::Operational
                ) =>
            {
                self.lose(i, format!("fell back to {s} while booting"));
            }
            _ => {}
        }
    }

    fn start_configuration(&mut self, i: usize) {
        let sdo_config = self.config.sdo.clone();
        let Some(s) = self.slots.get_mut(i) else { return };
        let mut client = SdoClient::new(sdo_config);
        let mut queued = 0;
        for e in &s.config {
            if client.write(e.index, e.subindex, e.data.clone()).is_ok() {
                queued += 1;
            }
        }
        s.sdo = Some(client);
        s.sdo_total = queued;
        s.sdo_done = 0;
        s.sdo_out.clear();
        let node = s.node;
        tracing::info!(node, writes = queued, "configuring CN by SDO");
        self.set_phase(i, BootPhase::Configuring);
    }

    /// Collects SDO outcomes and frames of node `i`; ends the configuration when done.
    fn collect_sdo(&mut self, i: usize, now: Instant) {
        let mut events = Vec::new();
        let mut done = false;
        {
            let Some(s) = self.slots.get_mut(i) else { return };
            let Some(client) = s.sdo.as_mut() else { return };
            while let Some(f) = client.poll(now) {
                s.sdo_out.push_back(f);
            }
            while let Some(o) = client.pop_outcome() {
                if o.kind != TransferKind::Write {
                    continue;
                }
                s.sdo_done += 1;
                match o.result {
                    Ok(_) => events.push(EventKind::Configured {
                        index: o.index,
                        subindex: o.subindex,
                        done: s.sdo_done,
                        total: s.sdo_total,
                    }),
                    Err(e) => {
                        s.config_errors += 1;
                        tracing::warn!(
                            node = s.node,
                            index = o.index,
                            subindex = o.subindex,
                            "configuration write failed: {e}"
                        );
                        events.push(EventKind::ConfigurationError {
                            index: o.index,
                            subindex: o.subindex,
                            error: e.to_string(),
                        });
                    }
                }
            }
            if client.is_idle() && s.sdo_out.is_empty() && s.phase == BootPhase::Configuring {
                done = true;
            }
        }
        let node = self.slots.get(i).map_or(0, |s| s.node);
        for e in events {
            self.event(node, e);
        }
        if done {
            if let Some(s) = self.slots.get_mut(i) {
                s.configured = true;
                if let Some(mut c) = s.sdo.take() {
                    c.close();
                    while let Some(f) = c.poll(now) {
                        s.sdo_out.push_back(f);
                    }
                }
            }
            self.commands.push_back((node, NmtCommandId::ResetConfiguration));
            self.set_phase(i, BootPhase::ResetConfiguration);
        }
    }

    /// The async slot at `now`: the SoA and the MN's own ASnd (NMT command or SDO), in order.
    /// The node whose ASnd is to be waited for, if any, is [`CdcMn::awaited`].
    pub fn async_slot(&mut self, now: Instant) -> Vec<EplFrame> {
        self.awaited = None;
        if self.state == NmtState::PreOperational1 {
            return self.reduced_slot();
        }
        for i in 0..self.slots.len() {
            self.collect_sdo(i, now);
        }
        // 1. An NMT command of the MN (SoA NMTRequestInvite to itself: frames 1415, 1416).
        if let Some((node, command)) = self.commands.pop_front() {
            let mut out = vec![self.soa(RequestedService::NmtRequestInvite, MN_NODE_ID)];
            let cmd = NmtCommand { command, data: Vec::new(), reserved: 0 };
            out.push(self.frame(MacAddr::ASND, node, Message::Asnd(Asnd::NmtCommand(cmd))));
            tracing::info!(node, %command, "NMT command");
            self.event(node, EventKind::Command(command));
            return out;
        }
        // 2. The MN's SDO frames (SoA UnspecifiedInvite to itself: 935, 936).
        let n = self.slots.len();
        for k in 0..n {
            let i = (self.invite_rr + k) % n;
            let Some(s) = self.slots.get_mut(i) else { continue };
            if let Some(f) = s.sdo_out.pop_front() {
                let node = s.node;
                // The CN answers in a later slot.
                s.wants_invite = true;
                self.invite_rr = (i + 1) % n;
                return vec![
                    self.soa(RequestedService::UnspecifiedInvite, MN_NODE_ID),
                    self.frame(MacAddr::ASND, node, Message::Asnd(Asnd::Sdo(f))),
                ];
            }
        }
        // 3. A CN with ASnd frames to send (SoA UnspecifiedInvite to it: 944, 945); after
        //    such an invitation, identification and status requests go first, so that a CN
        //    that always has something to send does not starve them.
        if !self.invited_last {
            if let Some(out) = self.invite_slot() {
                self.invited_last = true;
                return out;
            }
        }
        self.invited_last = false;
        // Identification and status requests take turns (absent CNs are always unidentified).
        let out = if self.full_cycles % 2 == 0 {
            self.ident_slot().or_else(|| self.status_slot())
        } else {
            self.status_slot().or_else(|| self.ident_slot())
        };
        if let Some(out) = out {
            return out;
        }
        if let Some(out) = self.invite_slot() {
            self.invited_last = true;
            return out;
        }
        vec![self.soa(RequestedService::NoService, 0)]
    }

    /// An UnspecifiedInvite to a CN that has ASnd frames to send.
    fn invite_slot(&mut self) -> Option<Vec<EplFrame>> {
        let n = self.slots.len();
        for k in 0..n {
            let i = (self.invite_rr + k) % n;
            let Some(s) = self.slots.get_mut(i) else { continue };
            if s.wants_invite && s.mac.is_some() {
                s.wants_invite = false;
                let node = s.node;
                self.invite_rr = (i + 1) % n;
                self.awaited = Some(node);
                return Some(vec![self.soa(RequestedService::UnspecifiedInvite, node)]);
            }
        }
        None
    }

    /// Identification of an unidentified CN (IdentRequest: 1434, 1450), or of one whose
    /// identity mismatched, after a while.
    fn ident_slot(&mut self) -> Option<Vec<EplFrame>> {
        let n = self.slots.len();
        let cycle = self.cycle_index;
        let retry = self.config.retry_cycles;
        for k in 1..=n {
            let i = (self.ident_rr + k) % n;
            let Some(s) = self.slots.get(i) else { continue };
            let due = match s.phase {
                BootPhase::Unidentified => true,
                BootPhase::ResetConfiguration => cycle >= s.since + RESET_SETTLE_CYCLES,
                BootPhase::IdentityMismatch => cycle >= s.since + retry,
                _ => false,
            };
            if due {
                let node = s.node;
                self.ident_rr = i;
                self.awaited = Some(node);
                return Some(vec![self.soa(RequestedService::IdentRequest, node)]);
            }
        }
        None
    }

    /// StatusRequests: error signalling (ER on the first: 881), a CN's state after its
    /// identification (902), and now and then in OPERATIONAL.
    fn status_slot(&mut self) -> Option<Vec<EplFrame>> {
        let n = self.slots.len();
        let every = self.config.status_every;
        let periodic = every > 0 && self.full_cycles % every == 0;
        for k in 1..=n {
            let i = (self.status_rr + k) % n;
            let Some(s) = self.slots.get(i) else { continue };
            let ask = s.mac.is_some()
                && (!s.error_signalling
                    || s.status_due
                    || s.phase == BootPhase::Identified
                    || (periodic && s.phase == BootPhase::Operational));
            if ask {
                let node = s.node;
                let er = !s.error_signalling;
                self.status_rr = i;
                self.awaited = Some(node);
                let mut soa = Soa::new(self.state, RequestedService::StatusRequest, node);
                if er {
                    soa.flags = Flags::ER;
                }
                return Some(vec![self.frame(MacAddr::SOA, BROADCAST_NODE_ID, Message::Soa(soa))]);
            }
        }
        None
    }

    fn reduced_slot(&mut self) -> Vec<EplFrame> {
        let i = self.reduced_index.saturating_sub(1);
        let start = u64::from(self.config.preop1_start_cycles);
        if i < start {
            return vec![self.soa(RequestedService::NoService, 0)];
        }
        if i == start {
            // Reset every CN (frames 11, 12).
            let cmd = NmtCommand { command: NmtCommandId::ResetNode, data: Vec::new(), reserved: 0 };
            return vec![
                self.soa(RequestedService::NmtRequestInvite, MN_NODE_ID),
                self.frame(MacAddr::ASND, BROADCAST_NODE_ID, Message::Asnd(Asnd::NmtCommand(cmd))),
            ];
        }
        let unidentified: Vec<u8> = self.slots.iter().filter(|s| s.mac.is_none()).map(|s| s.node).collect();
        let k = usize::try_from(i).unwrap_or(0) % unidentified.len().max(1);
        match unidentified.get(k) {
            Some(&node) => {
                self.awaited = Some(node);
                vec![self.soa(RequestedService::IdentRequest, node)]
            }
            None => vec![self.soa(RequestedService::NoService, 0)],
        }
    }

    /// The node whose ASnd the current async slot waits for (after [`CdcMn::async_slot`]).
    pub fn awaited(&self) -> Option<u8> {
        self.awaited
    }

    /// Ends the cycle: the MN's own state and the CNs' NMT commands for the next cycles.
    pub fn end_cycle(&mut self, now: Instant) {
        match self.state {
            NmtState::PreOperational2 if self.full_cycles >= 10 => {
                self.set_mn_state(NmtState::ReadyToOperate)
            }
            NmtState::ReadyToOperate if self.full_cycles >= 20 => self.set_mn_state(NmtState::Operational),
            _ => {}
        }
        for i in 0..self.slots.len() {
            self.collect_sdo(i, now);
        }
        let cycle = self.cycle_index;
        let retry = self.config.retry_cycles;
        let mut queue = Vec::new();
        for s in &mut self.slots {
            if s.phase != BootPhase::Starting {
                continue;
            }
            let command = match s.state {
                NmtState::PreOperational2 => NmtCommandId::EnableReadyToOperate,
                NmtState::ReadyToOperate if s.assignment.contains(NodeAssignment::START_CN) => {
                    NmtCommandId::StartNode
                }
                _ => continue,
            };
            let due = s.last_command.map_or(true, |(c, last)| last != command || cycle >= c + retry);
            if due && !self.commands.iter().any(|c| c.0 == s.node) {
                s.last_command = Some((cycle, command));
                queue.push((s.node, command));
            }
        }
        self.commands.extend(queue);
    }
}

#[cfg(test)]
mod tests;
