//! The simulated segment (MN, five drive CNs, a passive monitor) on the in-process segment
//! (`MemHub`) on VIRTUAL time: every thread takes part in one threaded `VirtualClock`, so the
//! cycle, its time-outs and every figure are exact, whatever the host's load, and seconds of
//! cycles take a fraction of that in wall time. Figures are printed; the assertions are exact.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_clock::{Clock, VirtualClock};
use motus_epl::sim::pdo::STATUS_QUICK_STOP;
use motus_epl::sim::{CamAxis, CamProgram, CnChange, CnEvent, DriveParams, MnConfig, MnStats, Segment};
use motus_epl::transport::MemHub;
use motus_epl::{CycleSample, Monitor, MonitorConfig, MonitorStats};
use motus_epl_protocol::{NmtState, RequestedService, Value, ValueMap};

const NODES: [u8; 5] = [1, 2, 3, 4, 5];

fn map() -> ValueMap {
    let mut text = String::new();
    for n in NODES {
        text.push_str(&format!(
            "[[node]]\nnode = {n}\nvalues = [{{ name = \"status\", offset = 0, type = \"u16\" }}, {{ name = \"position\", offset = 16, type = \"i32\" }}, {{ name = \"speed\", offset = 20, type = \"i32\" }}]\n"
        ));
    }
    ValueMap::from_toml(&text).unwrap()
}

fn cam() -> Vec<CamAxis> {
    NODES
        .iter()
        .map(|&n| CamAxis {
            center: 1000.0 * f64::from(n),
            amplitude: 2000.0,
            period: 1.0,
            phase: 0.1 * f64::from(n),
        })
        .collect()
}

fn i32_of(s: &CycleSample, node: u8, name: &str) -> i32 {
    match s.node(node).and_then(|n| n.value(name)) {
        Some(Value::I32(x)) => x,
        other => panic!("node {node} {name}: {other:?}"),
    }
}

fn status_of(s: &CycleSample, node: u8) -> u16 {
    match s.node(node).and_then(|n| n.value("status")) {
        Some(Value::U16(x)) => x,
        other => panic!("node {node} status: {other:?}"),
    }
}

/// A monitored cycle and the virtual instant of its SoC.
type Seen = (Instant, CycleSample);

/// What a run recorded: the monitored cycles (SoC since the clock's base) and the MN's figures.
type Record = (Vec<(Duration, CycleSample)>, MnStats);

struct Rig {
    clock: VirtualClock,
    cycle: Duration,
    segment: Segment,
    seen: Arc<Mutex<Vec<Seen>>>,
    stop_monitor: StopOnDrop,
    monitor: Option<JoinHandle<MonitorStats>>,
    wall: std::time::Instant,
}

fn rig(name: &str, config: MnConfig, soc_loss_tolerance: Option<Duration>) -> Rig {
    let wall = std::time::Instant::now();
    let clock = VirtualClock::threaded();
    let shared = clock.shared();
    let hub = MemHub::with_clock(name, Arc::clone(&shared));
    // The monitor: its own port and thread, taking part in the clock.
    let seen = Arc::new(Mutex::new(Vec::new()));
    let stop_monitor = Arc::new(AtomicBool::new(false));
    let monitor = {
        let (link, seen, stop, clock) =
            (hub.connect(), Arc::clone(&seen), Arc::clone(&stop_monitor), clock.clone());
        motus_clock::spawn(&shared, std::thread::Builder::new().name("monitor".into()), move || {
            let mut m = Monitor::new(map(), MonitorConfig { stale_after: 0 });
            m.run(&link, &stop, |s| {
                // A cycle is reported at the next SoC, one cycle after its own.
                let soc = clock.now() - Duration::from_nanos(s.report.duration_ns.unwrap_or(0));
                seen.lock().unwrap().push((soc, s.clone()));
                ControlFlow::Continue(())
            })
            .unwrap()
        })
        .unwrap()
    };
    let axes = cam();
    let mut b = Segment::builder()
        .clock(Arc::clone(&shared))
        .config(config)
        .mn_link(Arc::new(hub.connect()))
        .program(Box::new(CamProgram::new(axes.clone())));
    for (node, axis) in NODES.iter().zip(&axes) {
        let params =
            DriveParams { initial_position: axis.at(0.0), soc_loss_tolerance, ..DriveParams::default() };
        b = b.drive(*node, Arc::new(hub.connect()), params);
    }
    let segment = b.start().unwrap();
    let cycle = config.cycle;
    Rig { clock, cycle, segment, seen, stop_monitor: StopOnDrop(stop_monitor), monitor: Some(monitor), wall }
}

