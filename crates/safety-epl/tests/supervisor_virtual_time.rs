//! The supervisor service (`OnlineSupervisor::run`, the loop `motus safety run` and the
//! station run, with its lease target and integrity watcher) in the loop of the simulated
//! juggler on the in-process segment, on VIRTUAL time: the MN, the supervisor, the watcher,
//! a monitor and the test take part in one threaded `VirtualClock`. The shipped 400 us rules
//! run as they are (no host jitter to allow for), and what is asserted is exact: which rule
//! stops the machine, the reaction (0 on virtual time: the stop leaves in the instant of the
//! frame), the cycle the drives' lease runs out in, the instant a silent segment is noticed.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_clock::{Clock, SharedClock, VirtualClock};
use motus_epl::sim::pdo::{STATUS_HOMED, STATUS_LEASE_STOP};
use motus_epl::sim::{MnConfig, Segment};
use motus_epl::transport::MemHub;
use motus_epl::{Monitor, MonitorConfig};
use motus_epl_protocol::Value;
use motus_epl_protocol::{EplFrame, MacAddr, Message, PRes, SafetyLease, SafetyNodeTiming};
use motus_realtime::{mailbox, MailboxSender};
use motus_safety::{Restart, RuleSet, JUGGLER_DRIVES_TOML, JUGGLER_TOML};
use motus_safety_epl::juggler::{self, Pattern};
use motus_safety_epl::{
    Command, EplLeaseTarget, InputMap, IntegrityWatcher, OnlineConfig, OnlineEvent, OnlineSupervisor,
    SafetyNode, SafetyNodeConfig, ServeEvent,
};

/// The juggler's cycle (the shipped rules' `cycle_time`).
const CYCLE: Duration = Duration::from_micros(400);
/// The lease the supervisor grants the drives on the wire, and the drives' own lease time.
const WIRE_LEASE: Duration = Duration::from_millis(20);
/// The thrower's upper limit in raw units (3400 units * raw_per_unit 10).
const THROWER_LIMIT_RAW: i32 = 34_000;

/// One monitored cycle: its SoC instant, the thrower's position, every speed and status word.
#[derive(Debug, Clone, PartialEq)]
struct Cycle {
    soc: Instant,
    thrower: i32,
    speeds: Vec<i32>,
    status: Vec<u16>,
}

/// Sets a stop flag when dropped (a failing test must not leave threads going on the clock).
struct StopOnDrop(Arc<AtomicBool>);

impl Drop for StopOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

struct Rig {
    clock: VirtualClock,
    hub: MemHub,
    segment: Option<Segment>,
    stop_sup: StopOnDrop,
    sup: Option<JoinHandle<OnlineSupervisor>>,
    commands: MailboxSender<Command>,
    /// The supervisor's events (passes left out) with the instant of each.
    events: Arc<Mutex<Vec<(Instant, ServeEvent)>>>,
    /// The instant of the supervisor's last pass.
    last_pass: Arc<Mutex<Option<Instant>>>,
    trace: Arc<Mutex<Vec<Cycle>>>,
    _stop_others: StopOnDrop,
    others: Vec<JoinHandle<()>>,
    wall: std::time::Instant,
}

/// What the supervisor starts with.
enum Integrity {
    /// Checked by the test (no files).
    Ok,
    /// An `IntegrityWatcher` on these files, checking every period.
    Watched(motus_safety::ConfigFiles, Duration),
}

fn rig(label: &str, pattern: Pattern, restart: Restart, integrity: Integrity) -> Rig {
    rig_with(label, pattern, restart, integrity, None)
}

