//! [`SafetyNode`]: the supervisor as a Controlled Node of the segment, publishing SafeToRun
//! in the POWERLINK schedule instead of an ASnd outside it.
//!
//! The node is a standards CN ([`motus_epl::node::cn::ControlledNode`]: NMT state machine,
//! IdentResponse, StatusResponse, SDO server) with the dictionary of
//! [`ObjectDictionary::safety_node`]: its PRes payload is the lease body of
//! [`motus_epl_protocol::SafetyLease`] (SafeToRun, a lease counter, the validity, the
//! configuration fingerprint). The MN polls it like any CN, and every node of the segment
//! receives its PRes (cross traffic): the drives read SafeToRun there
//! ([`motus_epl::sim::DriveParams::safety_node`]; a real drive maps 0x2100/2 by an RPDO for the
//! node's PRes).
//!
//! The supervisor decides; the node publishes. [`SafetyNode::new`] gives the node and its
//! [`SafetyNodeTarget`], the [`motus_safety::StopTarget`] that goes into the supervisor's
//! fan-out: a quick stop clears SafeToRun, a renewal grants it until the supervisor's own
//! lease expires. Each PReq for the node is answered with the state at that moment, the
//! counter advanced by one: SafeToRun is true only while a renewal is current and every stop
//! has been published at least once (a stop followed by a renewal before the MN polled the
//! node still reaches the drives), so a supervisor
//! that stops deciding publishes "not safe" (fail closed), and one that stops answering lets
//! the drives' leases expire. [`crate::OnlineSupervisor::with_safety_node`] runs the node in
//! the supervisor's own loop, so the drives see the decision of the frames before the PReq.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use motus_clock::SharedClock;
use motus_epl::node::cn::{serve_frame, CnError, CnEvent, ControlledNode};
use motus_epl::sim::stats::SampleWindow;
use motus_epl::sim::Percentiles;
use motus_epl::EthLink;
use motus_epl_protocol::{DeviceIdentity, NmtState, ObjectDictionary, SafetyNodeTiming, SAFETY_LEASE_OBJECT};
use motus_safety::{Lease, StopError, StopTarget};

/// Options of a [`SafetyNode`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SafetyNodeConfig {
    /// Node ID (1..=239); the MN must poll it (a node in its concise DCF, or
    /// [`motus_epl::sim::SegmentBuilder::polled_node`] on the simulated segment).
    pub node_id: u8,
    /// Cycle length and loss-of-SoC tolerance until the MN configures them.
    pub timing: SafetyNodeTiming,
    /// The validity each safe PRes grants the drives (they also bound it by their own lease
    /// time).
    pub wire_lease: Duration,
    /// First bytes of the approved configuration's fingerprint, published with the lease.
    pub fingerprint: [u8; 8],
}

/// What the supervisor last decided, shared by the target and the node.
#[derive(Debug, Default)]
struct Grant {
    /// Renewed and not stopped since.
    safe: bool,
    /// The supervisor's lease ends then.
    until: Option<Instant>,
    /// A stop not yet published: when it was decided.
    stop_pending_since: Option<Instant>,
}

fn lock(grant: &Mutex<Grant>) -> MutexGuard<'_, Grant> {
    grant.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The supervisor's side of a [`SafetyNode`] (see the module documentation).
pub struct SafetyNodeTarget {
    node_id: u8,
    grant: Arc<Mutex<Grant>>,
    origin: Instant,
    clock: SharedClock,
}

impl StopTarget for SafetyNodeTarget {
    fn name(&self) -> String {
        format!("POWERLINK safety node {} (SafeToRun in its PRes)", self.node_id)
    }

    fn quick_stop(&mut self) -> Result<(), StopError> {
        let now = self.clock.now();
        let mut g = lock(&self.grant);
        g.safe = false;
        g.until = None;
        g.stop_pending_since.get_or_insert(now);
        Ok(())
    }

    fn renew(&mut self, lease: &Lease) -> Result<(), StopError> {
        let mut g = lock(&self.grant);
        g.safe = true;
        g.until = Some(self.origin + lease.expires());
        Ok(())
    }
}

/// The supervisor as a CN (see the module documentation).
pub struct SafetyNode {
    cn: ControlledNode,
    link: Arc<dyn EthLink>,
    clock: SharedClock,
    grant: Arc<Mutex<Grant>>,
    counter: u16,
    wire_lease_us: u32,
    fingerprint: [u8; 8],
    turnaround: SampleWindow,
    stop_published_ns: Vec<u64>,
    pres_sent: u64,
    send_errors: u64,
}

impl std::fmt::Debug for SafetyNode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SafetyNode")
            .field("node", &self.cn.node_id())
            .field("state", &self.cn.state())
            .field("link", &self.link.describe())
            .finish_non_exhaustive()
    }
}