impl Rig {
    /// Boots the segment, then waits until half a cycle after a cycle's start (the MN's
    /// cycles start on the grid `base + k * cycle`, k >= 1): what the test does next happens
    /// between two cycles, never at the instant of one. Returns the boot time.
    fn boot(&self, label: &str) -> Duration {
        assert!(
            self.segment.wait_operational(Duration::from_secs(2)),
            "{label}: MN {}",
            self.segment.mn_state()
        );
        let booted = self.clock.since_base();
        for n in NODES {
            assert_eq!(self.segment.cn_state(n), Some(NmtState::Operational), "{label}: node {n}");
        }
        let c = self.cycle.as_nanos() as u64;
        let next = (self.clock.since_base().as_nanos() as u64 / c + 2) * c + c / 2;
        self.clock.sleep_until(self.clock.base() + Duration::from_nanos(next));
        eprintln!("{label}: OPERATIONAL after {booted:?} of virtual time");
        booted
    }

    fn cycles(&self, n: u32) {
        self.clock.sleep(self.cycle * n);
    }

    /// The monitored cycles whose SoC came after `t`.
    fn seen_after(&self, t: Instant) -> Vec<CycleSample> {
        self.seen_between(t, self.clock.now())
    }

    /// The monitored cycles whose SoC came after `from` and by `to`.
    fn seen_between(&self, from: Instant, to: Instant) -> Vec<CycleSample> {
        let seen = self.seen.lock().unwrap();
        seen.iter().filter(|(soc, _)| *soc > from && *soc <= to).map(|(_, s)| s.clone()).collect()
    }

    /// Every monitored cycle, its SoC in virtual time since the base, and the MN's figures.
    fn record(&self) -> Record {
        let seen = self.seen.lock().unwrap();
        let cycles = seen.iter().map(|(soc, s)| (*soc - self.clock.base(), s.clone())).collect();
        (cycles, self.segment.stats())
    }

    fn finish(mut self, label: &str) {
        let end = self.clock.since_base();
        self.stop_monitor.0.store(true, Ordering::Relaxed);
        self.segment.stop();
        let monitor = self.monitor.take().unwrap();
        let stats = motus_clock::while_blocked(&self.clock, || monitor.join()).unwrap();
        assert_eq!(stats.undecoded, 0, "{label}");
        eprintln!("{label}: {end:?} of virtual time in {:?} of wall time", self.wall.elapsed());
    }
}

/// Sets a stop flag when dropped: also when a test fails, the monitor must not go on alone on
/// the clock.
struct StopOnDrop(Arc<AtomicBool>);

impl Drop for StopOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

fn every_cycle_runs_without_a_miss(label: &str, cycle: Duration, pres_timeout: Duration) {
    let config = MnConfig { cycle, pres_timeout, ..MnConfig::default() };
    let rig = rig(label, config, None);
    rig.boot(label);
    rig.segment.reset_stats();
    let from = rig.clock.now();
    // Two seconds of cycles.
    let n = u32::try_from(Duration::from_secs(2).as_nanos() / cycle.as_nanos()).unwrap();
    rig.cycles(n);
    let st = rig.segment.stats();
    let (j, r) = (st.jitter(), st.rtt());
    eprintln!(
        "{label}: {} cycles ({} operational), PRes missed {:?}, late {}, overruns {}, SoC late p50/p99/max {}/{}/{} ns, \
         PReq->PRes p50/p99/max {}/{}/{} ns over {} polls",
        st.cycles,
        st.operational_cycles,
        st.pres_missed,
        st.pres_late,
        st.overruns,
        j.p50,
        j.p99,
        j.max,
        r.p50,
        r.p99,
        r.max,
        r.count,
    );
    // Exact on virtual time: every cycle ran, on its deadline, every PReq answered at once.
    assert_eq!(st.cycles, u64::from(n), "{label}");
    assert_eq!(st.operational_cycles, u64::from(n), "{label}");
    assert_eq!(st.total_missed(), 0, "{label}: {:?}", st.pres_missed);
    assert_eq!((st.pres_late, st.overruns, st.decode_errors, st.send_errors), (0, 0, 0, 0), "{label}");
    assert_eq!((j.count, j.max), (n as usize, 0), "{label}: every SoC on its deadline");
    assert_eq!((r.count, r.max), (NODES.len() * n as usize, 0), "{label}: every PRes in the PReq's instant");
    assert!(st.cn_events.is_empty(), "{label}: {:?}", st.cn_events);

    // The monitor saw every one of these cycles, every node fresh and valid in each, and the
    // drives followed their cams (PDO data both ways: set-points in, positions out).
    let seen = rig.seen_after(from);
    // The last cycle is reported at the next SoC, after the end of the window.
    assert_eq!(seen.len(), n as usize - 1, "{label}: cycles monitored");
    let stale: Vec<u64> = seen.iter().filter(|s| !s.all_fresh()).map(|s| s.index).collect();
    assert!(stale.is_empty(), "{label}: cycles with a stale or invalid node: {stale:?}");
    for n in NODES.iter() {
        let positions: Vec<i32> = seen.iter().map(|s| i32_of(s, *n, "position")).collect();
        let (lo, hi) = (positions.iter().min().unwrap(), positions.iter().max().unwrap());
        let center = 1000 * i32::from(*n);
        eprintln!("{label}: node {n}: positions {lo}..{hi} (cam {}..{})", center - 2000, center + 2000);
        assert!(
            hi - lo > 3900 && *lo >= center - 2010 && *hi <= center + 2010,
            "{label}: node {n}: {lo}..{hi}"
        );
    }

    // Quick stop: the bit goes out in the next cycle's PReq, and the drive shows it in that
    // very cycle's PRes; braking starts at the SoC after it, and every drive is at rest within
    // v²/(2 a_b) plus one cycle at its speed.
    let before = rig.clock.now();
    rig.segment.quick_stop(true);
    rig.cycles(100);
    let after = rig.seen_after(before);
    let first = &after[0];
    let brake = DriveParams::default().brake_decel;
    let last = after.last().unwrap();
    for n in NODES {
        assert_ne!(
            status_of(first, n) & STATUS_QUICK_STOP,
            0,
            "{label}: node {n} in the first cycle after the request"
        );
        let (p0, v0) = (f64::from(i32_of(first, n, "position")), f64::from(i32_of(first, n, "speed")));
        assert_eq!(i32_of(last, n, "speed"), 0, "{label}: node {n} still moving");
        let moved = (f64::from(i32_of(last, n, "position")) - p0).abs();
        let allowed = v0 * v0 / (2.0 * brake) + v0.abs() * cycle.as_secs_f64() + 1.0;
        eprintln!(
            "{label}: node {n}: quick stop at {v0} units/s, braked over {moved} (allowed {allowed:.1})"
        );
        assert!(moved <= allowed, "{label}: node {n} moved {moved} > {allowed}");
    }
    rig.finish(label);
}