/// [`rig`], with the supervisor as safety node `safety_node` (its PRes carries SafeToRun;
/// the drives read it there) instead of the lease ASnd.
fn rig_with(
    label: &str,
    pattern: Pattern,
    restart: Restart,
    integrity: Integrity,
    safety_node: Option<u8>,
) -> Rig {
    let wall = std::time::Instant::now();
    let rules = RuleSet::from_toml(JUGGLER_TOML).unwrap();
    assert_eq!(rules.config().supervisor.cycle_time, CYCLE.as_secs_f64());
    let clock = VirtualClock::threaded();
    let shared: SharedClock = clock.shared();
    let hub = MemHub::with_clock(label, Arc::clone(&shared));
    let stop_others = Arc::new(AtomicBool::new(false));
    let mut others = Vec::new();

    // The monitor: what really happened on the wire, cycle by cycle.
    let map = juggler::value_map(&rules);
    let trace = Arc::new(Mutex::new(Vec::new()));
    {
        let (link, stop, trace, map, clock) =
            (hub.connect(), Arc::clone(&stop_others), Arc::clone(&trace), map.clone(), clock.clone());
        others.push(
            motus_clock::spawn(&shared, std::thread::Builder::new().name("monitor".into()), move || {
                let mut m = Monitor::new(map, MonitorConfig { stale_after: 1 });
                m.run(&link, &stop, |s| {
                    let get = |node: u8, name: &str| s.node(node).and_then(|n| n.value(name));
                    if let Some(Value::I32(thrower)) = get(5, "position") {
                        let speeds = (1..=5)
                            .map(|n| match get(n, "speed") {
                                Some(Value::I32(v)) => v,
                                _ => i32::MAX,
                            })
                            .collect();
                        let status = (1..=5)
                            .map(|n| match get(n, "status") {
                                Some(Value::U16(v)) => v,
                                _ => 0,
                            })
                            .collect();
                        // Reported at the next SoC, one cycle after its own.
                        let soc = clock.now() - Duration::from_nanos(s.report.duration_ns.unwrap_or(0));
                        trace.lock().unwrap().push(Cycle { soc, thrower, speeds, status });
                    }
                    ControlFlow::Continue(())
                })
                .unwrap();
            })
            .unwrap(),
        );
    }

    // The supervisor, as `motus safety run` builds it, on the virtual clock.
    let sup_link: Arc<dyn motus_epl::EthLink> = Arc::new(hub.connect());
    let origin = clock.now();
    let renew = Duration::from_secs_f64(rules.config().supervisor.cycle_time);
    let inputs = InputMap::new(&rules, map, STATUS_HOMED).unwrap();
    let config = OnlineConfig { restart, ..OnlineConfig::default() };
    let mut sup = match safety_node {
        None => {
            let target = EplLeaseTarget::new(Arc::clone(&sup_link), origin, WIRE_LEASE, renew, [0; 8])
                .with_clock(Arc::clone(&shared));
            OnlineSupervisor::new(rules.clone(), inputs, vec![Box::new(target)], origin, config)
        }
        Some(node_id) => {
            let node_config = SafetyNodeConfig {
                node_id,
                timing: SafetyNodeTiming { cycle: CYCLE, soc_tolerance: CYCLE },
                wire_lease: WIRE_LEASE,
                fingerprint: [0; 8],
            };
            let (node, target) =
                SafetyNode::new(&node_config, Arc::clone(&sup_link), Arc::clone(&shared), origin).unwrap();
            OnlineSupervisor::new(rules.clone(), inputs, vec![Box::new(target)], origin, config)
                .with_safety_node(node)
        }
    }
    .with_clock(Arc::clone(&shared));
    let (commands, rx) = mailbox();
    match integrity {
        Integrity::Ok => sup.set_integrity(Ok(())),
        Integrity::Watched(files, every) => {
            let watcher = IntegrityWatcher::new(files, every).with_clock(Arc::clone(&shared));
            let stop = Arc::clone(&stop_others);
            others.push(watcher.spawn("integrity", commands.clone(), stop).unwrap());
        }
    }
    let stop_sup = Arc::new(AtomicBool::new(false));
    let events = Arc::new(Mutex::new(Vec::new()));
    let last_pass = Arc::new(Mutex::new(None));
    let handle = {
        let (stop, events, last_pass, clock) =
            (Arc::clone(&stop_sup), Arc::clone(&events), Arc::clone(&last_pass), clock.clone());
        motus_clock::spawn(&shared, std::thread::Builder::new().name("supervisor".into()), move || {
            sup.run(&*sup_link, &rx, &stop, Duration::from_millis(1), |_, e| {
                if *e == ServeEvent::Pass {
                    *last_pass.lock().unwrap() = Some(clock.now());
                } else {
                    events.lock().unwrap().push((clock.now(), e.clone()));
                }
                ControlFlow::Continue(())
            })
            .unwrap();
            sup
        })
        .unwrap()
    };

    // The segment: the juggler's drives, which run only under the supervisor's lease.
    let mut b = Segment::builder()
        .clock(Arc::clone(&shared))
        .config(MnConfig { cycle: CYCLE, pres_timeout: Duration::from_micros(150), ..MnConfig::default() })
        .mn_link(Arc::new(hub.connect()))
        .program(Box::new(juggler::program(&rules, pattern)));
    for (node, mut params) in juggler::drives(&rules, pattern, Some(WIRE_LEASE)) {
        params.safety_node = safety_node;
        b = b.drive(node, Arc::new(hub.connect()), params);
    }
    if let Some(n) = safety_node {
        b = b.polled_node(n);
    }
    let segment = b.start().unwrap();
    assert!(segment.wait_operational(Duration::from_secs(2)), "{label}: MN {}", segment.mn_state());
    eprintln!("{label}: OPERATIONAL after {:?} of virtual time", clock.since_base());
    Rig {
        clock,
        hub,
        segment: Some(segment),
        stop_sup: StopOnDrop(stop_sup),
        sup: Some(handle),
        commands,
        events,
        last_pass,
        trace,
        _stop_others: StopOnDrop(stop_others),
        others,
        wall,
    }
}