impl SafetyNode {
    /// A safety node on `link`, powered on at `clock`'s now, and its stop target; `origin` is
    /// the epoch of the supervisor's lease times (the [`crate::OnlineSupervisor`]'s).
    ///
    /// # Errors
    /// [`CnError::InvalidNodeId`].
    pub fn new(
        config: &SafetyNodeConfig,
        link: Arc<dyn EthLink>,
        clock: SharedClock,
        origin: Instant,
    ) -> Result<(Self, SafetyNodeTarget), CnError> {
        let mac = link.mac();
        let identity = DeviceIdentity {
            // A generic device (no standard profile), Motus's product code.
            device_type: 0,
            product_code: 0x4d4f_5355,
            device_name: "Motus safety supervisor".into(),
            mac_address: mac.0,
            serial_number: u32::from(config.node_id),
            ..DeviceIdentity::default()
        };
        let od = ObjectDictionary::safety_node(config.node_id, &identity, config.timing);
        let cn = ControlledNode::new(config.node_id, mac, od, clock.now())?;
        let grant = Arc::new(Mutex::new(Grant::default()));
        let target = SafetyNodeTarget {
            node_id: config.node_id,
            grant: Arc::clone(&grant),
            origin,
            clock: Arc::clone(&clock),
        };
        let node = SafetyNode {
            cn,
            link,
            clock,
            grant,
            counter: 0,
            wire_lease_us: u32::try_from(config.wire_lease.as_micros()).unwrap_or(u32::MAX),
            fingerprint: config.fingerprint,
            turnaround: SampleWindow::default(),
            stop_published_ns: Vec::new(),
            pres_sent: 0,
            send_errors: 0,
        };
        Ok((node, target))
    }

    /// Writes the lease of `now` into the dictionary (the PRes about to be sent); returns
    /// SafeToRun.
    fn publish(&mut self, now: Instant) -> bool {
        let safe = {
            let g = lock(&self.grant);
            // A stop is published at least once, even when a renewal followed it before the
            // MN polled the node.
            g.safe && g.stop_pending_since.is_none() && g.until.is_some_and(|until| now < until)
        };
        self.counter = self.counter.wrapping_add(1);
        let valid = if safe { self.wire_lease_us } else { 0 };
        let od = self.cn.od_mut();
        let written = [
            od.set_u8(SAFETY_LEASE_OBJECT, 2, u8::from(safe)),
            od.set_u16(SAFETY_LEASE_OBJECT, 3, self.counter),
            od.set_u32(SAFETY_LEASE_OBJECT, 4, valid),
            od.set(SAFETY_LEASE_OBJECT, 5, &self.fingerprint),
        ];
        if let Some(Err(e)) = written.into_iter().find(Result::is_err) {
            // Fail closed: the dictionary refused the lease, so publish "not safe".
            tracing::error!(node = self.cn.node_id(), "safety node: lease not written: {e}");
            let _ = self.cn.od_mut().set_u8(SAFETY_LEASE_OBJECT, 2, 0);
            return false;
        }
        safe
    }

    /// Handles one frame received at `at`: a PReq for the node is answered at once with the
    /// lease of this moment; everything else goes to the CN (NMT commands, SoA invitations,
    /// SDO).
    pub fn on_frame(&mut self, raw: &[u8], at: Instant) {
        let safe = self.cn.is_preq_for_me(raw).then(|| self.publish(self.clock.now()));
        let served = serve_frame(&mut self.cn, &*self.link, &*self.clock, raw);
        self.send_errors += served.send_errors;
        let Some(sent) = served.pres_sent_at else { return };
        self.pres_sent += 1;
        self.turnaround
            .push(u64::try_from(sent.saturating_duration_since(at).as_nanos()).unwrap_or(u64::MAX));
        if safe == Some(false) {
            if let Some(since) = lock(&self.grant).stop_pending_since.take() {
                let ns = sent.saturating_duration_since(since).as_nanos();
                self.stop_published_ns.push(u64::try_from(ns).unwrap_or(u64::MAX));
            }
        }
    }

    /// Handles time (SDO time-outs, loss of SoC); call it at least every cycle.
    pub fn poll(&mut self, now: Instant) {
        self.cn.poll(now);
    }

    /// The node's NMT state.
    pub fn state(&self) -> NmtState {
        self.cn.state()
    }

    /// The node ID.
    pub fn node_id(&self) -> u8 {
        self.cn.node_id()
    }

    /// The node's events since the last call (NMT state changes and their causes).
    pub fn take_events(&mut self) -> Vec<CnEvent> {
        self.cn.take_events()
    }

    /// PRes sent.
    pub fn pres_sent(&self) -> u64 {
        self.pres_sent
    }

    /// Frames that could not be sent.
    pub fn send_errors(&self) -> u64 {
        self.send_errors
    }

    /// PReq -> PRes turnaround (reception of the PReq to the return of the PRes `send`) of
    /// the last [`SampleWindow::CAPACITY`] PReq.
    pub fn turnaround(&self) -> Percentiles {
        self.turnaround.percentiles()
    }

    /// For each stop: from the supervisor's decision to the PRes that published it (up to
    /// one cycle: the node speaks when the MN polls it), ns.
    pub fn stop_published_ns(&self) -> &[u64] {
        &self.stop_published_ns
    }
}
