//! The simulated Managing Node (node 240): boot-up (`specs/powerlink.md` §6) and the cycle
//! (§5) on a dedicated thread with absolute deadlines.
//!
//! * PRE_OPERATIONAL_1, reduced cycle: SoA only, one per cycle period. The first SoA is
//!   followed by a broadcast NMTResetNode; the first [`MnConfig::preop1_start_cycles`] SoAs invite
//!   nobody, then each invites one unidentified CN with an IdentRequest. The MN learns each CN's
//!   MAC from the source of its IdentResponse. When every CN has answered: PRE_OPERATIONAL_2.
//! * Full cycle: SoC; for each identified CN a PReq (unicast, set-point payload, RD only when
//!   OPERATIONAL) and a wait for its PRes up to [`MnConfig::pres_timeout`] (a miss is counted);
//!   SoA. The async slot carries, in order of priority: an NMT command of the MN (SoA
//!   UnspecifiedInvite to 240, then the ASnd NMTCommand), a StatusRequest (during boot-up every
//!   cycle, in OPERATIONAL every [`MnConfig::status_request_every`] cycles), or nothing.
//! * Boot-up continues from the CN states seen in PRes: all CNs PRE_OPERATIONAL_2 ->
//!   NMTEnableReadyToOperate to each; all READY_TO_OPERATE -> MN READY_TO_OPERATE and
//!   NMTStartNode to each; all OPERATIONAL -> MN OPERATIONAL, the motion program starts.
//!   Commands are repeated every 20 cycles until the CN's state follows. Once the MN is
//!   READY_TO_OPERATE or OPERATIONAL, a CN that comes back in an earlier state (after a loss of
//!   SoC, or a reset) is booted on its own the same way while the others run.
//! * Loss: a CN whose PRes is missed [`MnConfig::lost_after`] times in a row is lost: no more
//!   PReq; the async slot invites it with an IdentRequest (after any NMT command) until it
//!   answers, then it is polled again. Both are recorded ([`super::MnStats::cn_events`]).
//! * Timing, on the segment's clock ([`super::SegmentBuilder::clock`]): sleep until
//!   [`MnConfig::busy_wait`] before the deadline (receiving stray frames meanwhile), then spin
//!   (on the system clock only); the lateness of each SoC after its deadline is recorded.
//!   Thread timer slack is set to 1 ns. A cycle whose work overruns the next deadline skips it.
//!   On a virtual clock every wait is a wait on the clock, so the cycle is exact.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use motus_clock::SharedClock;

use motus_epl_protocol::{
    Asnd, EplFrame, Flags, MacAddr, Message, NetTime, NmtCommand, NmtCommandId, NmtState, PReq,
    RequestedService, Soa, Soc, BROADCAST_NODE_ID, MN_NODE_ID,
};

use super::pdo::{SetPoint, CONTROL_ENABLE, CONTROL_QUICK_STOP};
use super::program::MotionProgram;
use super::stats::{CnChange, MnStats};
use crate::transport::{EthLink, MAX_FRAME};

/// Timing of the Managing Node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MnConfig {
    /// Cycle period (also the period of the reduced PreOp1 cycle).
    pub cycle: Duration,
    /// How long to wait for each PRes after its PReq.
    pub pres_timeout: Duration,
    /// How long to wait for an ASnd after a SoA invitation (capped by the next deadline).
    pub async_timeout: Duration,
    /// Spin (instead of sleeping) for this long before each deadline (on the system clock
    /// only: on another clock the MN sleeps on it).
    pub busy_wait: Duration,
    /// SoAs without invitation at the start of PreOp1 (openPOWERLINK: 10).
    pub preop1_start_cycles: u32,
    /// In OPERATIONAL, one StatusRequest every this many cycles (0: never).
    pub status_request_every: u32,
    /// Poll the link without sleeping while waiting for a PRes (saves the thread's wake-up
    /// latency, tens of microseconds on a busy machine, at the cost of one busy core; on the
    /// system clock only).
    pub spin_for_pres: bool,
    /// A CN whose PRes is missed this many times in a row is lost (see the module
    /// documentation); 0: never (the default: a CN is polled whatever it answers).
    pub lost_after: u32,
}

