//! The sans-IO Controlled Node: [`ControlledNode`] (see the module documentation of
//! [`super`]).

use std::collections::VecDeque;
use std::net::Ipv4Addr;
use std::time::{Duration, Instant};

use motus_epl_protocol::od::{RPDO_COMM_BASE, TPDO_COMM_BASE};
use motus_epl_protocol::{
    Asnd, EplFrame, FixedText, Flags, IdentResponse, MacAddr, Message, NmtCommandId, NmtState,
    ObjectDictionary, PReq, PRes, PrRs, RequestedService, SdoConfig, SdoFrame, SdoServer, Soa, StatusEntry,
    StatusResponse, BROADCAST_NODE_ID, ETHERTYPE_EPL, MN_NODE_ID,
};

/// Frames waiting for the async slot at most (SDO answers and retransmissions); the SDO
/// window keeps the queue far below it. A frame that would overflow it is dropped and
/// counted ([`CnCounters::async_dropped`]).
pub const MAX_ASYNC_QUEUE: usize = 32;
/// Error/event entries a StatusResponse carries at most (13 x 20 bytes fit the 300-byte
/// minimum async MTU).
pub const MAX_STATUS_ENTRIES: usize = 13;
/// PR of a pending generic async frame (SDO): 3, as the openPOWERLINK CN announces it
/// (`oplk_mn_cn_veth_merged.pcapng` frame 882: RS=1, PR=3).
pub const PR_GENERIC: u8 = 3;
/// PRes sent with frames waiting (RS > 0) and no invitation, after which the next PRes
/// announces none (RS 0) once and the real count again after it.
///
/// openPOWERLINK's MN (V2.7.2, `dllkcal_setAsyncPendingRequests`) queues an invitation only
/// when a node's RS rises above the count it keeps for the node, and sets its count to RS
/// otherwise. Its count can stay at 1 with no invitation queued: the MN then never invites
/// the node while RS stays 1. Seen on veth at 50 ms: an SDO answer announced for 97 cycles
/// (4.9 s), sent only after the MN's own SDO time-out and retransmission; each such stall
/// cost 5 s of the boot, and one boot took 59 s. A PRes with RS 0 resets the MN's count, and
/// the next one queues a fresh invitation.
pub const REANNOUNCE_AFTER: u32 = 8;

/// NMT_CycleLen_U32 (µs).
const CYCLE_LEN: u16 = 0x1006;
/// DLL_CNLossSoC_REC (cumulative count, threshold count, threshold).
const LOSS_SOC: u16 = 0x1C0B;
/// DLL_CNLossPReq_REC.
const LOSS_PREQ: u16 = 0x1C0D;
/// DLL_CNLossOfSocTolerance_U32 (ns).
const LOSS_SOC_TOLERANCE: u16 = 0x1C14;
/// NMT_CurrNMTState_U8.
const CURRENT_STATE: u16 = 0x1F8C;
/// NMT_CycleTiming_REC.
const CYCLE_TIMING: u16 = 0x1F98;
/// NMT_CNBasicEthernetTimeout_U32 (µs).
const BASIC_ETHERNET_TIMEOUT: u16 = 0x1F99;
/// NMT_ResetCmd_U8: an SDO write of a reset command ID resets the node.
const RESET_CMD: u16 = 0x1F9E;
/// A threshold counter grows by this much per error and shrinks by one per cycle without
/// (EPSG DS 301's DLL error counters).
const THRESHOLD_STEP: u32 = 8;

/// Errors of [`ControlledNode::new`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CnError {
    /// A CN's node ID is 1..=239.
    #[error("node ID {0} is not a Controlled Node's (1..=239)")]
    InvalidNodeId(u8),
}

/// Why the NMT state changed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StateCause {
    /// Power-on or a reset command running through the GS_ reset states.
    Reset,
    /// A SoA was received (NOT_ACTIVE or BASIC_ETHERNET -> PRE_OPERATIONAL_1).
    Soa,
    /// A SoC was received (-> PRE_OPERATIONAL_1 / PRE_OPERATIONAL_2).
    Soc,
    /// An NMT state command from the MN.
    Command(NmtCommandId),
    /// The loss-of-SoC or loss-of-PReq threshold was reached (-> PRE_OPERATIONAL_1).
    CycleError,
    /// No POWERLINK frame within NMT_CNBasicEthernetTimeout_U32 (-> BASIC_ETHERNET).
    BasicEthernetTimeout,
    /// A POWERLINK frame in BASIC_ETHERNET (-> PRE_OPERATIONAL_1).
    PowerlinkFrame,
}

