//! A simulated Controlled Node that behaves like a servo drive (`specs/powerlink.md` §5, §6):
//! NMT state machine driven by SoA/SoC and NMT commands, IdentResponse / StatusResponse on
//! invitation, PRes on its PReq (RD only in OPERATIONAL), and an [`AxisModel`] stepped once per
//! SoC with the RelativeTime difference as time step.
//!
//! A CN has no clock of its own: time is the reception time of each frame (the link's, virtual
//! on a [`crate::transport::MemHub`] made with a virtual clock), for its safety lease and its
//! loss of SoC. While unplugged ([`super::Segment::unplug`]) it receives and sends nothing.

use std::net::Ipv4Addr;
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use motus_epl_protocol::{
    Asnd, EplFrame, FixedText, Flags, IdentResponse, MacAddr, Message, NmtCommandId, NmtState, PRes, PrRs,
    RequestedService, SafetyLease, StatusResponse, BROADCAST_NODE_ID, LEASE_ASND_NODE_ID, MN_NODE_ID,
};

use super::axis::{AxisModel, DriveParams};
use super::pdo::{
    Actual, SetPoint, CONTROL_ENABLE, CONTROL_QUICK_STOP, STATUS_ENABLED, STATUS_HOMED, STATUS_LEASE_STOP,
    STATUS_QUICK_STOP, STATUS_STANDSTILL,
};
use crate::transport::{EthLink, FrameHandler, MAX_FRAME};

/// State a CN shares with the [`super::Segment`] handle.
#[derive(Debug)]
pub(crate) struct CnShared {
    pub(crate) state: AtomicU8,
    /// Set while the CN's cable is pulled: it receives and sends nothing.
    pub(crate) unplugged: AtomicBool,
}

impl CnShared {
    pub(crate) fn new() -> Self {
        Self { state: AtomicU8::new(NmtState::NotActive.raw()), unplugged: AtomicBool::new(false) }
    }
}

pub(crate) struct Cn {
    node: u8,
    link: Arc<dyn EthLink>,
    mac: MacAddr,
    state: NmtState,
    axis: AxisModel,
    setpoint: SetPoint,
    last_relative_us: Option<u64>,
    lease_timeout: Option<Duration>,
    /// Expiry of the newest safe lease (`None`: none yet, or revoked).
    lease_until: Option<Instant>,
    /// The node whose PRes carries the lease (see [`DriveParams::safety_node`]).
    safety_node: Option<u8>,
    /// The lease counter of the last renewal from the safety node.
    last_lease_seq: Option<u16>,
    soc_loss_tolerance: Option<Duration>,
    /// Reception time of the last SoC.
    last_soc_at: Option<Instant>,
    shared: Arc<CnShared>,
    out: Vec<u8>,
}

impl Cn {
    pub(crate) fn new(node: u8, link: Arc<dyn EthLink>, params: DriveParams, shared: Arc<CnShared>) -> Self {
        let mac = link.mac();
        let initial = params.initial_position.round() as i32;
        Self {
            node,
            link,
            mac,
            state: NmtState::NotActive,
            axis: AxisModel::new(params),
            setpoint: SetPoint { control: 0, target: initial },
            last_relative_us: None,
            lease_timeout: params.lease_timeout,
            lease_until: None,
            safety_node: params.safety_node,
            last_lease_seq: None,
            soc_loss_tolerance: params.soc_loss_tolerance,
            last_soc_at: None,
            shared,
            out: Vec::with_capacity(MAX_FRAME),
        }
    }

    fn set_state(&mut self, s: NmtState) {
        if s != self.state {
            tracing::debug!(node = self.node, from = %self.state, to = %s, "CN state");
        }
        self.state = s;
        self.shared.state.store(s.raw(), Ordering::Relaxed);
    }

    fn send(&mut self, dst_node: u8, message: Message) {
        let frame = EplFrame::new(self.mac, MacAddr::BROADCAST, dst_node, self.node, message);
        self.out.clear();
        if let Err(e) = frame.encode_into(&mut self.out) {
            tracing::warn!(node = self.node, "encode: {e}");
            return;
        }
        if let Err(e) = self.link.send(&self.out) {
            tracing::warn!(node = self.node, "send: {e}");
        }
    }

    /// The PRes payload at `now`.
    fn actual(&self, now: Instant) -> Actual {
        let mut status = 0;
        if self.setpoint.control & CONTROL_ENABLE != 0 {
            status |= STATUS_ENABLED;
        }
        if self.setpoint.control & CONTROL_QUICK_STOP != 0 {
            status |= STATUS_QUICK_STOP;
        }
        if self.axis.speed() == 0.0 {
            status |= STATUS_STANDSTILL;
        }
        if self.lease_stop(now) {
            status |= STATUS_LEASE_STOP;
        }
        status |= STATUS_HOMED;
        Actual {
            status,
            position: self.axis.position().round() as i32,
            speed: self.axis.speed().round() as i32,
        }
    }