impl Rig {
    /// Waits until half a cycle after the next cycle's start (the MN's cycles start on the
    /// grid `base + k * CYCLE`): the test acts between cycles, never in the instant of one.
    fn between_cycles(&self) {
        let c = CYCLE.as_nanos() as u64;
        let next = (self.clock.since_base().as_nanos() as u64 / c + 1) * c + c / 2;
        self.clock.sleep_until(self.clock.base() + Duration::from_nanos(next));
    }

    /// One more link on the segment (for a test's own node).
    fn forger_link(&self) -> motus_epl::transport::MemLink {
        self.hub.connect()
    }

    fn events(&self) -> Vec<(Instant, ServeEvent)> {
        self.events.lock().unwrap().clone()
    }

    fn trace(&self) -> Vec<Cycle> {
        self.trace.lock().unwrap().clone()
    }

    fn since(&self, t: Instant) -> Duration {
        t.saturating_duration_since(self.clock.base())
    }

    /// Stops everything; returns the supervisor.
    fn finish(mut self, label: &str) -> OnlineSupervisor {
        let end = self.clock.since_base();
        self.stop_sup.0.store(true, Ordering::Relaxed);
        self._stop_others.0.store(true, Ordering::Relaxed);
        let sup = self.sup.take().unwrap();
        let sup = motus_clock::while_blocked(&self.clock, || sup.join()).unwrap();
        drop(self.segment.take());
        for t in self.others.drain(..) {
            motus_clock::while_blocked(&self.clock, || t.join()).unwrap();
        }
        eprintln!("{label}: {end:?} of virtual time in {:?} of wall time", self.wall.elapsed());
        sup
    }
}

/// The unsafe events: (instant, diagnosis, reaction).
fn unsafe_events(events: &[(Instant, ServeEvent)]) -> Vec<(Instant, String, Option<Duration>)> {
    events
        .iter()
        .filter_map(|(t, e)| match e {
            ServeEvent::Online(OnlineEvent::Unsafe { diagnosis, reaction, .. }) => {
                Some((*t, diagnosis.clone(), *reaction))
            }
            _ => None,
        })
        .collect()
}

/// The unsafe events that stopped the drives (a frame's reaction measured); the others are
/// SafeToRun falling again while the drives are already stopped and held.
fn stops_by_frames(events: &[(Instant, ServeEvent)]) -> Vec<(Instant, String, Option<Duration>)> {
    unsafe_events(events).into_iter().filter(|(_, _, reaction)| reaction.is_some()).collect()
}