/// Something the node did or saw that its user may want to know (log, print).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CnEvent {
    /// The NMT state changed.
    State {
        /// The previous state.
        from: NmtState,
        /// The new state.
        to: NmtState,
        /// Why.
        cause: StateCause,
    },
    /// An NMT command addressed to this node (or broadcast, or an "Ex" command naming it).
    NmtCommand(NmtCommandId),
    /// An SDO client (the MN) wrote an entry of the dictionary.
    SdoWrite {
        /// Index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// The value written (little-endian bytes).
        value: Vec<u8>,
    },
    /// A SoC did not come within the cycle length plus the loss-of-SoC tolerance (0x1C14).
    LossOfSoc,
    /// A cycle in READY_TO_OPERATE or OPERATIONAL passed without a PReq for this node.
    LossOfPReq,
}

/// Counters of a [`ControlledNode`] since it was made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CnCounters {
    /// SoC received.
    pub soc: u64,
    /// PReq for this node received in a state that answers them.
    pub preq: u64,
    /// PReq whose payload was applied to the RPDO-mapped objects.
    pub preq_applied: u64,
    /// SoA received.
    pub soa: u64,
    /// IdentResponse sent.
    pub ident_responses: u64,
    /// StatusResponse sent.
    pub status_responses: u64,
    /// SDO frames received from the MN.
    pub sdo_received: u64,
    /// Frames sent in the async slot after an UnspecifiedInvite (SDO).
    pub async_sent: u64,
    /// Async frames dropped because the queue was full.
    pub async_dropped: u64,
    /// Frames that did not decode as POWERLINK.
    pub decode_errors: u64,
    /// Losses of SoC.
    pub loss_of_soc: u64,
    /// Losses of PReq.
    pub loss_of_preq: u64,
    /// Cycle errors (a loss threshold reached: back to PRE_OPERATIONAL_1).
    pub cycle_errors: u64,
}

/// A standards-based POWERLINK Controlled Node, sans-IO (see the module documentation).
#[derive(Debug)]
pub struct ControlledNode {
    node: u8,
    mac: MacAddr,
    od: ObjectDictionary,
    state: NmtState,
    sdo: SdoServer,
    async_queue: VecDeque<Vec<u8>>,
    events: Vec<CnEvent>,
    counters: CnCounters,
    /// Exception clear: set by a SoA with ER for this node, cleared once reported to a
    /// StatusRequest without ER.
    ec: bool,
    /// Exception new (toggled when an error entry is posted and the last one was
    /// acknowledged).
    en: bool,
    /// EA of the last PReq (the MN's acknowledgement of EN).
    ea: bool,
    entries: VecDeque<StatusEntry>,
    /// When the node entered NOT_ACTIVE (or last saw a POWERLINK frame there).
    quiet_since: Instant,
    /// The next SoC is late after this (loss-of-SoC monitoring).
    soc_deadline: Option<Instant>,
    /// A SoC opened a cycle in READY_TO_OPERATE/OPERATIONAL (PReq loss monitoring).
    cycle_open: bool,
    preq_in_cycle: bool,
    /// PRes sent with frames waiting and no invitation since ([`REANNOUNCE_AFTER`]).
    uninvited_pres: u32,
    /// The next PRes announces no frames waiting (RS 0), once.
    reannounce: bool,
    /// An NMT reset asked through 0x1F9E, run once its SDO answer has left.
    pending_reset: Option<NmtCommandId>,
    /// The cycle length (0x1006) and loss-of-SoC tolerance (0x1C14) in effect: read at every
    /// reset (GS_RESET_CONFIGURATION), as the configuration takes effect then.
    cycle: Duration,
    tolerance: Duration,
    /// How long a reset takes ([`ControlledNode::set_reset_time`]).
    reset_time: Duration,
    /// A reset in progress ends then (the node ignores every frame until).
    resetting_until: Option<Instant>,
    /// The PRes frame, ready to send.
    pres: Vec<u8>,
    pres_dirty: bool,
}

/// Whether `cmd` is one of the four reset commands.
fn is_reset(cmd: NmtCommandId) -> bool {
    matches!(
        cmd,
        NmtCommandId::ResetNode
            | NmtCommandId::ResetCommunication
            | NmtCommandId::ResetConfiguration
            | NmtCommandId::SwReset
    )
}

/// Whether the node answers PReq in `state`.
fn answers_preq(state: NmtState) -> bool {
    matches!(state, NmtState::PreOperational2 | NmtState::ReadyToOperate | NmtState::Operational)
}

/// Whether the node watches the SoC in `state`: from READY_TO_OPERATE on, once the cycle
/// configuration has taken effect (in PRE_OPERATIONAL_2 the MN is still writing the cycle
/// length; the openPOWERLINK CN stays there for seconds with a 50 ms cycle and its default
/// 1 ms cycle length: `oplk_mn_cn_veth_merged.pcapng` frames 867-1416).
fn watches_soc(state: NmtState) -> bool {
    matches!(state, NmtState::ReadyToOperate | NmtState::Operational | NmtState::Stopped)
}

