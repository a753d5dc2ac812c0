#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! The supervisor in the loop of a simulated juggler, over the unprivileged UDP link on
//! loopback: drives that need the safety lease, a monitor recording what really happened.
//!
//! Function only, with generous liveness time-outs: the supervisor stops the thrower before
//! its limit, the drives stop by themselves when it dies. The false stops a loaded host causes
//! (late UDP frames making data stale) and the time the drives take to stop are printed; the
//! reaction time is measured by `cargo bench -p motus-safety-epl --bench reaction`
//! (`scripts/realtime.sh`).

use motus_realtime::{mailbox as channel, MailboxSender as Sender};
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use motus_epl::sim::{MnConfig, Segment};
use motus_epl::{EthLink, Monitor, MonitorConfig, UdpHub};
use motus_epl_protocol::Value;
use motus_safety::{RuleSet, JUGGLER_TOML};
use motus_safety_epl::juggler::{self, Pattern};
use motus_safety_epl::{
    Command, EplLeaseTarget, InputMap, OnlineConfig, OnlineEvent, OnlineSupervisor, ServeEvent,
};

/// Per cycle: (thrower raw position, every speed, every status word).
type Trace = Arc<Mutex<Vec<(i32, Vec<i32>, Vec<u16>)>>>;

struct Rig {
    _segment: Segment,
    stop_sup: Arc<AtomicBool>,
    sup: Option<std::thread::JoinHandle<OnlineSupervisor>>,
    commands: Sender<Command>,
    events: Arc<Events>,
    stop_mon: Arc<AtomicBool>,
    trace: Trace,
}

/// The supervisor's events (passes left out), with a wake-up on each.
#[derive(Default)]
struct Events {
    list: Mutex<Vec<ServeEvent>>,
    added: Condvar,
}

impl Events {
    fn push(&self, e: ServeEvent) {
        self.list.lock().unwrap().push(e);
        self.added.notify_all();
    }

    fn snapshot(&self) -> Vec<ServeEvent> {
        self.list.lock().unwrap().clone()
    }

    /// Waits until `done` holds for the events from index `from` on; returns them.
    fn wait_from(
        &self,
        from: usize,
        timeout: Duration,
        what: &str,
        done: impl Fn(&[ServeEvent]) -> bool,
    ) -> Vec<ServeEvent> {
        let list = self.list.lock().unwrap();
        let (list, r) =
            self.added.wait_timeout_while(list, timeout, |l| !done(l.get(from..).unwrap_or(&[]))).unwrap();
        let after = list.get(from..).unwrap_or(&[]).to_vec();
        assert!(!r.timed_out(), "not {what} within {timeout:?}: {after:?}");
        after
    }
}

/// The juggler's rules for a 1 ms cycle (the UDP link on a shared CI machine does not hold
/// 400 us with five drives): lease 9 cycles and data up to 15 cycles old, so a late UDP frame
/// does not stop the machine (as `motus demo`'s rules; the prediction horizon grows with the
/// data's actual age).
pub fn rules_1ms() -> RuleSet {
    let text = JUGGLER_TOML
        .replace("cycle_time = 0.0004", "cycle_time = 0.001")
        .replace("lease_time = 0.0008", "lease_time = 0.009")
        .replace("max_sample_age = 3 ", "max_sample_age = 15 ");
    assert_ne!(text, JUGGLER_TOML);
    RuleSet::from_toml(&text).unwrap()
}