impl Default for MnConfig {
    fn default() -> Self {
        Self {
            cycle: Duration::from_millis(1),
            pres_timeout: Duration::from_micros(300),
            async_timeout: Duration::from_micros(300),
            busy_wait: Duration::from_micros(50),
            preop1_start_cycles: 10,
            status_request_every: 1000,
            spin_for_pres: false,
            lost_after: 0,
        }
    }
}

/// State the MN shares with the [`super::Segment`] handle.
#[derive(Debug, Default)]
pub(crate) struct MnShared {
    pub(crate) state: AtomicU8,
    pub(crate) quick_stop: AtomicBool,
    pub(crate) stats: Mutex<MnStats>,
}

#[derive(Debug)]
struct CnSlot {
    node: u8,
    /// A drive of the segment (set-point in its PReq, actual values to the program), or a
    /// node polled with an empty PReq ([`super::SegmentBuilder::polled_node`]).
    drive: bool,
    mac: Option<MacAddr>,
    state: NmtState,
    /// The last NMT command queued for the CN, and the cycle it was queued in.
    last_command: Option<(u64, NmtCommandId)>,
    /// PRes missed in a row.
    missed: u32,
    /// Lost (see [`MnConfig::lost_after`]) and not identified again yet.
    lost: bool,
}

pub(crate) struct Mn {
    link: Arc<dyn EthLink>,
    clock: SharedClock,
    mac: MacAddr,
    config: MnConfig,
    cns: Vec<CnSlot>,
    state: NmtState,
    program: Option<Box<dyn MotionProgram>>,
    shared: Arc<MnShared>,
    commands: VecDeque<(u8, NmtCommandId)>,
    cycle_index: u64,
    reduced_index: u64,
    status_rr: usize,
    ident_rr: usize,
    op_start: Option<Instant>,
    /// The clock's time and the wall time when the MN started (NetTime of each SoC).
    net_epoch: Option<(Instant, Duration)>,
    targets: Vec<i32>,
    out: Vec<u8>,
    buf: Vec<u8>,
}

impl Mn {
    pub(crate) fn new(
        link: Arc<dyn EthLink>,
        clock: SharedClock,
        config: MnConfig,
        nodes: &[(u8, i32)],
        polled: &[u8],
        program: Option<Box<dyn MotionProgram>>,
        shared: Arc<MnShared>,
    ) -> Self {
        let slot = |node: u8, drive: bool| CnSlot {
            node,
            drive,
            mac: None,
            state: NmtState::NotActive,
            last_command: None,
            missed: 0,
            lost: false,
        };
        Self {
            mac: link.mac(),
            link,
            clock,
            config,
            cns: nodes
                .iter()
                .map(|&(node, _)| slot(node, true))
                .chain(polled.iter().map(|&node| slot(node, false)))
                .collect(),
            state: NmtState::PreOperational1,
            program,
            shared,
            commands: VecDeque::new(),
            cycle_index: 0,
            reduced_index: 0,
            status_rr: 0,
            ident_rr: 0,
            op_start: None,
            net_epoch: None,
            targets: nodes.iter().map(|&(_, p)| p).collect(),
            out: Vec::with_capacity(MAX_FRAME),
            buf: vec![0; MAX_FRAME],
        }
    }

    fn stats(&self) -> std::sync::MutexGuard<'_, MnStats> {
        self.shared.stats.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn set_state(&mut self, s: NmtState) {
        tracing::debug!(from = %self.state, to = %s, "MN state");
        self.state = s;
        self.shared.state.store(s.raw(), Ordering::Relaxed);
    }

    fn send(&mut self, dst_mac: MacAddr, dst_node: u8, message: Message) {
        let frame = EplFrame::new(self.mac, dst_mac, dst_node, MN_NODE_ID, message);
        self.out.clear();
        let ok = frame.encode_into(&mut self.out).is_ok() && self.link.send(&self.out).is_ok();
        if !ok {
            self.stats().send_errors += 1;
        }
    }