#[test]
fn the_thrower_is_stopped_before_its_limit_and_runs_again_after_a_reset() {
    let label = "vt limit";
    let rig = rig(label, Pattern::Limit, Restart::Manual, Integrity::Ok);
    // The cam reaches the limit within half a period (1 s).
    rig.clock.sleep(Duration::from_millis(800));
    let events = rig.events();
    for (t, why, reaction) in &unsafe_events(&events) {
        eprintln!("{label}: unsafe at {:?}: {why} (reaction {reaction:?})", rig.since(*t));
    }
    // Stopped at the start-up (no data yet), then by the rule, and by nothing else.
    let stops = stops_by_frames(&events);
    assert_eq!(stops.len(), 2, "{label}: {events:?}");
    assert!(stops[0].1.ends_with("no data"), "{label}: the start-up stop: {}", stops[0].1);
    let (at, why, reaction) = &stops[1];
    assert!(why.starts_with("rule limits_thrower"), "{label}: {why}");
    // The stop leaves in the instant of the frame that made the state unsafe.
    assert_eq!(*reaction, Some(Duration::ZERO), "{label}");
    let trace = rig.trace();
    let max = trace.iter().map(|c| c.thrower).max().unwrap();
    eprintln!("{label}: thrower max {max} raw (limit {THROWER_LIMIT_RAW}) over {} cycles", trace.len());
    assert!(max < THROWER_LIMIT_RAW, "{label}: the thrower passed its limit: {max} raw");
    // The revoke leaves in the instant of the thrower's PRes, after every PRes of that cycle:
    // every drive shows the lease stop in its PRes of the next cycle, then comes to rest and
    // stays there.
    let first_lease_stop = trace
        .iter()
        .position(|c| c.soc > *at && c.status.iter().any(|s| s & STATUS_LEASE_STOP != 0))
        .unwrap();
    eprintln!(
        "{label}: lease stop on the wire from the cycle of {:?}",
        rig.since(trace[first_lease_stop].soc)
    );
    assert_eq!(trace[first_lease_stop].soc, *at + CYCLE, "{label}");
    assert!(trace[first_lease_stop].status.iter().all(|s| s & STATUS_LEASE_STOP != 0), "{label}");
    let last = trace.last().unwrap();
    assert!(last.speeds.iter().all(|v| *v == 0), "{label}: speeds {:?}", last.speeds);
    assert!(last.status.iter().all(|s| s & STATUS_LEASE_STOP != 0), "{label}: {:?}", last.status);

    // Manual restart: the operator's reset through the loop's command channel releases the
    // drives, and the program is stopped by the rule again.
    rig.between_cycles();
    let reset_at = rig.clock.now();
    rig.commands.send(Command::Reset).unwrap();
    // The cam comes back to the limit 1.19 s later.
    rig.clock.sleep(Duration::from_millis(1250));
    let after: Vec<(Instant, ServeEvent)> = rig.events().into_iter().filter(|(t, _)| *t > reset_at).collect();
    for (t, e) in &after {
        eprintln!("{label}: after the reset, at {:?}: {e:?}", rig.since(*t));
    }
    assert_eq!(after.first().map(|(_, e)| e), Some(&ServeEvent::Reset), "{label}");
    assert!(after[0].0 <= reset_at + CYCLE, "{label}: the reset is applied at the next pass");
    assert!(
        matches!(after.get(1), Some((_, ServeEvent::Online(OnlineEvent::Safe { held: false, .. })))),
        "{label}: released"
    );
    let again = stops_by_frames(&after);
    assert_eq!(again.len(), 1, "{label}: {after:?}");
    assert!(again[0].1.starts_with("rule limits_thrower"), "{label}: {}", again[0].1);
    assert_eq!(again[0].2, Some(Duration::ZERO), "{label}");
    let max = rig.trace().iter().map(|c| c.thrower).max().unwrap();
    assert!(max < THROWER_LIMIT_RAW, "{label}: the thrower passed its limit: {max} raw");
    let sup = rig.finish(label);
    assert_eq!(sup.stops(), 3, "{label}: start-up, the limit, the limit again");
    assert_eq!(sup.reaction().samples_ns.len(), 3, "{label}");
    assert!(sup.reaction().samples_ns.iter().all(|r| *r == 0), "{label}: {:?}", sup.reaction().samples_ns);
}