fn rig(pattern: Pattern, restart: motus_safety::Restart) -> Rig {
    let rules = rules_1ms();
    let hub = UdpHub::new();
    let mut b = Segment::builder()
        .config(MnConfig { cycle: Duration::from_millis(1), ..MnConfig::default() })
        .mn_link(Arc::new(hub.connect().unwrap()))
        .program(Box::new(juggler::program(&rules, pattern)));
    for (node, params) in juggler::drives(&rules, pattern, Some(Duration::from_millis(20))) {
        b = b.drive(node, Arc::new(hub.connect().unwrap()), params);
    }
    // Monitor.
    let map = juggler::value_map(&rules);
    let mon_link: Arc<dyn EthLink> = Arc::new(hub.connect().unwrap());
    let stop_mon = Arc::new(AtomicBool::new(false));
    let trace = Arc::new(Mutex::new(Vec::new()));
    {
        let (stop, trace, map) = (Arc::clone(&stop_mon), Arc::clone(&trace), map.clone());
        std::thread::spawn(move || {
            let mut m = Monitor::new(map, MonitorConfig { stale_after: 1 });
            m.run(&*mon_link, &stop, |s| {
                let get = |node: u8, name: &str| s.node(node).and_then(|n| n.value(name));
                if let Some(Value::I32(p)) = get(5, "position") {
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
                    trace.lock().unwrap().push((p, speeds, status));
                }
                ControlFlow::Continue(())
            })
            .unwrap();
        });
    }
    // Supervisor.
    let sup_link: Arc<dyn EthLink> = Arc::new(hub.connect().unwrap());
    let origin = Instant::now();
    let target = EplLeaseTarget::new(
        Arc::clone(&sup_link),
        origin,
        Duration::from_millis(20),
        Duration::from_millis(2),
        [0; 8],
    );
    let inputs = InputMap::new(&rules, map, motus_epl::sim::pdo::STATUS_HOMED).unwrap();
    let mut sup = OnlineSupervisor::new(
        rules,
        inputs,
        vec![Box::new(target)],
        origin,
        OnlineConfig { restart, ..OnlineConfig::default() },
    );
    sup.set_integrity(Ok(()));
    let stop_sup = Arc::new(AtomicBool::new(false));
    let events = Arc::new(Events::default());
    let (commands, rx) = channel();
    let handle = {
        let (stop, events) = (Arc::clone(&stop_sup), Arc::clone(&events));
        std::thread::spawn(move || {
            sup.run(&*sup_link, &rx, &stop, Duration::from_millis(1), |_, e| {
                if *e != ServeEvent::Pass {
                    events.push(e.clone());
                }
                ControlFlow::Continue(())
            })
            .unwrap();
            sup
        })
    };
    let segment = b.start().unwrap();
    assert!(segment.wait_operational(Duration::from_secs(10)), "MN state {}", segment.mn_state());
    Rig { _segment: segment, stop_sup, sup: Some(handle), commands, events, stop_mon, trace }
}