impl ControlledNode {
    /// A node with ID `node` (1..=239) sending from `mac`, with the dictionary `od` (usually
    /// [`ObjectDictionary::controlled_node`]), powered on at `now`: it runs through
    /// GS_INITIALISING and the reset states to NOT_ACTIVE (the events record it) and waits
    /// for the MN's SoA or SoC. The SDO server uses [`SdoConfig::default`].
    ///
    /// # Errors
    /// [`CnError::InvalidNodeId`].
    pub fn new(node: u8, mac: MacAddr, od: ObjectDictionary, now: Instant) -> Result<Self, CnError> {
        Self::with_sdo_config(node, mac, od, SdoConfig::default(), now)
    }

    /// [`ControlledNode::new`] with the SDO server's time-outs and limits.
    ///
    /// # Errors
    /// [`CnError::InvalidNodeId`].
    pub fn with_sdo_config(
        node: u8,
        mac: MacAddr,
        od: ObjectDictionary,
        sdo: SdoConfig,
        now: Instant,
    ) -> Result<Self, CnError> {
        if !(1..=239).contains(&node) {
            return Err(CnError::InvalidNodeId(node));
        }
        let mut cn = Self {
            node,
            mac,
            od,
            state: NmtState::Initialising,
            sdo: SdoServer::new(sdo),
            async_queue: VecDeque::new(),
            events: Vec::new(),
            counters: CnCounters::default(),
            ec: false,
            en: false,
            ea: false,
            entries: VecDeque::new(),
            quiet_since: now,
            soc_deadline: None,
            cycle_open: false,
            preq_in_cycle: false,
            uninvited_pres: 0,
            reannounce: false,
            pending_reset: None,
            cycle: Duration::from_millis(1),
            tolerance: Duration::ZERO,
            reset_time: Duration::ZERO,
            resetting_until: None,
            pres: Vec::new(),
            pres_dirty: true,
        };
        let _ = cn.od.set_u8(CURRENT_STATE, 0, NmtState::Initialising.raw());
        cn.reset(now, NmtCommandId::SwReset, StateCause::Reset);
        cn.rebuild_pres();
        Ok(cn)
    }

    /// How long the node takes from an NMT reset command to NOT_ACTIVE (default zero:
    /// at once). It stays in GS_RESET_CONFIGURATION meanwhile and ignores every frame, as a
    /// device that restarts does (the openPOWERLINK CN takes 0.5-0.8 s:
    /// `oplk_mn_cn_veth_merged.pcapng`, NMTResetNode in frame 12, first IdentResponse in 866;
    /// NMTResetConfiguration in 1416, IdentResponse in 1451). The openPOWERLINK MN at a 1 ms
    /// cycle fails (critical error "transmit buffer for asynchronous frames is full",
    /// NMT_GS_OFF) when it configures a CN by SDO during its reduced PRE_OPERATIONAL_1 cycle,
    /// which it does when the CN answers its first IdentRequests right after the reset.
    pub fn set_reset_time(&mut self, reset_time: Duration) {
        self.reset_time = reset_time;
    }

    /// The node ID.
    pub fn node_id(&self) -> u8 {
        self.node
    }

    /// The MAC address the node's frames carry.
    pub fn mac(&self) -> MacAddr {
        self.mac
    }

    /// The current NMT state.
    pub fn state(&self) -> NmtState {
        self.state
    }

    /// The object dictionary.
    pub fn od(&self) -> &ObjectDictionary {
        &self.od
    }

    /// The object dictionary, to change inputs or parameters as the device itself does
    /// ([`ObjectDictionary::set`]); the PRes is prepared again before it is next sent.
    pub fn od_mut(&mut self) -> &mut ObjectDictionary {
        self.pres_dirty = true;
        &mut self.od
    }

    /// The counters.
    pub fn counters(&self) -> CnCounters {
        self.counters
    }

    /// Frames waiting for the async slot (the RS field).
    pub fn async_pending(&self) -> usize {
        self.async_queue.len()
    }

    /// The events since the last call, oldest first.
    pub fn take_events(&mut self) -> Vec<CnEvent> {
        std::mem::take(&mut self.events)
    }

    /// Posts an error/event entry for the MN: it goes into every StatusResponse (the
    /// [`MAX_STATUS_ENTRIES`] latest) and EN toggles in the PRes and StatusResponse when the
    /// MN has acknowledged (EA) the previous one.
    pub fn post_error(&mut self, entry: StatusEntry) {
        if self.entries.len() >= MAX_STATUS_ENTRIES {
            self.entries.pop_front();
        }
        self.entries.push_back(entry);
        if self.en == self.ea {
            self.en = !self.en;
        }
        self.pres_dirty = true;
    }