/// What a run recorded, in virtual time since the clock's base: the monitored cycles (SoC
/// instant, thrower, speeds, status words) and the supervisor's events.
type Record = (Vec<(Duration, i32, Vec<i32>, Vec<u16>)>, Vec<(Duration, ServeEvent)>);

fn record(rig: &Rig) -> Record {
    let trace = rig.trace().into_iter().map(|c| (rig.since(c.soc), c.thrower, c.speeds, c.status)).collect();
    let events = rig.events().into_iter().map(|(t, e)| (rig.since(t), e)).collect();
    (trace, events)
}

#[test]
fn the_drives_stop_on_their_own_when_the_supervisor_dies() {
    the_supervisor_dies("vt supervisor dies");
}

#[test]
fn a_run_on_virtual_time_is_the_same_every_time() {
    let first = the_supervisor_dies("vt same run 1");
    let second = the_supervisor_dies("vt same run 2");
    assert_eq!(first.0.len(), second.0.len(), "cycles monitored");
    assert!(first == second, "the two runs differ");
}

fn the_supervisor_dies(label: &str) -> Record {
    let rig = rig(label, Pattern::Juggle, Restart::Manual, Integrity::Ok);
    rig.clock.sleep(Duration::from_millis(400));
    let events = rig.events();
    // Juggling is safe: the start-up stop (no data yet), released once every axis reported.
    let stops = unsafe_events(&events);
    assert_eq!(stops.len(), 1, "{label}: {events:?}");
    let trace = rig.trace();
    assert!(trace.iter().rev().take(100).any(|c| c.speeds.iter().any(|v| *v != 0)), "{label}: not moving");
    assert!(
        trace.iter().rev().take(900).all(|c| c.status.iter().all(|s| s & STATUS_LEASE_STOP == 0)),
        "{label}"
    );

    // The supervisor ends (no more renewals). Its last pass renewed the lease; the drives
    // run on it for exactly the wire lease, then quick-stop at the next SoC.
    rig.between_cycles();
    let killed_at = rig.clock.now();
    rig.stop_sup.0.store(true, Ordering::Relaxed);
    rig.clock.sleep(Duration::from_millis(300));
    let last_pass = rig.last_pass.lock().unwrap().unwrap();
    eprintln!("{label}: killed at {:?}, last pass at {:?}", rig.since(killed_at), rig.since(last_pass));
    assert!(last_pass > killed_at && last_pass <= killed_at + CYCLE, "{label}: the pass of the next frame");
    let trace = rig.trace();
    let after: Vec<&Cycle> = trace.iter().filter(|c| c.soc > killed_at).collect();
    let first_stop = after.iter().position(|c| c.status.iter().any(|s| s & STATUS_LEASE_STOP != 0)).unwrap();
    let lease_out = after[first_stop].soc;
    eprintln!(
        "{label}: lease stop from the SoC at {:?}: {:?} after the last renewal",
        rig.since(lease_out),
        lease_out - last_pass
    );
    assert_eq!(lease_out - last_pass, WIRE_LEASE, "{label}: the drives ran on their lease, not a cycle more");
    assert!(after[first_stop].status.iter().all(|s| s & STATUS_LEASE_STOP != 0), "{label}: every drive");
    let at_rest = after.iter().position(|c| c.speeds.iter().all(|v| *v == 0)).unwrap();
    eprintln!("{label}: every drive at rest {} cycles after the lease ran out", at_rest - first_stop);
    assert!(at_rest > first_stop, "{label}");
    assert!(
        after[at_rest..].iter().all(|c| c.speeds.iter().all(|v| *v == 0)),
        "{label}: a drive moved again"
    );
    let record = record(&rig);
    rig.finish(label);
    record
}