impl Rig {
    /// Waits (liveness: `timeout`) for the first stop by a rule (with its reaction time) among
    /// the events from index `from`; returns its diagnosis and reaction. A stop by anything
    /// else holds the drives (manual restart; on a loaded host a late frame can make the data
    /// stale before the program gets far): the operator resets, as on the real machine.
    fn wait_rule_stop(&self, from: usize, timeout: Duration) -> (String, Duration) {
        let t0 = Instant::now();
        let mut seen = from;
        loop {
            let events = self.events.snapshot();
            for e in events.get(seen..).unwrap_or(&[]) {
                match e {
                    ServeEvent::Online(OnlineEvent::Unsafe { diagnosis, reaction: Some(r), .. })
                        if diagnosis.starts_with("rule ") =>
                    {
                        return (diagnosis.clone(), *r);
                    }
                    ServeEvent::Online(OnlineEvent::Safe { held: true, .. }) => {
                        eprintln!("held after a stop that was not a rule's: operator reset");
                        self.commands.send(Command::Reset).unwrap();
                    }
                    _ => {}
                }
            }
            seen = seen.max(events.len());
            assert!(t0.elapsed() < timeout, "no stop by a rule within {timeout:?}: {:?}", &events[from..]);
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Waits (liveness: `timeout`) until the monitor's latest cycle shows every drive at rest
    /// with the lease stop in its status word; returns the whole trace.
    fn wait_at_rest(&self, timeout: Duration) -> Vec<(i32, Vec<i32>, Vec<u16>)> {
        let t0 = Instant::now();
        loop {
            let trace = self.trace.lock().unwrap().clone();
            if trace.last().is_some_and(|(_, speeds, status)| {
                speeds.iter().all(|v| *v == 0)
                    && status.iter().all(|s| s & motus_epl::sim::pdo::STATUS_LEASE_STOP != 0)
            }) {
                return trace;
            }
            assert!(t0.elapsed() < timeout, "drives not at rest within {timeout:?}: {:?}", trace.last());
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.stop_sup.store(true, Ordering::Relaxed);
        self.stop_mon.store(true, Ordering::Relaxed);
    }
}

#[test]
fn student_program_beyond_the_limit_is_stopped_before_the_limit() {
    // Manual restart (the default): the drives stay stopped although the thrower at rest is
    // safe again.
    let mut rig = rig(Pattern::Limit, motus_safety::Restart::Manual);
    // The cam reaches the limit (3400 units = 34 000 raw) within half a period. The first
    // stop by a rule: `limits_thrower` as a rule, or (on a loaded host, whose late samples
    // widen the predicted reach) another axis's rule a moment earlier. Either way the thrower
    // must not pass its limit, checked below.
    let (diagnosis, reaction) = rig.wait_rule_stop(0, Duration::from_secs(30));
    eprintln!("stop: {diagnosis}; reaction {reaction:?}");
    if !diagnosis.contains("limits_thrower") {
        eprintln!("NOTE: another rule stopped the drives before limits_thrower did");
    }
    // Every drive comes to rest, with the lease stop in its status word.
    let trace = rig.wait_at_rest(Duration::from_secs(10));
    let max = trace.iter().map(|t| t.0).max().unwrap();
    eprintln!("thrower max {max} raw over {} cycles", trace.len());
    assert!(max < 34_000, "the thrower passed its limit: {max} raw");
    // The operator's reset goes through the loop's command channel: applied, the drives run
    // again (safe, no longer held), and the program is stopped again by a rule.
    let n = rig.events.snapshot().len();
    rig.commands.send(Command::Reset).unwrap();
    let after = rig.events.wait_from(n, Duration::from_secs(20), "reset and released", |after| {
        after.iter().position(|e| *e == ServeEvent::Reset).is_some_and(|i| {
            after[i..].iter().any(|e| matches!(e, ServeEvent::Online(OnlineEvent::Safe { held: false, .. })))
        })
    });
    let (again, _) = rig.wait_rule_stop(n + after.len(), Duration::from_secs(30));
    eprintln!("stopped again: {again}");
    let sup = {
        rig.stop_sup.store(true, Ordering::Relaxed);
        rig.sup.take().unwrap().join().unwrap()
    };
    assert!(sup.stops() >= 1);
    drop(rig);
}

#[test]
fn juggling_runs_and_drives_stop_on_their_own_when_the_supervisor_dies() {
    // Automatic restart: a late frame on a loaded machine must not end the run.
    let mut rig = rig(Pattern::Juggle, motus_safety::Restart::Automatic);
    std::thread::sleep(Duration::from_millis(1500));
    // The juggler moves under a valid lease (liveness: within 10 s).
    let t0 = Instant::now();
    while !rig.trace.lock().unwrap().iter().rev().take(100).any(|c| c.1.iter().any(|v| *v != 0)) {
        assert!(t0.elapsed() < Duration::from_secs(10), "the juggler should move under a valid lease");
        std::thread::sleep(Duration::from_millis(20));
    }
    let unsafe_events = rig
        .events
        .snapshot()
        .iter()
        .filter_map(|e| match e {
            ServeEvent::Online(OnlineEvent::Unsafe { diagnosis, cycle, .. }) => {
                Some(format!("{cycle}: {diagnosis}"))
            }
            _ => None,
        })
        .collect::<Vec<_>>();
    eprintln!(
        "stops while juggling: {} {:?}",
        unsafe_events.len(),
        &unsafe_events[..unsafe_events.len().min(5)]
    );
    // Only the start-up (no data before the first PRes of every axis) should be unsafe; on a
    // loaded host a late UDP frame now and then makes data stale (a false stop, which is the
    // safe side): printed above, not asserted (the host's load).
    // Kill the supervisor: no more renewals. The drives stop by themselves: the 20 ms lease
    // plus braking (< 50 ms at these speeds) plus a few cycles; waited for with a liveness
    // time-out, the time printed.
    rig.stop_sup.store(true, Ordering::Relaxed);
    rig.sup.take().unwrap().join().unwrap();
    let killed = Instant::now();
    let killed_at = rig.trace.lock().unwrap().len();
    let stopped_at = loop {
        let t = rig.trace.lock().unwrap().clone();
        if let Some(i) = t[killed_at..].iter().position(|c| c.1.iter().all(|v| *v == 0)) {
            break i;
        }
        assert!(killed.elapsed() < Duration::from_secs(10), "drives never stopped");
        std::thread::sleep(Duration::from_millis(20));
    };
    eprintln!("drives at rest {stopped_at} cycles ({:?}) after the supervisor died", killed.elapsed());
    // At rest for good: a few hundred cycles more, none moving.
    let t0 = Instant::now();
    while rig.trace.lock().unwrap().len() < killed_at + stopped_at + 300 {
        assert!(t0.elapsed() < Duration::from_secs(10), "the segment stopped cycling");
        std::thread::sleep(Duration::from_millis(20));
    }
    let t = rig.trace.lock().unwrap().clone();
    assert!(t[killed_at + stopped_at..].iter().all(|c| c.1.iter().all(|v| *v == 0)), "a drive moved again");
    drop(rig);
}