    /// Whether `raw` is a PReq from the MN for this node (checked on the raw bytes:
    /// EtherType 0x88AB without VLAN tag, message type PReq, destination this node, source
    /// the MN), whatever the node's state.
    pub fn is_preq_for_me(&self, raw: &[u8]) -> bool {
        let ethertype = ETHERTYPE_EPL.to_be_bytes();
        raw.get(12..14) == Some(&ethertype[..])
            && raw.get(14).map(|t| t & 0x7F) == Some(0x03)
            && raw.get(15) == Some(&self.node)
            && raw.get(16) == Some(&MN_NODE_ID)
    }

    /// The PRes to send at once if `raw` is a PReq for this node that it answers in its
    /// state (checked on the raw bytes: EtherType 0x88AB without VLAN tag, message type
    /// PReq, destination this node, source the MN), else `None`. The MS flag of the PReq is
    /// copied. Call [`ControlledNode::on_answered_preq`] with the PReq after sending it.
    pub fn pres_for(&mut self, raw: &[u8]) -> Option<&[u8]> {
        if !self.is_preq_for_me(raw) || !answers_preq(self.state) {
            return None;
        }
        if self.pres_dirty {
            self.rebuild_pres();
        }
        let ms = raw.get(18).is_some_and(|f| f & Flags::MS.bits() != 0);
        if let Some(flags) = self.pres.get_mut(18) {
            if ms {
                *flags |= Flags::MS.bits();
            } else {
                *flags &= !Flags::MS.bits();
            }
        }
        Some(&self.pres)
    }

    /// Handles a received frame at `now` and returns the frames to send, in order (a PRes
    /// for a PReq, an IdentResponse / StatusResponse / queued SDO frame for a SoA inviting
    /// this node). Frames that do not decode are counted and ignored.
    pub fn on_frame(&mut self, now: Instant, raw: &[u8]) -> Vec<Vec<u8>> {
        self.handle(now, raw, false)
    }

    /// [`ControlledNode::on_frame`] for a PReq already answered with
    /// [`ControlledNode::pres_for`]: everything but sending the PRes again.
    pub fn on_answered_preq(&mut self, now: Instant, raw: &[u8]) -> Vec<Vec<u8>> {
        self.handle(now, raw, true)
    }

    /// Handles time: SDO retransmissions and time-outs (queued for the async slot), loss of
    /// SoC, the BASIC_ETHERNET time-out. A CN sends only when the MN asks, so nothing is
    /// returned; call it at [`ControlledNode::next_deadline`] at the latest.
    pub fn poll(&mut self, now: Instant) {
        self.finish_reset(now);
        while let Some(frame) = self.sdo.poll(now) {
            self.queue_sdo(&frame);
        }
        if self.state == NmtState::NotActive {
            if let Some(t) = self.basic_ethernet_deadline() {
                if now >= t {
                    self.set_state(NmtState::BasicEthernet, StateCause::BasicEthernetTimeout);
                }
            }
        }
        while let Some(deadline) = self.soc_deadline {
            if now <= deadline || !watches_soc(self.state) {
                break;
            }
            self.counters.loss_of_soc += 1;
            self.events.push(CnEvent::LossOfSoc);
            tracing::debug!(node = self.node, "loss of SoC");
            self.soc_deadline = Some(deadline + self.cycle_len());
            if self.record_error(LOSS_SOC) {
                self.cycle_error();
            }
        }
        self.run_pending_reset(now);
        if self.pres_dirty {
            self.rebuild_pres();
        }
    }

    /// When [`ControlledNode::poll`] next has work, if ever.
    pub fn next_deadline(&self) -> Option<Instant> {
        let basic = if self.state == NmtState::NotActive { self.basic_ethernet_deadline() } else { None };
        let soc = self.soc_deadline.filter(|_| watches_soc(self.state)).map(|t| t + Duration::from_nanos(1));
        [self.sdo.next_deadline(), basic, soc, self.resetting_until].into_iter().flatten().min()
    }

    fn basic_ethernet_deadline(&self) -> Option<Instant> {
        let us = self.od.u32(BASIC_ETHERNET_TIMEOUT, 0).unwrap_or(0);
        (us > 0).then(|| self.quiet_since + Duration::from_micros(u64::from(us)))
    }

    /// The cycle length in effect (0x1006 at the last reset, at least 1 µs).
    pub fn cycle_len(&self) -> Duration {
        self.cycle
    }

    /// The cycle configuration takes effect (GS_RESET_CONFIGURATION).
    fn apply_cycle_configuration(&mut self) {
        self.cycle = Duration::from_micros(u64::from(self.od.u32(CYCLE_LEN, 0).unwrap_or(0).max(1)));
        self.tolerance = Duration::from_nanos(u64::from(self.od.u32(LOSS_SOC_TOLERANCE, 0).unwrap_or(0)));
    }

    /// Ends a reset in progress when its time has come.
    fn finish_reset(&mut self, now: Instant) {
        if self.resetting_until.is_some_and(|t| now >= t) {
            self.resetting_until = None;
            self.quiet_since = now;
            self.set_state(NmtState::NotActive, StateCause::Reset);
        }
    }