#[test]
fn a_silent_segment_lets_the_supervisors_lease_expire_and_stops() {
    let label = "vt silent segment";
    let mut rig = rig(label, Pattern::Juggle, Restart::Manual, Integrity::Ok);
    rig.clock.sleep(Duration::from_millis(200));
    rig.between_cycles();
    let before = rig.events().len();
    let stopped_at = rig.clock.now();
    // The MN stops after one more cycle: no frame at all from then on.
    rig.segment.take().unwrap().stop();
    rig.clock.sleep(Duration::from_millis(50));
    // The monitor reports a cycle at the next SoC: the last cycle, after the stop, is not in
    // its trace, and came one cycle after the last one there.
    let last_soc = rig.trace().iter().map(|c| c.soc).max().unwrap() + CYCLE;
    let events = rig.events();
    let new = &events[before..];
    eprintln!("{label}: segment stopped at {:?}: {new:?}", rig.since(stopped_at));
    let stops = unsafe_events(new);
    assert_eq!(stops.len(), 1, "{label}: {new:?}");
    let (at, why, reaction) = &stops[0];
    assert_eq!(why, "no data from the segment: SafeToRun lease expired", "{label}");
    assert_eq!(*reaction, None, "{label}: a lease expiry, not a frame");
    // The last cycle is the one after the stop (at most one cycle later); its frames all
    // come in its SoC's instant on virtual time, so the lease (0.8 ms) runs out between the
    // supervisor's 1 ms polls, and the first poll after it stops the drives.
    eprintln!("{label}: last SoC at {:?}, stop at {:?}", rig.since(last_soc), rig.since(*at));
    assert!(last_soc > stopped_at, "{label}");
    assert_eq!(*at - last_soc, Duration::from_millis(1), "{label}: one poll after the last frame");
    let sup = rig.finish(label);
    assert_eq!(sup.stops(), 2, "{label}: start-up and the expiry");
}

#[test]
fn an_unapproved_change_on_disk_stops_the_drives_at_the_next_check() {
    let label = "vt integrity";
    let dir = tempfile::tempdir().unwrap();
    let files = motus_safety::ConfigFiles {
        rules: dir.path().join("juggler.toml"),
        drives: Some(dir.path().join("drives.toml")),
        approval: dir.path().join("juggler.approved"),
        key: dir.path().join("admin.key"),
    };
    std::fs::write(&files.rules, JUGGLER_TOML).unwrap();
    std::fs::write(files.drives.as_ref().unwrap(), JUGGLER_DRIVES_TOML).unwrap();
    std::fs::write(&files.key, "an-administrator-key-0123456789").unwrap();
    let (_, snapshot) =
        motus_safety::config_files::read_snapshot(&files.rules, files.drives.as_deref()).unwrap();
    let key = motus_safety::config_files::read_key(&files.key).unwrap();
    motus_safety::config_files::approve(&snapshot, "alice", "test", &key, &files.approval).unwrap();
    // A period off the cycle grid (100.001 ms): each check falls between two cycles.
    let every = Duration::from_micros(100_001);
    let rig = rig(label, Pattern::Juggle, Restart::Manual, Integrity::Watched(files.clone(), every));
    rig.clock.sleep(Duration::from_millis(250));
    let events = rig.events();
    // The check at start-up (applied at the first pass): integrity OK; the start-up stop,
    // then the release.
    assert_eq!(events.first().map(|(_, e)| e), Some(&ServeEvent::Integrity(Ok(()))), "{label}: {events:?}");
    assert_eq!(unsafe_events(&events).len(), 1, "{label}: {events:?}");
    assert!(matches!(events.last(), Some((_, ServeEvent::Online(OnlineEvent::Safe { held: false, .. })))));

    // A drive parameter changed on disk without approval.
    rig.between_cycles();
    let changed_at = rig.clock.now();
    let drives = files.drives.as_ref().unwrap();
    std::fs::write(drives, JUGGLER_DRIVES_TOML.replacen("homing_mode = 0", "homing_mode = 7", 1)).unwrap();
    rig.clock.sleep(Duration::from_millis(200));
    let new: Vec<(Instant, ServeEvent)> = rig.events().into_iter().filter(|(t, _)| *t > changed_at).collect();
    eprintln!("{label}: changed at {:?}: {new:?}", rig.since(changed_at));
    // The next check is at the next multiple of the period; its result is applied at the
    // supervisor's next pass (the next frame, the SoC of the next cycle), which stops the
    // drives in the same pass.
    let k = (rig.since(changed_at).as_nanos() / every.as_nanos() + 1) as u32;
    let check = rig.clock.base() + every * k;
    let c = CYCLE.as_nanos() as u64;
    let next_soc = rig.clock.base() + Duration::from_nanos((rig.since(check).as_nanos() as u64 / c + 1) * c);
    match &new[..] {
        [(t1, ServeEvent::Integrity(Err(why))), (t2, ServeEvent::Online(OnlineEvent::Unsafe { diagnosis, reaction, .. }))] =>
        {
            assert!(why.contains("drive[arm_left].homing_mode: 0 -> 7"), "{label}: {why}");
            assert_eq!(diagnosis, why, "{label}");
            assert_eq!((*t1, *t2), (next_soc, next_soc), "{label}: check at {:?}", rig.since(check));
            assert_eq!(*reaction, Some(Duration::ZERO), "{label}");
        }
        other => panic!("{label}: {other:?}"),
    }
    let sup = rig.finish(label);
    assert!(sup.integrity_checks() >= 4, "{label}: {}", sup.integrity_checks());
}

