//! The reaction scenario on veth (needs root), shared by `tests/veth_reaction.rs` (function:
//! every unsafe event answered by one revoke) and `benches/reaction.rs` (the figures: 10,000
//! events, p99 inside Motus against the 1 ms target, run by `scripts/realtime.sh`).
//!
//! Two veth ports on a bridge in network namespaces. A stimulus port plays the segment (SoC
//! and the five drives' PRes, all safe), then one PRes that puts the thrower beyond its limit;
//! the supervisor's port must answer with a safety-lease revoke. Two figures per event:
//! * inside Motus: from the reception of the unsafe PRes (when `recv` returned) to the revoke
//!   handed to the kernel (`send` returned) — "from the arrival of the PRes to the quick-stop
//!   action leaving Motus";
//! * end to end: from the stimulus's `send` of the PRes to its reception of the revoke (two
//!   veth hops and the bridge, twice the kernel).
//!
//! "Inside" is the larger figure at the median: a veth `send` returns only after the kernel
//! has carried the frame across the bridge into the receiving socket and woken its reader
//! (the softirq runs in the sender's context), so it includes the revoke's delivery.
//!
//! The stimulus reads the start-up stop's revoke before the first event and checks that no
//! revoke is left over before each: it waits for its own event's answer, never an older one.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, dead_code)]

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use motus_epl::netns::BridgedPorts;
use motus_epl::sim::Percentiles;
use motus_epl::EthLink;
use motus_epl_protocol::{EplFrame, Flags, MacAddr, Message, NmtState, PRes, PrRs, SafetyLease, Soc};
use motus_safety::{RuleSet, JUGGLER_TOML};
use motus_safety_epl::juggler;
use motus_safety_epl::{EplLeaseTarget, InputMap, OnlineConfig, OnlineEvent, OnlineSupervisor, ServeEvent};

/// How long the stimulus waits for an event's revoke (liveness only: a revoke takes about
/// 100 us; a host that holds a thread off the CPU longer than this is broken, not loaded).
pub const REVOKE_TIMEOUT: Duration = Duration::from_secs(5);

fn pres(mac: MacAddr, node: u8, position: i32) -> Vec<u8> {
    let mut payload = vec![0u8; 24];
    payload[0] = 0x11; // enabled, homed
    payload[16..20].copy_from_slice(&position.to_le_bytes());
    let m = Message::PRes(PRes {
        nmt_state: NmtState::Operational,
        flags: Flags::RD,
        pr_rs: PrRs::default(),
        pdo_version: 0,
        payload,
        reserved: 0,
    });
    EplFrame::new(mac, MacAddr::BROADCAST, 255, node, m).encode().unwrap()
}

fn soc(mac: MacAddr, relative_us: u64) -> Vec<u8> {
    let m = Message::Soc(Soc {
        flags: Flags::empty(),
        net_time: Default::default(),
        relative_time: relative_us,
        reserved1: 0,
        reserved2: 0,
    });
    EplFrame::new(mac, MacAddr::BROADCAST, 255, 240, m).encode().unwrap()
}

/// True if `bytes` is a safety-lease revoke.
fn is_revoke(bytes: &[u8]) -> bool {
    matches!(EplFrame::decode(bytes), Ok(f) if matches!(&f.message,
        Message::Asnd(a) if SafetyLease::from_asnd(a).is_some_and(|l| !l.safe)))
}

/// Waits for a revoke on `link` up to `timeout`; its reception time.
fn wait_revoke(link: &dyn EthLink, buf: &mut [u8], timeout: Duration) -> Option<Instant> {
    let end = Instant::now() + timeout;
    while Instant::now() < end {
        if let Some((n, at)) = link.recv(buf, Duration::from_millis(50)).unwrap() {
            if is_revoke(&buf[..n]) {
                return Some(at);
            }
        }
    }
    None
}

/// Reads what is already queued on `link`; the number of revokes among it.
fn drain_revokes(link: &dyn EthLink, buf: &mut [u8]) -> usize {
    let mut revokes = 0;
    while let Some((n, _)) = link.recv(buf, Duration::ZERO).unwrap() {
        revokes += usize::from(is_revoke(&buf[..n]));
    }
    revokes
}

/// What a run of [`run`] measured.
pub struct Reaction {
    /// Unsafe events sent.
    pub events: usize,
    /// Inside Motus: unsafe PRes received -> revoke `send` returned (ns).
    pub inside: Percentiles,
    /// End to end: stimulus `send` -> revoke received (ns).
    pub end_to_end: Percentiles,
    /// Events whose revoke did not come within [`REVOKE_TIMEOUT`].
    pub missed: usize,
    /// Revokes no event caused.
    pub stale: usize,
    /// Stops by the supervisor (one per event plus the start-up's).
    pub stops: u64,
    /// Lease expiries: the stimulus thread held off the CPU between a safe cycle and its
    /// unsafe PRes for longer than the lease (a loaded host).
    pub expiries: usize,
}

