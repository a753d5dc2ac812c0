//! [`EplLeaseTarget`]: SafeToRun to every drive of the segment as a broadcast safety lease.

use std::sync::Arc;
use std::time::{Duration, Instant};

use motus_clock::{SharedClock, SystemClock};
use motus_epl::EthLink;
use motus_epl_protocol::{EplFrame, MacAddr, Message, SafetyLease, BROADCAST_NODE_ID, LEASE_ASND_NODE_ID};
use motus_safety::{Lease, StopError, StopTarget};

/// Node ID the supervisor sends from (253, POWERLINK's diagnostic device; drives take a lease
/// ASnd from this node only).
pub const SUPERVISOR_NODE_ID: u8 = LEASE_ASND_NODE_ID;

/// Broadcasts safety leases on a POWERLINK link (see the module documentation of
/// [`motus_epl_protocol::lease`]).
pub struct EplLeaseTarget {
    link: Arc<dyn EthLink>,
    origin: Instant,
    wire_lease: Duration,
    renew_every: Duration,
    last_renewal: Option<Instant>,
    fingerprint: [u8; 8],
    seq: u16,
    buf: Vec<u8>,
    clock: SharedClock,
    /// Time the last revoke left (after `send` returned).
    pub last_stop_sent: Option<Instant>,
}

impl EplLeaseTarget {
    /// A target on `link`. `origin` is the epoch of the supervisor's `now`; each renewal
    /// grants the drives `wire_lease` from its reception, and renewals are sent at most every
    /// `renew_every`.
    pub fn new(
        link: Arc<dyn EthLink>,
        origin: Instant,
        wire_lease: Duration,
        renew_every: Duration,
        fingerprint: [u8; 8],
    ) -> Self {
        Self {
            link,
            origin,
            wire_lease,
            renew_every,
            last_renewal: None,
            fingerprint,
            seq: 0,
            buf: Vec::with_capacity(64),
            clock: SystemClock::shared(),
            last_stop_sent: None,
        }
    }

    /// Takes the time of renewals and revokes from `clock` (the supervisor's; `origin` is an
    /// instant of it) instead of the system clock.
    #[must_use]
    pub fn with_clock(mut self, clock: SharedClock) -> Self {
        self.clock = clock;
        self
    }

    fn send(&mut self, lease: SafetyLease) -> Result<(), StopError> {
        let frame = EplFrame::new(
            self.link.mac(),
            MacAddr::BROADCAST,
            BROADCAST_NODE_ID,
            SUPERVISOR_NODE_ID,
            Message::Asnd(lease.to_asnd()),
        );
        self.buf.clear();
        let err = |m: String| StopError { target: self.link.describe(), message: m };
        frame.encode_into(&mut self.buf).map_err(|e| err(e.to_string()))?;
        self.link.send(&self.buf).map_err(|e| err(e.to_string()))?;
        self.seq = self.seq.wrapping_add(1);
        Ok(())
    }
}

impl StopTarget for EplLeaseTarget {
    fn name(&self) -> String {
        format!("POWERLINK safety lease on {}", self.link.describe())
    }

    fn quick_stop(&mut self) -> Result<(), StopError> {
        let r = self.send(SafetyLease::revoke(self.seq, self.fingerprint));
        self.last_stop_sent = Some(self.clock.now());
        self.last_renewal = None;
        r
    }

    fn renew(&mut self, lease: &Lease) -> Result<(), StopError> {
        let now = self.clock.now();
        if self.last_renewal.is_some_and(|t| now.duration_since(t) < self.renew_every) {
            return Ok(());
        }
        // Never grant beyond what the supervisor's own lease allows plus the wire lease.
        let left = lease.expires().saturating_sub(now.duration_since(self.origin));
        let valid = self.wire_lease.max(left);
        let wire = SafetyLease {
            safe: true,
            seq: self.seq,
            valid_for_us: u32::try_from(valid.as_micros()).unwrap_or(u32::MAX),
            fingerprint: self.fingerprint,
        };
        self.last_renewal = Some(now);
        self.send(wire)
    }
}