/// The supervisor's node ID as a safety node (polled after the drives 1..=5).
const SAFETY_NODE: u8 = 100;

#[test]
fn as_a_safety_node_the_supervisor_stops_the_thrower_through_its_pres() {
    let label = "vt safety node limit";
    let rig = rig_with(label, Pattern::Limit, Restart::Manual, Integrity::Ok, Some(SAFETY_NODE));
    rig.clock.sleep(Duration::from_millis(800));
    let events = rig.events();
    let stops = stops_by_frames(&events);
    assert_eq!(stops.len(), 2, "{label}: {events:?}");
    let (at, why, _) = &stops[1];
    assert!(why.starts_with("rule limits_thrower"), "{label}: {why}");
    let trace = rig.trace();
    let max = trace.iter().map(|c| c.thrower).max().unwrap();
    eprintln!("{label}: thrower max {max} raw (limit {THROWER_LIMIT_RAW})");
    assert!(max < THROWER_LIMIT_RAW, "{label}: the thrower passed its limit: {max} raw");
    // The node is polled after the drives: its PRes of the same cycle carries the stop, and
    // every drive brakes from the next SoC, as with the lease ASnd.
    let first_lease_stop = trace
        .iter()
        .position(|c| c.soc > *at && c.status.iter().any(|s| s & STATUS_LEASE_STOP != 0))
        .unwrap();
    assert_eq!(trace[first_lease_stop].soc, *at + CYCLE, "{label}");
    assert!(trace[first_lease_stop].status.iter().all(|s| s & STATUS_LEASE_STOP != 0), "{label}");
    let last = trace.last().unwrap();
    assert!(last.speeds.iter().all(|v| *v == 0), "{label}: speeds {:?}", last.speeds);
    let sup = rig.finish(label);
    let node = sup.safety_node().unwrap();
    eprintln!(
        "{label}: {} PRes; stops published {:?} ns after the decision",
        node.pres_sent(),
        node.stop_published_ns()
    );
    // Both stops (start-up, the limit) published, each in the PRes of the cycle of the decision
    // or, for the start-up stop decided while the node was booting, its first PRes.
    assert_eq!(node.stop_published_ns().len(), 2, "{label}");
    assert!(node.stop_published_ns()[1] < CYCLE.as_nanos() as u64, "{label}");
}