#[test]
fn every_cycle_runs_without_a_miss_at_1ms() {
    every_cycle_runs_without_a_miss("vt 1 ms", Duration::from_millis(1), Duration::from_micros(300));
}

#[test]
fn every_cycle_runs_without_a_miss_at_400us() {
    every_cycle_runs_without_a_miss("vt 400 us", Duration::from_micros(400), Duration::from_micros(150));
}

/// A CN unplugged between two cycles: its PRes is missed `lost_after` times, then the MN
/// declares it lost (in exactly that cycle), stops polling it and invites it with an
/// IdentRequest in every async slot. Plugged back, it answers the first invitation; with a
/// loss-of-SoC tolerance shorter than its absence it comes back in PRE_OPERATIONAL_1 and is
/// booted again (EnableReadyToOperate, StartNode) while the others run.
fn a_silent_cn_is_lost_and_found(
    label: &str,
    cycle: Duration,
    pres_timeout: Duration,
    soc_loss: bool,
) -> Record {
    const LOST_AFTER: u32 = 5;
    const NODE: u8 = 3;
    let config = MnConfig { cycle, pres_timeout, lost_after: LOST_AFTER, ..MnConfig::default() };
    let rig = rig(label, config, soc_loss.then_some(cycle * 3));
    rig.boot(label);
    rig.segment.reset_stats();
    rig.cycles(10);

    let unplugged_at = rig.clock.now();
    let c_unplug = rig.segment.stats().cycles;
    assert!(rig.segment.unplug(NODE, true));
    rig.cycles(LOST_AFTER + 10);
    let st = rig.segment.stats();
    eprintln!(
        "{label}: unplugged after cycle {c_unplug}: {:?}, PRes missed {:?}",
        st.cn_events, st.pres_missed
    );
    assert_eq!(
        st.cn_events,
        vec![CnEvent { cycle: c_unplug + u64::from(LOST_AFTER), node: NODE, change: CnChange::Lost }],
        "{label}: lost in the cycle of its {LOST_AFTER}th missed PRes"
    );
    assert_eq!(st.pres_missed.get(&NODE), Some(&u64::from(LOST_AFTER)), "{label}: {:?}", st.pres_missed);
    assert_eq!(st.total_missed(), u64::from(LOST_AFTER), "{label}: only node {NODE} missed");
    assert_eq!(st.overruns, 0, "{label}");

    let plugged_at = rig.clock.now();
    let c_plug = st.cycles;
    assert!(rig.segment.unplug(NODE, false));
    rig.cycles(30);
    let st = rig.segment.stats();
    eprintln!("{label}: plugged back after cycle {c_plug}: {:?}", st.cn_events);
    assert_eq!(
        st.cn_events.get(1),
        Some(&CnEvent { cycle: c_plug + 1, node: NODE, change: CnChange::Found }),
        "{label}: found in the first async slot after it came back"
    );
    assert_eq!(st.cn_events.len(), 2, "{label}");
    assert_eq!(st.total_missed(), u64::from(LOST_AFTER), "{label}: no miss after it came back");
    assert_eq!(st.overruns, 0, "{label}");
    assert_eq!(rig.segment.cn_state(NODE), Some(NmtState::Operational), "{label}");

    // What went over the wire, cycle by cycle.
    let during = rig.seen_between(unplugged_at, plugged_at);
    assert_eq!(during.len(), (LOST_AFTER + 10) as usize, "{label}");
    for (k, s) in during.iter().enumerate() {
        let polled = s.report.polled.contains(&NODE);
        assert_eq!(
            polled,
            k < LOST_AFTER as usize,
            "{label}: cycle {k} after the unplug: polled {:?}",
            s.report.polled
        );
        assert!(!s.report.saw_pres(NODE), "{label}: a PRes from the unplugged node");
        if k >= LOST_AFTER as usize {
            assert_eq!(s.report.soa, Some((RequestedService::IdentRequest, NODE)), "{label}: cycle {k}");
        }
        for n in NODES.iter().filter(|n| **n != NODE) {
            let ns = s.node(*n).unwrap();
            assert!(!ns.stale && ns.valid, "{label}: node {n} in cycle {k} after the unplug: {ns:?}");
        }
    }
    let back = rig.seen_after(plugged_at);
    // The first cycle after the plug: not polled yet; it answers the IdentRequest.
    assert!(!back[0].report.polled.contains(&NODE), "{label}");
    assert_eq!(back[0].report.soa, Some((RequestedService::IdentRequest, NODE)), "{label}");
    assert!(back[0].report.asnd_from.contains(&NODE), "{label}: IdentResponse");
    // Then polled every cycle; valid data once OPERATIONAL again.
    let states: Vec<Option<NmtState>> =
        back[1..8].iter().map(|s| s.report.pres_of(NODE).map(|p| p.nmt_state)).collect();
    eprintln!("{label}: node {NODE}'s PRes states after the plug: {states:?}");
    let first_valid = back.iter().position(|s| s.node(NODE).is_some_and(|n| !n.stale && n.valid)).unwrap();
    if soc_loss {
        use NmtState::*;
        // Cycle 1: PRE_OP_1 -> PRE_OP_2 at its SoC; EnableReadyToOperate in the async slot of
        // cycle 2, StartNode in that of cycle 4.
        assert_eq!(
            states,
            [
                PreOperational2,
                PreOperational2,
                ReadyToOperate,
                ReadyToOperate,
                Operational,
                Operational,
                Operational
            ]
            .map(Some),
            "{label}"
        );
        assert_eq!(first_valid, 5, "{label}");
    } else {
        assert!(states.iter().all(|s| *s == Some(NmtState::Operational)), "{label}: {states:?}");
        assert_eq!(first_valid, 1, "{label}");
    }
    for s in &back[first_valid..] {
        assert!(s.all_fresh(), "{label}: cycle {} after the plug", s.index);
    }
    // The drive follows its cam again.
    let positions: Vec<i32> = back[first_valid..].iter().map(|s| i32_of(s, NODE, "position")).collect();
    assert!(positions.first() != positions.last(), "{label}: node {NODE} does not move: {positions:?}");
    let record = rig.record();
    rig.finish(label);
    record
}

#[test]
fn a_silent_cn_is_lost_and_found_at_1ms() {
    a_silent_cn_is_lost_and_found(
        "vt loss 1 ms",
        Duration::from_millis(1),
        Duration::from_micros(300),
        false,
    );
}

#[test]
fn a_silent_cn_is_lost_and_booted_again_at_400us() {
    a_silent_cn_is_lost_and_found(
        "vt loss 400 us",
        Duration::from_micros(400),
        Duration::from_micros(150),
        true,
    );
}

#[test]
fn a_silent_cn_is_lost_and_booted_again_at_1ms() {
    a_silent_cn_is_lost_and_found(
        "vt loss+soc 1 ms",
        Duration::from_millis(1),
        Duration::from_micros(300),
        true,
    );
}

#[test]
fn a_run_on_virtual_time_is_the_same_every_time() {
    let run = |label| {
        a_silent_cn_is_lost_and_found(label, Duration::from_micros(400), Duration::from_micros(150), true)
    };
    let (first, second) = (run("vt same run 1"), run("vt same run 2"));
    assert_eq!(first.0.len(), second.0.len(), "cycles monitored");
    assert!(first.0 == second.0, "the monitored cycles differ");
    assert!(first.1 == second.1, "the MN's figures differ");
}