    /// Receives one frame until `deadline`; returns it decoded, handling ASnd bookkeeping.
    fn recv_until(&mut self, deadline: Instant) -> Option<(EplFrame, Instant)> {
        let now = self.clock.now();
        if now >= deadline {
            return None;
        }
        let (n, at) = if self.config.spin_for_pres {
            loop {
                if let Some(r) = self.link.recv(&mut self.buf, Duration::ZERO).ok()? {
                    break r;
                }
                if self.clock.now() >= deadline {
                    return None;
                }
                std::hint::spin_loop();
            }
        } else {
            self.link.recv(&mut self.buf, deadline - now).ok()??
        };
        match EplFrame::decode(self.buf.get(..n).unwrap_or(&[])) {
            Ok(frame) => {
                self.observe(&frame);
                Some((frame, at))
            }
            Err(_) => {
                self.stats().decode_errors += 1;
                None
            }
        }
    }

    /// Learns MACs and states from IdentResponse, StatusResponse and PRes; a lost CN that
    /// identifies itself is found.
    fn observe(&mut self, frame: &EplFrame) {
        let (state, learn_mac) = match &frame.message {
            Message::Asnd(Asnd::IdentResponse(r)) => (r.nmt_state, true),
            Message::Asnd(Asnd::StatusResponse(r)) => (r.nmt_state, false),
            Message::PRes(p) => (p.nmt_state, false),
            _ => return,
        };
        let Some(cn) = self.cns.iter_mut().find(|c| c.node == frame.src_node) else { return };
        cn.state = state;
        if !learn_mac {
            return;
        }
        cn.mac = Some(frame.ethernet.src);
        if cn.lost {
            cn.lost = false;
            cn.missed = 0;
            let node = cn.node;
            tracing::info!(node, state = %state, "CN found again");
            self.stats().cn_event(node, CnChange::Found);
        }
    }

    fn sleep_until(&mut self, deadline: Instant) {
        let wake = deadline.checked_sub(self.config.busy_wait).unwrap_or(deadline);
        while self.clock.now() < wake {
            // Stray or late frames are observed and dropped.
            let _ = self.recv_until(wake);
        }
        // Spinning (busy_wait is zero on a clock other than the system's).
        while self.clock.now() < deadline {
            std::hint::spin_loop();
        }
    }

    /// Runs until `stop` is set.
    pub(crate) fn run(mut self, stop: &AtomicBool) {
        if let Err(e) = nix::sys::prctl::set_timerslack(1) {
            tracing::debug!("timer slack: {e}");
        }
        self.shared.state.store(self.state.raw(), Ordering::Relaxed);
        let start = self.clock.now();
        self.net_epoch = Some((start, SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default()));
        let epoch = start + self.config.cycle;
        let mut deadline = epoch;
        let mut first_soc: Option<Instant> = None;
        while !stop.load(Ordering::Relaxed) {
            self.sleep_until(deadline);
            let late = self.clock.now().saturating_duration_since(deadline);
            if self.state == NmtState::PreOperational1 {
                self.reduced_cycle(deadline + self.config.cycle);
            } else {
                let start = *first_soc.get_or_insert(deadline);
                {
                    let mut st = self.stats();
                    st.start_late_ns.push(u64::try_from(late.as_nanos()).unwrap_or(u64::MAX));
                    st.cycles += 1;
                    if self.state == NmtState::Operational {
                        st.operational_cycles += 1;
                    }
                }
                self.full_cycle(
                    deadline,
                    deadline.saturating_duration_since(start),
                    deadline + self.config.cycle,
                );
            }
            deadline += self.config.cycle;
            let now = self.clock.now();
            // Past the next deadline (work that ends exactly on it, as a wait capped by it does
            // on a virtual clock, is on time).
            if now > deadline {
                self.stats().overruns += 1;
                while deadline < now {
                    deadline += self.config.cycle;
                }
            }
        }
    }