    fn handle(&mut self, now: Instant, raw: &[u8], answered: bool) -> Vec<Vec<u8>> {
        self.finish_reset(now);
        if self.resetting_until.is_some() {
            return Vec::new();
        }
        let frame = match EplFrame::decode(raw) {
            Ok(f) => f,
            Err(e) => {
                self.counters.decode_errors += 1;
                tracing::trace!(node = self.node, "undecodable frame: {e}");
                return Vec::new();
            }
        };
        let mut out = Vec::new();
        if frame.src_node == MN_NODE_ID {
            self.quiet_since = now;
            if self.state == NmtState::BasicEthernet {
                self.set_state(NmtState::PreOperational1, StateCause::PowerlinkFrame);
            }
        }
        match &frame.message {
            Message::Soc(_) if frame.src_node == MN_NODE_ID => self.on_soc(now),
            Message::PReq(p) if frame.dst_node == self.node && frame.src_node == MN_NODE_ID => {
                self.on_preq(p, answered, &mut out);
            }
            Message::Soa(s) if frame.src_node == MN_NODE_ID => self.on_soa(s, &mut out),
            Message::Asnd(a) if frame.dst_node == self.node || frame.dst_node == BROADCAST_NODE_ID => {
                self.on_asnd(now, frame.src_node, a);
            }
            _ => {}
        }
        self.run_pending_reset(now);
        if self.pres_dirty {
            self.rebuild_pres();
        }
        out
    }

    fn on_soc(&mut self, now: Instant) {
        self.counters.soc += 1;
        match self.state {
            NmtState::NotActive => self.set_state(NmtState::PreOperational1, StateCause::Soc),
            NmtState::PreOperational1 => self.set_state(NmtState::PreOperational2, StateCause::Soc),
            _ => {}
        }
        if !watches_soc(self.state) {
            return;
        }
        // Loss of PReq: the cycle this SoC closes had no PReq (multiplexed CNs are not
        // polled every cycle: not checked for them).
        let multiplexed = self.od.u8(CYCLE_TIMING, 7).unwrap_or(0) != 0;
        let polled_state = matches!(self.state, NmtState::ReadyToOperate | NmtState::Operational);
        let mut error = false;
        if self.cycle_open && polled_state && !multiplexed {
            if self.preq_in_cycle {
                self.decay(LOSS_PREQ);
            } else {
                self.counters.loss_of_preq += 1;
                self.events.push(CnEvent::LossOfPReq);
                error |= self.record_error(LOSS_PREQ);
            }
        }
        self.cycle_open = polled_state;
        self.preq_in_cycle = false;
        self.decay(LOSS_SOC);
        self.soc_deadline = Some(now + self.cycle + self.tolerance);
        if error {
            self.cycle_error();
        }
    }

    fn on_preq(&mut self, p: &PReq, answered: bool, out: &mut Vec<Vec<u8>>) {
        if !answers_preq(self.state) {
            return;
        }
        self.counters.preq += 1;
        self.preq_in_cycle = true;
        if !answered {
            if self.pres_dirty {
                self.rebuild_pres();
            }
            let mut pres = self.pres.clone();
            if let Some(flags) = pres.get_mut(18) {
                if p.flags.contains(Flags::MS) {
                    *flags |= Flags::MS.bits();
                } else {
                    *flags &= !Flags::MS.bits();
                }
            }
            out.push(pres);
        }
        self.count_uninvited_pres();
        let ea = p.flags.contains(Flags::EA);
        if ea != self.ea {
            self.ea = ea;
        }
        let expected_version = self.od.u8(RPDO_COMM_BASE, 2).unwrap_or(0);
        let usable = self.state == NmtState::Operational
            && p.flags.contains(Flags::RD)
            && p.pdo_version >> 4 == expected_version >> 4;
        if usable {
            match self.od.apply_preq_payload(&p.payload) {
                Ok(n) if n > 0 => self.counters.preq_applied += 1,
                Ok(_) => {}
                Err(e) => tracing::debug!(node = self.node, "PReq payload not applied: {e}"),
            }
        }
    }

