//! The master on a **threaded virtual clock** ([`Master::with_threaded_clock`]): its
//! receive thread, heartbeat and SYNC producers take part in a [`VirtualClock::threaded`]
//! clock with the test thread and a simulator thread, and every wait for another thread
//! parks on the clock. So the producers send at exactly their period, `wait_boot` and
//! `wait_state` return at the instant of the frame they wait for and time out after exactly
//! their time-out, a lost heartbeat is reported the instant the consumer time runs out, and
//! LSS and SDO time-outs last exactly their time-out: figures that do not depend on the
//! host's load, in milliseconds of wall time.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_can::pair::SETTLE;
use motus_can::{CanFrame, PairBus, PairPeer};
use motus_canopen::{Master, MasterEvent, NmtCommand, NmtState};
use motus_clock::{Clock, SharedClock, VirtualClock};
use motus_icla_sim::{SharedDrives, SimConfig, SimDrive};

/// Records every frame it receives with the instant it arrived; answers nothing.
#[derive(Default)]
struct Recorder {
    frames: Vec<(Instant, CanFrame)>,
}

impl PairPeer for Recorder {
    fn on_frame(&mut self, frame: &CanFrame, now: Instant) -> Vec<CanFrame> {
        self.frames.push((now, frame.clone()));
        Vec::new()
    }
    fn poll(&mut self, _: Instant) -> Vec<CanFrame> {
        Vec::new()
    }
}

#[test]
fn the_heartbeat_and_sync_producers_send_at_exactly_their_period() {
    let clock = VirtualClock::threaded();
    let recorder = Arc::new(Mutex::new(Recorder::default()));
    let bus = Arc::new(PairBus::threaded(Arc::clone(&recorder), clock.shared()));
    let master = Master::with_threaded_clock(bus, clock.shared());
    let t0 = clock.now();
    let mut heartbeat = master.start_heartbeat(0x7E, Duration::from_millis(100)).unwrap();
    let mut sync = master.start_sync(Duration::from_millis(7), Some(4)).unwrap();
    // Half a millisecond after the last beat (not at its instant), what was sent so far.
    // (Stopping a producer joins its thread, and while this one waits for the join time
    // may move on for the other producer.)
    clock.sleep(Duration::from_micros(1_000_500));
    let frames = recorder.lock().unwrap().frames.clone();
    heartbeat.stop();
    sync.stop();
    let at = |id: u32| -> Vec<Duration> {
        frames.iter().filter(|(_, f)| f.id() == id).map(|(t, _)| t.saturating_duration_since(t0)).collect()
    };
    // The heartbeat (state 5, operational) at 0, 100, ... 1000 ms: a grid that the
    // nanosecond a send takes to settle does not shift.
    let beats = at(0x77E);
    let expected: Vec<Duration> = (0..=10).map(|k| Duration::from_millis(100 * k)).collect();
    assert_eq!(beats, expected);
    assert!(frames.iter().filter(|(_, f)| f.id() == 0x77E).all(|(_, f)| f.data() == [0x05]));
    // SYNC every 7 ms from 0 to 994 ms, counters 1, 2, 3, 4, 1, ...
    let syncs = at(0x080);
    assert_eq!(syncs.len(), 143);
    assert!(syncs.iter().enumerate().all(|(k, t)| *t == Duration::from_millis(7 * k as u64)), "{syncs:?}");
    let counters: Vec<u8> =
        frames.iter().filter(|(_, f)| f.id() == 0x080).map(|(_, f)| f.data()[0]).collect();
    assert_eq!(&counters[..6], &[1, 2, 3, 4, 1, 2]);
    assert!(sync.periods().iter().all(|p| *p == Duration::from_millis(7)));
}

/// Simulated drives on a threaded pair, their control loop run by a simulator thread every
/// millisecond (half a millisecond off the test's whole milliseconds).
struct Sim {
    drives: SharedDrives,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    clock: SharedClock,
}

impl Drop for Sim {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            motus_clock::while_blocked(&*self.clock, || t.join()).unwrap();
        }
    }
}

fn sim(clock: &VirtualClock, configs: Vec<SimConfig>) -> (Sim, Master) {
    let shared = clock.shared();
    let (bus, drives) =
        motus_icla_sim::pair_threaded(configs.into_iter().map(SimDrive::new).collect(), shared.clone());
    let stop = Arc::new(AtomicBool::new(false));
    let (b, s, c) = (Arc::clone(&bus), Arc::clone(&stop), shared.clone());
    let thread = motus_clock::spawn(&shared, std::thread::Builder::new().name("sim".into()), move || {
        c.sleep(Duration::from_micros(500));
        motus_icla_sim::run_pair(&b, Duration::from_millis(1), &s, |_| {});
    })
    .unwrap();
    let master = Master::with_threaded_clock(bus, shared.clone());
    (Sim { drives, stop, thread: Some(thread), clock: shared }, master)
}