    fn reduced_cycle(&mut self, next_deadline: Instant) {
        self.stats().reduced_cycles += 1;
        let i = self.reduced_index;
        self.reduced_index += 1;
        let invite = if i < u64::from(self.config.preop1_start_cycles) {
            None
        } else {
            let unidentified: Vec<u8> = self.cns.iter().filter(|c| c.mac.is_none()).map(|c| c.node).collect();
            if unidentified.is_empty() {
                self.set_state(NmtState::PreOperational2);
                return;
            }
            let k = usize::try_from(i).unwrap_or(0) % unidentified.len();
            unidentified.get(k).copied()
        };
        let soa = match invite {
            Some(node) => Soa::new(self.state, RequestedService::IdentRequest, node),
            None if i == 0 => Soa::new(self.state, RequestedService::UnspecifiedInvite, MN_NODE_ID),
            None => Soa::new(self.state, RequestedService::NoService, 0),
        };
        self.send(MacAddr::SOA, BROADCAST_NODE_ID, Message::Soa(soa));
        if i == 0 {
            // Reset every CN at the start of PreOp1 (specs/powerlink.md §6 timeline).
            let cmd = NmtCommand { command: NmtCommandId::ResetNode, data: Vec::new(), reserved: 0 };
            self.send(MacAddr::ASND, BROADCAST_NODE_ID, Message::Asnd(Asnd::NmtCommand(cmd)));
        }
        if let Some(node) = invite {
            self.wait_asnd(node, next_deadline);
        }
    }

    fn wait_asnd(&mut self, node: u8, next_deadline: Instant) {
        let cap = next_deadline.checked_sub(self.config.busy_wait).unwrap_or(next_deadline);
        let until = (self.clock.now() + self.config.async_timeout).min(cap);
        while self.clock.now() < until {
            if let Some((f, _)) = self.recv_until(until) {
                if matches!(f.message, Message::Asnd(_)) && f.src_node == node {
                    return;
                }
            }
        }
    }

    fn full_cycle(&mut self, deadline: Instant, since_first_soc: Duration, next_deadline: Instant) {
        // NetTime: the wall time of the deadline, counted on the segment's clock from the start.
        let wall = self
            .net_epoch
            .map_or(Duration::ZERO, |(start, wall)| wall + deadline.saturating_duration_since(start));
        let soc = Soc {
            flags: Flags::empty(),
            net_time: NetTime { seconds: wall.as_secs() as u32, nanoseconds: wall.subsec_nanos() },
            relative_time: u64::try_from(since_first_soc.as_micros()).unwrap_or(u64::MAX),
            reserved1: 0,
            reserved2: 0,
        };
        self.send(MacAddr::SOC, BROADCAST_NODE_ID, Message::Soc(soc));
        let operational = self.state == NmtState::Operational;
        if operational {
            let t = self.op_start.map_or(Duration::ZERO, |s| deadline.saturating_duration_since(s));
            if let Some(p) = self.program.as_mut() {
                p.setpoints(t, &mut self.targets);
            }
        }
        let quick_stop = self.shared.quick_stop.load(Ordering::Relaxed);
        for i in 0..self.cns.len() {
            let Some(cn) = self.cns.get(i) else { continue };
            let (node, drive, Some(mac)) = (cn.node, cn.drive, cn.mac) else { continue };
            let mut control = if operational { CONTROL_ENABLE } else { 0 };
            if quick_stop {
                control |= CONTROL_QUICK_STOP;
            }
            let sp = SetPoint { control, target: self.targets.get(i).copied().unwrap_or(0) };
            let preq = PReq {
                flags: if operational { Flags::RD } else { Flags::empty() },
                payload: if drive { sp.encode().to_vec() } else { Vec::new() },
                ..PReq::default()
            };
            let sent = self.clock.now();
            self.send(mac, node, Message::PReq(preq));
            self.wait_pres(i, node, sent, operational, drive);
        }
        self.async_phase(next_deadline);
        self.boot_step(deadline);
        self.cycle_index += 1;
    }

    fn wait_pres(&mut self, index: usize, node: u8, sent: Instant, operational: bool, drive: bool) {
        let until = sent + self.config.pres_timeout;
        loop {
            match self.recv_until(until) {
                Some((f, at)) => {
                    if let Message::PRes(pres) = &f.message {
                        if f.src_node == node {
                            if let Some(cn) = self.cns.get_mut(index) {
                                cn.missed = 0;
                            }
                            if operational {
                                let rtt = at.saturating_duration_since(sent).as_nanos();
                                self.stats().pres_rtt_ns.push(u64::try_from(rtt).unwrap_or(u64::MAX));
                                if let (true, Some(p), Some(a)) =
                                    (drive, self.program.as_mut(), super::pdo::Actual::decode(&pres.payload))
                                {
                                    p.actual(index, &a);
                                }
                            }
                            return;
                        }
                        self.stats().pres_late += 1;
                    }
                }
                None if self.clock.now() >= until => break,
                None => {}
            }
        }
        if operational {
            *self.stats().pres_missed.entry(node).or_default() += 1;
        }
        let lost_after = self.config.lost_after;
        let Some(cn) = self.cns.get_mut(index) else { return };
        cn.missed = cn.missed.saturating_add(1);
        if lost_after > 0 && cn.missed >= lost_after {
            tracing::warn!(node, missed = cn.missed, "CN lost: no PRes {lost_after} times in a row");
            cn.mac = None;
            cn.lost = true;
            cn.missed = 0;
            cn.state = NmtState::NotActive;
            cn.last_command = None;
            self.stats().cn_event(node, CnChange::Lost);
        }
    }