    fn on_soa(&mut self, s: &Soa, out: &mut Vec<Vec<u8>>) {
        self.counters.soa += 1;
        if matches!(self.state, NmtState::NotActive | NmtState::BasicEthernet) {
            self.set_state(NmtState::PreOperational1, StateCause::Soa);
        }
        if s.target != self.node {
            return;
        }
        let er = s.flags.contains(Flags::ER);
        if er {
            // Exception reset: the MN (re)starts error signalling; acknowledge with EC.
            self.ec = true;
            self.en = false;
            self.ea = false;
            self.entries.clear();
        }
        match s.requested_service {
            RequestedService::IdentRequest => {
                if let Some(f) = self.asnd(BROADCAST_NODE_ID, Asnd::IdentResponse(self.ident_response())) {
                    self.counters.ident_responses += 1;
                    out.push(f);
                }
            }
            RequestedService::StatusRequest => {
                if let Some(f) = self.asnd(BROADCAST_NODE_ID, Asnd::StatusResponse(self.status_response())) {
                    self.counters.status_responses += 1;
                    out.push(f);
                }
                if !er {
                    // The MN has seen EC and stopped asking for the reset.
                    self.ec = false;
                }
            }
            RequestedService::UnspecifiedInvite => {
                self.uninvited_pres = 0;
                if self.reannounce {
                    self.reannounce = false;
                    self.pres_dirty = true;
                }
                if let Some(f) = self.async_queue.pop_front() {
                    self.counters.async_sent += 1;
                    self.pres_dirty = true;
                    out.push(f);
                }
            }
            _ => {}
        }
    }

    fn on_asnd(&mut self, now: Instant, src: u8, a: &Asnd) {
        if src != MN_NODE_ID {
            return;
        }
        match a {
            Asnd::NmtCommand(c) => self.on_nmt_command(now, c.command, &c.data),
            Asnd::Sdo(f) => {
                if matches!(self.state, NmtState::NotActive | NmtState::BasicEthernet) {
                    return;
                }
                self.counters.sdo_received += 1;
                let replies = self.sdo.on_frame(now, f, &mut self.od);
                for r in &replies {
                    self.queue_sdo(r);
                }
                self.take_remote_writes();
            }
            _ => {}
        }
    }

    /// Runs an NMT command from the MN (broadcast or to this node; "Ex" commands when the
    /// node list in their data names this node).
    fn on_nmt_command(&mut self, now: Instant, command: NmtCommandId, data: &[u8]) {
        let raw = command.raw();
        let command = if (0x41..=0x4B).contains(&raw) {
            let named = data.get(usize::from(self.node / 8)).is_some_and(|b| b & (1 << (self.node % 8)) != 0);
            if !named {
                return;
            }
            NmtCommandId::from_raw(raw - 0x20)
        } else {
            command
        };
        self.events.push(CnEvent::NmtCommand(command));
        tracing::debug!(node = self.node, %command, state = %self.state, "NMT command");
        let cause = StateCause::Command(command);
        match command {
            NmtCommandId::StartNode if self.state == NmtState::ReadyToOperate => {
                self.set_state(NmtState::Operational, cause);
            }
            NmtCommandId::StopNode
                if matches!(
                    self.state,
                    NmtState::PreOperational2 | NmtState::ReadyToOperate | NmtState::Operational
                ) =>
            {
                self.set_state(NmtState::Stopped, cause);
            }
            NmtCommandId::EnterPreOperational2
                if matches!(
                    self.state,
                    NmtState::ReadyToOperate | NmtState::Operational | NmtState::Stopped
                ) =>
            {
                self.set_state(NmtState::PreOperational2, cause);
            }
            NmtCommandId::EnableReadyToOperate if self.state == NmtState::PreOperational2 => {
                self.set_state(NmtState::ReadyToOperate, cause);
            }
            c if is_reset(c) => self.reset(now, c, cause),
            _ => {}
        }
    }

    /// Reports the entries an SDO client wrote and acts on 0x1F9E (NMT_ResetCmd_U8).
    fn take_remote_writes(&mut self) {
        let writes = self.od.take_remote_writes();
        if writes.is_empty() {
            return;
        }
        self.pres_dirty = true;
        for (index, subindex) in writes {
            let value = self.od.value(index, subindex).unwrap_or_default().to_vec();
            tracing::debug!(node = self.node, "SDO write {index:#06x}/{subindex} = {value:02x?}");
            if index == RESET_CMD && subindex == 0 {
                let cmd = value.first().map(|&b| NmtCommandId::from_raw(b));
                if let Some(cmd) = cmd.filter(|c| is_reset(*c)) {
                    self.pending_reset = Some(cmd);
                }
            }
            self.events.push(CnEvent::SdoWrite { index, subindex, value });
        }
    }

    /// A reset asked through 0x1F9E runs once the SDO answer has been sent.
    fn run_pending_reset(&mut self, now: Instant) {
        if self.async_queue.is_empty() {
            if let Some(cmd) = self.pending_reset.take() {
                self.events.push(CnEvent::NmtCommand(cmd));
                self.reset(now, cmd, StateCause::Command(cmd));
            }
        }
    }