/// Runs `events` unsafe events on veth (needs root) and returns the figures; asserts nothing
/// about them (the callers do).
pub fn run(events: usize) -> Reaction {
    let ns = BridgedPorts::create("react", &["stim", "sup"]).unwrap();
    let links = ns.open(&["stim", "sup"]).unwrap();
    let (stim, sup_link) = (Arc::clone(&links[0]), Arc::clone(&links[1]));

    let rules = RuleSet::from_toml(JUGGLER_TOML).unwrap();
    let inputs = InputMap::new(&rules, juggler::value_map(&rules), 0x10).unwrap();
    let origin = Instant::now();
    let target = EplLeaseTarget::new(
        Arc::clone(&sup_link),
        origin,
        Duration::from_millis(20),
        Duration::from_millis(50), // few renewals: the stimulus waits for revokes only
        [0; 8],
    );
    let mut sup = OnlineSupervisor::new(
        rules,
        inputs,
        vec![Box::new(target)],
        origin,
        OnlineConfig { restart: motus_safety::Restart::Automatic, ..OnlineConfig::default() },
    );
    sup.set_integrity(Ok(()));
    let stop = Arc::new(AtomicBool::new(false));
    let sup_thread = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            // The lease check fires only when the stimulus thread is held off the CPU between
            // a safe cycle and its unsafe PRes for longer than the lease (a loaded host): that
            // expiry stops the drives and its revoke answers the event. Counted, not hidden.
            let mut expiries = 0usize;
            // No operator here: the command channel stays empty.
            let (_commands, rx) = motus_realtime::mailbox();
            sup.run(&*sup_link, &rx, &stop, Duration::from_millis(5), |_, e| {
                if matches!(e, ServeEvent::Online(OnlineEvent::Unsafe { reaction: None, diagnosis, .. }) if diagnosis.contains("lease expired")) {
                    expiries += 1;
                }
                ControlFlow::Continue(())
            })
            .unwrap();
            (sup, expiries)
        })
    };

    let mac = stim.mac();
    // Safe pose in raw units: arms -500, verticals 1000 / 10 000, thrower -7100 units (x10).
    let safe_raw = [-500, 1000, -500, 10_000, -71_000];
    let safe: Vec<Vec<u8>> = (1..=5u8).zip(safe_raw).map(|(n, p)| pres(mac, n, p)).collect();
    let unsafe_pres = pres(mac, 5, 35_000); // 3500 units: beyond the thrower's 3400 limit
    let mut buf = vec![0u8; 1518];
    let mut end_to_end = Vec::with_capacity(events);
    let mut missed = 0;
    // Start-up: the first SoC finds no data (unsafe) and stops; its revoke must be read
    // here, or every event would take the previous one's revoke for its own.
    let mut relative = 400u64;
    stim.send(&soc(mac, relative)).unwrap();
    assert!(wait_revoke(&*stim, &mut buf, REVOKE_TIMEOUT).is_some(), "no revoke for the start-up stop");
    let mut stale = 0;
    for _ in 0..events {
        // Nothing may be left over from the last event: each answer is read before the next.
        stale += drain_revokes(&*stim, &mut buf);
        // A safe cycle: SoC + five PRes (the supervisor grants SafeToRun again).
        relative += 400;
        stim.send(&soc(mac, relative)).unwrap();
        for f in &safe {
            stim.send(f).unwrap();
        }
        std::thread::sleep(Duration::from_micros(100));
        let t0 = Instant::now();
        stim.send(&unsafe_pres).unwrap();
        match wait_revoke(&*stim, &mut buf, REVOKE_TIMEOUT) {
            Some(at) => end_to_end.push(u64::try_from(at.duration_since(t0).as_nanos()).unwrap()),
            None => {
                // Not answered (a broken supervisor): the run stops here, `check` says so.
                missed += 1;
                break;
            }
        }
    }
    stop.store(true, Ordering::Relaxed);
    let (sup, expiries) = sup_thread.join().unwrap();
    drop(ns);
    Reaction {
        events,
        inside: sup.reaction().percentiles(),
        end_to_end: Percentiles::of(&end_to_end),
        missed,
        stale,
        stops: sup.stops(),
        expiries,
    }
}

impl Reaction {
    /// One line with every figure.
    pub fn summary(&self) -> String {
        let us = |ns: u64| ns as f64 / 1000.0;
        format!(
            "reaction over {} events: inside Motus p50 {:.1} us p99 {:.1} us max {:.1} us ({} measured); \
             end to end (stimulus send -> revoke received) p50 {:.1} us p99 {:.1} us max {:.1} us; missed {}; \
             lease expiries (stimulus thread held off the CPU longer than the lease) {}",
            self.events,
            us(self.inside.p50),
            us(self.inside.p99),
            us(self.inside.max),
            self.inside.count,
            us(self.end_to_end.p50),
            us(self.end_to_end.p99),
            us(self.end_to_end.max),
            self.missed,
            self.expiries,
        )
    }

    /// The functional checks: every unsafe event answered by exactly one stop.
    pub fn check(&self) {
        assert_eq!(self.missed, 0, "every unsafe PRes must be answered by a revoke");
        assert_eq!(self.stale, 0, "revokes no event caused (one stop counted twice?)");
        // One stop per unsafe event, plus the start-up SoC (no data yet: unsafe). An
        // event that came after the lease had already expired (and stopped the drives) finds
        // them stopped: its revoke is the expiry's, and it has no reaction time of its own.
        assert_eq!(self.stops, self.events as u64 + 1, "one stop per unsafe event");
        assert_eq!(
            self.inside.count + self.expiries,
            self.events + 1,
            "every stop is an unsafe event's or a lease expiry's"
        );
    }
}