    fn async_phase(&mut self, next_deadline: Instant) {
        if let Some((node, command)) = self.commands.pop_front() {
            let soa = Soa::new(self.state, RequestedService::UnspecifiedInvite, MN_NODE_ID);
            self.send(MacAddr::SOA, BROADCAST_NODE_ID, Message::Soa(soa));
            let cmd = NmtCommand { command, data: Vec::new(), reserved: 0 };
            self.send(MacAddr::ASND, node, Message::Asnd(Asnd::NmtCommand(cmd)));
            return;
        }
        // A lost CN is invited to identify itself again, one per cycle in turn.
        let n = self.cns.len();
        let lost = (1..=n)
            .map(|k| (self.ident_rr + k) % n.max(1))
            .find(|&i| self.cns.get(i).is_some_and(|c| c.lost));
        if let Some(i) = lost {
            self.ident_rr = i;
            if let Some(node) = self.cns.get(i).map(|c| c.node) {
                let soa = Soa::new(self.state, RequestedService::IdentRequest, node);
                self.send(MacAddr::SOA, BROADCAST_NODE_ID, Message::Soa(soa));
                self.wait_asnd(node, next_deadline);
                return;
            }
        }
        let every = u64::from(self.config.status_request_every);
        let booting = self.state != NmtState::Operational;
        let ask = !self.cns.is_empty() && (booting || (every > 0 && self.cycle_index % every == 0));
        if ask {
            self.status_rr = (self.status_rr + 1) % self.cns.len();
            if let Some(node) = self.cns.get(self.status_rr).map(|c| c.node) {
                let soa = Soa::new(self.state, RequestedService::StatusRequest, node);
                self.send(MacAddr::SOA, BROADCAST_NODE_ID, Message::Soa(soa));
                self.wait_asnd(node, next_deadline);
                return;
            }
        }
        let soa = Soa::new(self.state, RequestedService::NoService, 0);
        self.send(MacAddr::SOA, BROADCAST_NODE_ID, Message::Soa(soa));
    }

    fn boot_step(&mut self, deadline: Instant) {
        let all = |cns: &[CnSlot], s: NmtState| cns.iter().all(|c| c.state == s);
        // Whether CNs in READY_TO_OPERATE are started (else only PRE_OPERATIONAL_2 ones are
        // enabled).
        let start = match self.state {
            NmtState::PreOperational2 => {
                if all(&self.cns, NmtState::ReadyToOperate) {
                    self.set_state(NmtState::ReadyToOperate);
                    return;
                }
                false
            }
            NmtState::ReadyToOperate => {
                if all(&self.cns, NmtState::Operational) {
                    self.set_state(NmtState::Operational);
                    self.op_start = Some(deadline + self.config.cycle);
                    return;
                }
                true
            }
            NmtState::Operational => true,
            _ => return,
        };
        let cycle = self.cycle_index;
        for cn in &mut self.cns {
            let command = match cn.state {
                NmtState::PreOperational2 => NmtCommandId::EnableReadyToOperate,
                NmtState::ReadyToOperate if start => NmtCommandId::StartNode,
                _ => continue,
            };
            // A command is repeated every 20 cycles until the CN follows.
            let due = cn.last_command.map_or(true, |(c, last)| last != command || cycle >= c + 20);
            if cn.mac.is_some() && due {
                cn.last_command = Some((cycle, command));
                self.commands.push_back((cn.node, command));
            }
        }
    }
}