#[test]
fn boot_up_and_states_are_waited_for_on_the_clock() {
    let clock = VirtualClock::threaded();
    let (sim, m) = sim(&clock, vec![SimConfig::node(5)]);
    let t0 = clock.now();
    // The drive boots at its first control-loop step, 1.5 ms in.
    m.wait_boots(5, 1, Duration::from_secs(1)).unwrap();
    assert_eq!(clock.elapsed(t0), Duration::from_micros(1500));
    assert_eq!(m.node_state(5), Some(NmtState::BootUp), "the boot-up message");
    // Its heartbeat (every 1000 ms from the boot) reports each state.
    m.nmt(5, NmtCommand::Start).unwrap();
    m.wait_state(5, NmtState::Operational, Duration::from_secs(2)).unwrap();
    assert_eq!(clock.elapsed(t0), Duration::from_micros(1_001_500));
    // A state that never comes: the wait fails after exactly its time-out.
    let before = clock.now();
    let e = m.wait_state(5, NmtState::Stopped, Duration::from_millis(300)).unwrap_err();
    assert!(e.is_timeout(), "{e}");
    assert_eq!(clock.elapsed(before), Duration::from_millis(300));
    // A reset: the node boots again (counted).
    m.nmt(5, NmtCommand::ResetNode).unwrap();
    m.wait_boots(5, 2, Duration::from_secs(1)).unwrap();
    assert_eq!(m.boot_count(5), 2);
    drop(sim);
}

#[test]
fn a_lost_heartbeat_is_reported_the_instant_the_consumer_time_runs_out() {
    let clock = VirtualClock::threaded();
    let (sim, m) = sim(&clock, vec![SimConfig::node(5)]);
    let events = m.events_on_clock();
    m.wait_boots(5, 1, Duration::from_secs(1)).unwrap();
    m.monitor_heartbeat(5, Duration::from_millis(1500));
    clock.sleep(Duration::from_secs(5));
    assert!(!m.heartbeat_lost(5), "the heartbeat (every 1000 ms) keeps it alive");
    motus_icla_sim::lock(&sim.drives)[0].set_heartbeat_stopped(true);
    let lost = loop {
        match events.recv_timeout(Duration::from_secs(10)).expect("heartbeat loss reported") {
            MasterEvent::HeartbeatLost { node, last_seen } => break (node, last_seen, clock.now()),
            _ => continue,
        }
    };
    assert_eq!(lost.0, 5);
    // Reported (and received by this thread) one microsecond after the consumer time: a
    // loss is a silence longer than it.
    assert_eq!(lost.2 - lost.1, Duration::from_micros(1_500_001), "last seen {:?}", lost.1);
    assert!(m.heartbeat_lost(5));
    // The heartbeat comes back: recovered at the instant of its frame.
    motus_icla_sim::lock(&sim.drives)[0].set_heartbeat_stopped(false);
    let back = events.recv_timeout(Duration::from_secs(2)).unwrap();
    assert!(matches!(back, MasterEvent::HeartbeatRecovered { node: 5, .. }), "{back:?}");
    assert!(!m.heartbeat_lost(5));
}

#[test]
fn lss_and_sdo_time_outs_last_exactly_their_time_out_of_virtual_time() {
    let clock = VirtualClock::threaded();
    let (sim, m) = sim(&clock, vec![SimConfig::node(5), SimConfig::unconfigured(77)]);
    m.wait_boots(5, 1, Duration::from_secs(1)).unwrap();
    // FASTSCAN finds the unconfigured drive; each step without an answer takes its 10 ms.
    let before = clock.now();
    let id = m.lss_fastscan(Duration::from_millis(10)).unwrap().expect("the unconfigured drive answers");
    assert_eq!(id.serial, 77);
    println!("fastscan took {:?} of virtual time", clock.elapsed(before));
    m.lss_configure_node_id(6).unwrap();
    m.lss_switch_global(motus_canopen::LssMode::Waiting).unwrap();
    m.wait_boots(6, 1, Duration::from_secs(1)).unwrap();
    // Nobody is in configuration: the confirmation times out after exactly 500 ms (plus
    // the nanosecond its request's send settles).
    let before = clock.now();
    let e = m.lss_inquire_node_id().unwrap_err();
    assert!(e.to_string().contains("inquire node-ID"), "{e}");
    assert_eq!(clock.elapsed(before), Duration::from_millis(500) + SETTLE);
    // An SDO answered at once, then one never answered.
    let before = clock.now();
    assert_eq!(m.read_u32(6, 0x1018, 4).unwrap(), 77);
    assert_eq!(clock.elapsed(before), SETTLE, "answered within the send");
    m.set_sdo_timeout(Duration::from_millis(200));
    motus_icla_sim::lock(&sim.drives)[0].set_drop_sdo_replies(true);
    let before = clock.now();
    let e = m.read_u32(5, 0x1000, 0).unwrap_err();
    assert!(e.is_timeout(), "{e}");
    // 200 ms from the request, and the abort the client sends when it gives up.
    assert_eq!(clock.elapsed(before), Duration::from_millis(200) + SETTLE);
}