    fn ident_response(&self) -> IdentResponse {
        IdentResponse {
            flags: Flags::empty(),
            pr_rs: PrRs::default(),
            nmt_state: self.state,
            epl_version: 0x20,
            // isochronous | SDO/ASnd | NMT info services
            feature_flags: 0x0000_0015,
            mtu: 300,
            poll_in_size: super::pdo::PREQ_PAYLOAD_LEN as u16,
            poll_out_size: super::pdo::PRES_PAYLOAD_LEN as u16,
            response_time: 50_000,
            // CiA 402 drive
            device_type: 0x0002_0192,
            vendor_id: 0x0000_0000,
            product_code: 0x4d4f_5455,
            revision_number: 1,
            serial_number: u32::from(self.node),
            vendor_ext1: [0; 8],
            verify_conf_date: 0,
            verify_conf_time: 0,
            app_sw_date: 0,
            app_sw_time: 0,
            ip_address: Ipv4Addr::new(192, 168, 100, self.node),
            subnet_mask: Ipv4Addr::new(255, 255, 255, 0),
            default_gateway: Ipv4Addr::new(192, 168, 100, 254),
            host_name: FixedText::Text(format!("motus-drive-{}", self.node)),
            vendor_ext2: Vec::new(),
            reserved1: 0,
            reserved2: 0,
            reserved3: 0,
        }
    }

    fn status_response(&self) -> StatusResponse {
        StatusResponse {
            flags: Flags::empty(),
            pr_rs: PrRs::default(),
            nmt_state: self.state,
            static_errors: [0; 8],
            entries: Vec::new(),
            reserved: [0; 3],
        }
    }

    /// True when this drive needs a lease and has no valid one at `now`.
    fn lease_stop(&self, now: Instant) -> bool {
        self.lease_timeout.is_some() && self.lease_until.map_or(true, |until| now >= until)
    }

    fn on_lease(&mut self, lease: &SafetyLease, at: Instant) {
        let Some(timeout) = self.lease_timeout else { return };
        if lease.safe {
            let valid = Duration::from_micros(u64::from(lease.valid_for_us)).min(timeout);
            self.lease_until = Some(at + valid);
        } else {
            if self.lease_until.is_some() {
                tracing::info!(node = self.node, seq = lease.seq, "safety lease revoked: quick stop");
            }
            // Braking starts at the next SoC (the axis model steps once per cycle).
            self.lease_until = None;
        }
    }

    /// The lease in a PRes of the safety node: a renewal needs the RD flag (the node is
    /// OPERATIONAL) and a counter that advanced (a node answering from a frozen buffer renews
    /// nothing); SafeToRun false revokes at once, whatever the flags.
    fn on_safety_pres(&mut self, pres: &PRes, at: Instant) {
        let Some(lease) = SafetyLease::decode(&pres.payload) else { return };
        if !lease.safe {
            self.on_lease(&lease, at);
            self.last_lease_seq = Some(lease.seq);
            return;
        }
        if !pres.flags.contains(Flags::RD) || self.last_lease_seq == Some(lease.seq) {
            return;
        }
        self.last_lease_seq = Some(lease.seq);
        self.on_lease(&lease, at);
    }

    /// Handles one received frame (received at `at`).
    pub(crate) fn handle_at(&mut self, frame: &EplFrame, at: Instant) {
        match (&frame.message, self.safety_node) {
            (Message::Asnd(asnd), safety_node) => {
                if let Some(lease) = SafetyLease::from_asnd(asnd) {
                    if safety_node.is_none() && frame.src_node == LEASE_ASND_NODE_ID {
                        self.on_lease(&lease, at);
                    } else {
                        tracing::debug!(node = self.node, from = frame.src_node, "lease ASnd ignored");
                    }
                    return;
                }
            }
            (Message::PRes(pres), Some(safety)) if frame.src_node == safety => {
                self.on_safety_pres(pres, at);
                return;
            }
            _ => {}
        }
        self.handle(frame, at);
    }