    /// Runs through the reset states of `kind` to NOT_ACTIVE: SwReset from GS_INITIALISING,
    /// ResetNode from GS_RESET_APPLICATION (every object back to its default),
    /// ResetCommunication (the communication profile 0x1000-0x1FFF back to its defaults,
    /// the SDO connection, async queue and error signalling dropped), ResetConfiguration
    /// (the configuration written so far takes effect; values are kept, as is the SDO
    /// connection, which the MN closes itself: `oplk_mn_cn_veth_merged.pcapng` frames
    /// 1416-1426).
    fn reset(&mut self, now: Instant, kind: NmtCommandId, cause: StateCause) {
        let chain: &[NmtState] = match kind {
            NmtCommandId::SwReset => &[
                NmtState::Initialising,
                NmtState::ResetApplication,
                NmtState::ResetCommunication,
                NmtState::ResetConfiguration,
            ],
            NmtCommandId::ResetNode => {
                &[NmtState::ResetApplication, NmtState::ResetCommunication, NmtState::ResetConfiguration]
            }
            NmtCommandId::ResetCommunication => &[NmtState::ResetCommunication, NmtState::ResetConfiguration],
            _ => &[NmtState::ResetConfiguration],
        };
        for &s in chain {
            self.set_state(s, cause);
            match s {
                NmtState::ResetApplication => self.od.restore_defaults(0x2000..=0xFFFF),
                NmtState::ResetCommunication => {
                    self.od.restore_defaults(0x1000..=0x1FFF);
                    let _ = self.od.take_remote_writes();
                    self.sdo.reset();
                    self.async_queue.clear();
                    self.pending_reset = None;
                    self.ec = false;
                    self.en = false;
                    self.ea = false;
                    self.entries.clear();
                }
                NmtState::ResetConfiguration => self.apply_cycle_configuration(),
                _ => {}
            }
        }
        self.soc_deadline = None;
        self.cycle_open = false;
        self.preq_in_cycle = false;
        self.quiet_since = now;
        if self.reset_time.is_zero() {
            self.set_state(NmtState::NotActive, cause);
        } else {
            self.resetting_until = Some(now + self.reset_time);
        }
    }

    /// A loss threshold was reached: NMT cycle error, back to PRE_OPERATIONAL_1.
    fn cycle_error(&mut self) {
        self.counters.cycle_errors += 1;
        tracing::info!(node = self.node, state = %self.state, "cycle error: back to PRE_OPERATIONAL_1");
        self.soc_deadline = None;
        self.cycle_open = false;
        self.set_state(NmtState::PreOperational1, StateCause::CycleError);
    }

    /// Counts an error in the DLL error counter record `index` (cumulative +1, threshold
    /// count +8); true when the threshold count reaches a non-zero threshold (and is reset).
    fn record_error(&mut self, index: u16) -> bool {
        let cumulative = self.od.u32(index, 1).unwrap_or(0).wrapping_add(1);
        let _ = self.od.set_u32(index, 1, cumulative);
        let count = self.od.u32(index, 2).unwrap_or(0).saturating_add(THRESHOLD_STEP);
        let threshold = self.od.u32(index, 3).unwrap_or(0);
        let reached = threshold != 0 && count >= threshold;
        let _ = self.od.set_u32(index, 2, if reached { 0 } else { count });
        reached
    }

    /// One cycle without the error of counter record `index`.
    fn decay(&mut self, index: u16) {
        if let Some(count) = self.od.u32(index, 2).filter(|&c| c > 0) {
            let _ = self.od.set_u32(index, 2, count - 1);
        }
    }

    fn set_state(&mut self, to: NmtState, cause: StateCause) {
        if to == self.state {
            return;
        }
        let from = self.state;
        self.state = to;
        let _ = self.od.set_u8(CURRENT_STATE, 0, to.raw());
        self.pres_dirty = true;
        tracing::debug!(node = self.node, %from, %to, ?cause, "NMT state");
        self.events.push(CnEvent::State { from, to, cause });
    }

    /// After a PRes: counts it when frames wait for an invitation, and has the next PRes
    /// announce none once after [`REANNOUNCE_AFTER`] of them (see there why).
    fn count_uninvited_pres(&mut self) {
        if self.reannounce {
            // That PRes said RS 0: the next says the real count again.
            self.reannounce = false;
            self.uninvited_pres = 0;
            self.pres_dirty = true;
        } else if self.async_queue.is_empty() {
            self.uninvited_pres = 0;
        } else {
            self.uninvited_pres += 1;
            if self.uninvited_pres >= REANNOUNCE_AFTER {
                self.reannounce = true;
                self.pres_dirty = true;
            }
        }
    }

    fn pr_rs(&self) -> PrRs {
        if self.reannounce {
            return PrRs { pr: 0, rs: 0, link: 0 };
        }
        let rs = u8::try_from(self.async_queue.len().min(7)).unwrap_or(7);
        PrRs { pr: if rs > 0 { PR_GENERIC } else { 0 }, rs, link: 0 }
    }

    /// EN and EC as the StatusResponse and IdentResponse carry them.
    fn exception_flags(&self) -> Flags {
        let mut f = Flags::empty();
        if self.en {
            f |= Flags::EN;
        }
        if self.ec {
            f |= Flags::EC;
        }
        f
    }