/// A node that is not the safety node forging leases every cycle: lease ASnds from node 253
/// and from the safety node's ID, and a PRes from node 101 with a safe lease body.
fn forge_leases(hub_link: motus_epl::transport::MemLink, clock: SharedClock, stop: Arc<AtomicBool>) {
    let mut seq = 0u16;
    let send = |src: u8, message: Message| {
        let frame = EplFrame::new(MacAddr([2, 0, 0, 0, 0, src]), MacAddr::BROADCAST, 255, src, message);
        motus_epl::EthLink::send(&hub_link, &frame.encode().unwrap()).unwrap();
    };
    while !stop.load(Ordering::Relaxed) {
        seq = seq.wrapping_add(1);
        let lease = SafetyLease { safe: true, seq, valid_for_us: 1_000_000, fingerprint: [0; 8] };
        send(253, Message::Asnd(lease.to_asnd()));
        send(SAFETY_NODE, Message::Asnd(lease.to_asnd()));
        let pres = PRes {
            nmt_state: motus_epl_protocol::NmtState::Operational,
            flags: motus_epl_protocol::Flags::RD,
            pr_rs: motus_epl_protocol::PrRs::default(),
            pdo_version: 0,
            payload: lease.encode().to_vec(),
            reserved: 0,
        };
        send(101, Message::PRes(pres));
        clock.sleep(CYCLE / 2);
    }
}

#[test]
fn killing_the_safety_node_stops_the_drives_and_forged_leases_do_not_help() {
    let label = "vt safety node dies";
    let rig = rig_with(label, Pattern::Juggle, Restart::Manual, Integrity::Ok, Some(SAFETY_NODE));
    rig.clock.sleep(Duration::from_millis(400));
    let trace = rig.trace();
    assert!(trace.iter().rev().take(100).any(|c| c.speeds.iter().any(|v| *v != 0)), "{label}: not moving");
    assert!(
        trace.iter().rev().take(900).all(|c| c.status.iter().all(|s| s & STATUS_LEASE_STOP == 0)),
        "{label}: juggling runs under the safety node's PRes"
    );
    // A forger joins the segment, then the supervisor ends.
    let hub_link = rig.forger_link();
    let stop_forger = Arc::new(AtomicBool::new(false));
    let forger = {
        let (clock, stop) = (rig.clock.shared(), Arc::clone(&stop_forger));
        motus_clock::spawn(
            &rig.clock.shared(),
            std::thread::Builder::new().name("forger".into()),
            move || forge_leases(hub_link, clock, stop),
        )
        .unwrap()
    };
    rig.between_cycles();
    let killed_at = rig.clock.now();
    rig.stop_sup.0.store(true, Ordering::Relaxed);
    rig.clock.sleep(Duration::from_millis(300));
    let last_pass = rig.last_pass.lock().unwrap().unwrap();
    let trace = rig.trace();
    let after: Vec<&Cycle> = trace.iter().filter(|c| c.soc > killed_at).collect();
    let first_stop = after.iter().position(|c| c.status.iter().any(|s| s & STATUS_LEASE_STOP != 0)).unwrap();
    let lease_out = after[first_stop].soc;
    eprintln!("{label}: lease stop {:?} after the supervisor's last pass", lease_out - last_pass);
    // The last renewal is the node's last PRes, in the cycle of the last pass.
    assert!(lease_out >= last_pass + WIRE_LEASE - CYCLE, "{label}");
    assert!(lease_out <= last_pass + WIRE_LEASE + CYCLE, "{label}: the forged leases kept the drives going");
    assert!(after[first_stop].status.iter().all(|s| s & STATUS_LEASE_STOP != 0), "{label}: every drive");
    let at_rest = after.iter().position(|c| c.speeds.iter().all(|v| *v == 0)).unwrap();
    assert!(
        after[at_rest..].iter().all(|c| c.speeds.iter().all(|v| *v == 0)),
        "{label}: a drive moved again"
    );
    stop_forger.store(true, Ordering::Relaxed);
    motus_clock::while_blocked(&rig.clock, || forger.join()).unwrap();
    rig.finish(label);
}