    /// Handles one received frame (received at `at`).
    fn handle(&mut self, frame: &EplFrame, at: Instant) {
        match &frame.message {
            Message::Soc(soc) => {
                let lost_socs = self.soc_loss_tolerance.is_some_and(|tolerance| {
                    self.last_soc_at.is_some_and(|last| at.saturating_duration_since(last) >= tolerance)
                });
                self.last_soc_at = Some(at);
                match self.state {
                    NmtState::PreOperational2 | NmtState::ReadyToOperate | NmtState::Operational
                        if lost_socs =>
                    {
                        tracing::warn!(
                            node = self.node,
                            "loss of SoC: cycle error, back to PRE_OPERATIONAL_1"
                        );
                        self.set_state(NmtState::PreOperational1);
                    }
                    NmtState::NotActive => self.set_state(NmtState::PreOperational1),
                    NmtState::PreOperational1 => self.set_state(NmtState::PreOperational2),
                    _ => {}
                }
                let dt = self
                    .last_relative_us
                    .map_or(0.0, |last| soc.relative_time.saturating_sub(last) as f64 * 1e-6);
                self.last_relative_us = Some(soc.relative_time);
                let enabled =
                    self.setpoint.control & CONTROL_ENABLE != 0 && self.state == NmtState::Operational;
                let quick_stop = self.setpoint.control & CONTROL_QUICK_STOP != 0 || self.lease_stop(at);
                let target = if enabled { f64::from(self.setpoint.target) } else { self.axis.position() };
                self.axis.step(dt, target, quick_stop || !enabled && self.axis.speed() != 0.0);
            }
            Message::Soa(soa) => {
                if self.state == NmtState::NotActive {
                    self.set_state(NmtState::PreOperational1);
                }
                if soa.target == self.node {
                    match soa.requested_service {
                        RequestedService::IdentRequest => {
                            let body = self.ident_response();
                            self.send(BROADCAST_NODE_ID, Message::Asnd(Asnd::IdentResponse(body)));
                        }
                        RequestedService::StatusRequest => {
                            let body = self.status_response();
                            self.send(BROADCAST_NODE_ID, Message::Asnd(Asnd::StatusResponse(body)));
                        }
                        _ => {}
                    }
                }
            }
            Message::PReq(preq) if frame.dst_node == self.node && frame.ethernet.dst == self.mac => {
                if let Some(sp) = SetPoint::decode(&preq.payload) {
                    self.setpoint = sp;
                }
                let operational = self.state == NmtState::Operational;
                let pres = PRes {
                    nmt_state: self.state,
                    flags: if operational { Flags::RD } else { Flags::empty() },
                    pr_rs: PrRs::default(),
                    pdo_version: 0,
                    payload: self.actual(at).encode(),
                    reserved: 0,
                };
                self.send(BROADCAST_NODE_ID, Message::PRes(pres));
            }
            Message::Asnd(Asnd::NmtCommand(cmd))
                if frame.src_node == MN_NODE_ID
                    && (frame.dst_node == self.node || frame.dst_node == BROADCAST_NODE_ID) =>
            {
                self.nmt_command(cmd.command);
            }
            _ => {}
        }
    }

    fn nmt_command(&mut self, command: NmtCommandId) {
        use NmtState as S;
        let next = match (command, self.state) {
            (
                NmtCommandId::ResetNode | NmtCommandId::ResetCommunication | NmtCommandId::ResetConfiguration,
                _,
            ) => Some(S::NotActive),
            (NmtCommandId::EnableReadyToOperate, S::PreOperational2) => Some(S::ReadyToOperate),
            (NmtCommandId::StartNode, S::ReadyToOperate) => Some(S::Operational),
            (NmtCommandId::StopNode, S::PreOperational2 | S::ReadyToOperate | S::Operational) => {
                Some(S::Stopped)
            }
            (NmtCommandId::EnterPreOperational2, S::Operational | S::Stopped) => Some(S::PreOperational2),
            _ => None,
        };
        if let Some(s) = next {
            self.set_state(s);
        }
    }

    /// This CN as a receiver of its link's frames (run in the sending thread on an
    /// in-process segment, or by a receiving thread: [`crate::transport::serve_on_thread`]).
    pub(crate) fn into_handler(mut self) -> FrameHandler {
        self.set_state(NmtState::NotActive);
        Box::new(move |bytes, at| {
            if self.shared.unplugged.load(Ordering::Relaxed) {
                return;
            }
            if let Ok(frame) = EplFrame::decode(bytes) {
                self.handle_at(&frame, at);
            }
        })
    }

    /// The CN's link.
    pub(crate) fn link(&self) -> Arc<dyn EthLink> {
        Arc::clone(&self.link)
    }
}

/// Serves several CNs (their links and [`Cn::into_handler`]s) from one thread, polling the
/// links without sleeping.
pub(crate) fn run_spinning(mut cns: Vec<(Arc<dyn EthLink>, FrameHandler)>, stop: &AtomicBool) {
    let mut buf = vec![0u8; MAX_FRAME];
    while !stop.load(Ordering::Relaxed) {
        let mut idle = true;
        for (link, handler) in &mut cns {
            match link.recv(&mut buf, Duration::ZERO) {
                Ok(Some((n, at))) => {
                    idle = false;
                    handler(buf.get(..n).unwrap_or(&[]), at);
                }
                Ok(None) => {}
                Err(e) => tracing::warn!(link = %link.describe(), "recv: {e}"),
            }
        }
        if idle {
            std::hint::spin_loop();
        }
    }
}