    /// The IdentResponse, from the dictionary: state, FeatureFlags 0x1F82, MTU 0x1F98/8,
    /// PReq/PRes payload limits 0x1F98/4,5, PResMaxLatency 0x1F98/3, identity 0x1000 and
    /// 0x1018, VerifyConfiguration 0x1020, and the IP convention `192.168.100.<node>/24` with
    /// gateway .254.
    pub fn ident_response(&self) -> IdentResponse {
        let od = &self.od;
        IdentResponse {
            flags: self.exception_flags(),
            pr_rs: self.pr_rs(),
            nmt_state: self.state,
            epl_version: od.u8(0x1F83, 0).unwrap_or(0x20),
            feature_flags: od.u32(0x1F82, 0).unwrap_or(0),
            mtu: od.u16(CYCLE_TIMING, 8).unwrap_or(300),
            poll_in_size: od.u16(CYCLE_TIMING, 4).unwrap_or(0),
            poll_out_size: od.u16(CYCLE_TIMING, 5).unwrap_or(0),
            response_time: od.u32(CYCLE_TIMING, 3).unwrap_or(0),
            device_type: od.u32(0x1000, 0).unwrap_or(0),
            vendor_id: od.u32(0x1018, 1).unwrap_or(0),
            product_code: od.u32(0x1018, 2).unwrap_or(0),
            revision_number: od.u32(0x1018, 3).unwrap_or(0),
            serial_number: od.u32(0x1018, 4).unwrap_or(0),
            vendor_ext1: [0; 8],
            verify_conf_date: od.u32(0x1020, 1).unwrap_or(0),
            verify_conf_time: od.u32(0x1020, 2).unwrap_or(0),
            app_sw_date: od.u32(0x1F52, 1).unwrap_or(0),
            app_sw_time: od.u32(0x1F52, 2).unwrap_or(0),
            ip_address: Ipv4Addr::new(192, 168, 100, self.node),
            subnet_mask: Ipv4Addr::new(255, 255, 255, 0),
            default_gateway: Ipv4Addr::new(192, 168, 100, 254),
            host_name: FixedText::Text(format!("motus-cn-{}", self.node)),
            vendor_ext2: Vec::new(),
            reserved1: 0,
            reserved2: 0,
            reserved3: 0,
        }
    }

    /// The StatusResponse: EN/EC, RS/PR, state, the error register 0x1001 as the first byte
    /// of the static error field, and the posted error entries.
    pub fn status_response(&self) -> StatusResponse {
        let mut static_errors = [0u8; 8];
        static_errors[0] = self.od.u8(0x1001, 0).unwrap_or(0);
        StatusResponse {
            flags: self.exception_flags(),
            pr_rs: self.pr_rs(),
            nmt_state: self.state,
            static_errors,
            entries: self.entries.iter().copied().collect(),
            reserved: [0; 3],
        }
    }

    /// The PRes: state, RD only in OPERATIONAL, EN, RS/PR, the TPDO mapping version
    /// (0x1800/2) and the TPDO payload; 60 bytes or 24 + payload.
    fn rebuild_pres(&mut self) {
        let mut flags = Flags::empty();
        if self.state == NmtState::Operational {
            flags |= Flags::RD;
        }
        if self.en {
            flags |= Flags::EN;
        }
        let pres = PRes {
            nmt_state: self.state,
            flags,
            pr_rs: self.pr_rs(),
            pdo_version: self.od.u8(TPDO_COMM_BASE, 2).unwrap_or(0),
            payload: self.od.pres_payload(),
            reserved: 0,
        };
        let frame = EplFrame::new(self.mac, MacAddr::PRES, BROADCAST_NODE_ID, self.node, Message::PRes(pres));
        self.pres.clear();
        if let Err(e) = frame.encode_into(&mut self.pres) {
            tracing::warn!(node = self.node, "PRes not encoded: {e}");
        }
        self.pres_dirty = false;
    }

    fn asnd(&self, dst: u8, body: Asnd) -> Option<Vec<u8>> {
        let frame = EplFrame::new(self.mac, MacAddr::ASND, dst, self.node, Message::Asnd(body));
        match frame.encode() {
            Ok(f) => Some(f),
            Err(e) => {
                tracing::warn!(node = self.node, "ASnd not encoded: {e}");
                None
            }
        }
    }

    fn queue_sdo(&mut self, frame: &SdoFrame) {
        let Some(f) = self.asnd(MN_NODE_ID, Asnd::Sdo(frame.clone())) else { return };
        if self.async_queue.len() >= MAX_ASYNC_QUEUE {
            self.counters.async_dropped += 1;
            return;
        }
        self.async_queue.push_back(f);
        self.pres_dirty = true;
    }
}
