#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! Recovery of the cell's CANopen devices, driven by the station's reconnection as in
//! `motus serve`: a socketcand hub on loopback TCP, simulated IclA drives on it as `motus
//! sim icla` runs them (each node its own connection, restarted like a process), the cell's
//! master and drivers, and a `Reconnector` polled by the test.
//!
//! - A drive that restarts (boot-up message) is brought up again: its heartbeat consumer
//!   0x1016, read back by SDO from another master on the bus, is set again, and it homes
//!   after a reset.
//! - The hub stops and starts again on the same port: the devices are connected again (about
//!   1-3 s, from the back-offs; printed, with a 15 s liveness time-out), and the cell's own
//!   simulated drives survive it.

use std::net::SocketAddr;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_axis::{Axis, AxisCommand, AxisState, MotionProfile};
use motus_can::socketcand::{Hub, HubConfig};
use motus_can::CanError;
use motus_canopen::{Master, NmtState};
use motus_cell::{open_cell, CellOptions, RunningCell};
use motus_icla_sim::{SimConfig, SimDrive};
use motus_station::alarm::{AlarmCode, MemoryAlarms};
use motus_station::devices::{Backoff, DeviceEvent, FaultTable, Reconnector};

/// The station's reconnection back-off (`motus serve`).
const STATION_BACKOFF: Backoff = Backoff { initial: Duration::from_millis(100), max: Duration::from_secs(1) };

/// What the bring-up writes into 0x1016:1: the master (node 126) watched with 300 ms.
const CONSUMER_ENTRY: u64 = (126 << 16) | 300;

fn hub_at(listen: SocketAddr) -> Hub {
    Hub::start(HubConfig { listen, bitrate: None, channel: "can0".into() }).unwrap()
}

/// A cell with two CiA 402 drives (nodes 2 and 3) on the hub at `uri`.
fn cell(dir: &Path, uri: &str, simulate: bool) -> motus_station::config::Cell {
    let mut text = format!(
        "[station]\nname = \"recovery\"\nlisten = \"127.0.0.1:0\"\ndata_dir = \"data\"\n\n\
         [[link]]\nname = \"vcan\"\nkind = \"can\"\nuri = \"{uri}\"\n"
    );
    for n in [2, 3] {
        text.push_str(&format!(
            "\n[[device]]\nname = \"drive{n}\"\nkind = \"cia402\"\nlink = \"vcan\"\naddress = {n}\nsimulate = {simulate}\n\n\
             [[axis]]\nname = \"wheel{n}\"\ndevice = \"drive{n}\"\nunit = \"rad\"\nscale = 0.029452431\n\
             limits = {{ min = -1.0e6, max = 1.0e6 }}\nmax_velocity = 20.0\nmax_acceleration = 40.0\n\
             student = {{ max_velocity = 10.0, max_acceleration = 20.0 }}\n"
        ));
    }
    let path = dir.join("cell.toml");
    std::fs::write(&path, text).unwrap();
    motus_station::config::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// One `motus sim icla --bus URI --nodes N` process: its own connection, fresh drive state.
struct SimProcess {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<(), CanError>>>,
}

impl SimProcess {
    fn start(uri: &str, node: u8) -> Self {
        let bus = motus_can::open_bus(uri).unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let drives = Arc::new(std::sync::Mutex::new(vec![SimDrive::new(SimConfig::node(node))]));
        let s = Arc::clone(&stop);
        let thread = std::thread::spawn(move || motus_icla_sim::run_shared(bus, drives, s));
        Self { stop, thread: Some(thread) }
    }

    fn kill(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for SimProcess {
    fn drop(&mut self) {
        self.kill();
    }
}

fn reconnector(rc: &RunningCell) -> (Reconnector, Arc<MemoryAlarms>, Arc<FaultTable>) {
    let alarms = Arc::new(MemoryAlarms::new());
    let faults = Arc::new(FaultTable::new());
    let mut rec = Reconnector::new(STATION_BACKOFF, alarms.clone(), faults.clone());
    for h in rc.device_handles() {
        rec.add(h);
    }
    (rec, alarms, faults)
}

/// Polls the reconnector every 50 ms (as the station's thread does every 100 ms) until
/// `done` holds for the events seen so far; returns them.
fn poll_until(
    rec: &mut Reconnector,
    timeout: Duration,
    mut done: impl FnMut(&[DeviceEvent]) -> bool,
) -> Vec<DeviceEvent> {
    let t0 = Instant::now();
    let mut seen = Vec::new();
    loop {
        seen.extend(rec.poll(Instant::now()));
        if done(&seen) {
            return seen;
        }
        assert!(t0.elapsed() < timeout, "not done within {timeout:?}: {seen:?}; {:?}", rec.status());
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn connected(events: &[DeviceEvent], device: &str) -> bool {
    events.iter().any(|e| matches!(e, DeviceEvent::Connected { device: d, .. } if d == device))
}

fn lost(events: &[DeviceEvent], device: &str) -> bool {
    events.iter().any(|e| matches!(e, DeviceEvent::Lost { device: d, .. } if d == device))
}

fn wait(axis: &mut dyn Axis, timeout: Duration, done: impl Fn(&AxisState) -> bool) -> AxisState {
    let t0 = Instant::now();
    let mut last;
    loop {
        match axis.read_state() {
            Ok(s) if done(&s) => return s,
            Ok(s) => last = format!("{s:?}"),
            Err(e) => last = e.to_string(),
        }
        assert!(t0.elapsed() < timeout, "{}: not done within {timeout:?}; last {last}", axis.name());
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn exec(axis: &mut dyn Axis, cmd: AxisCommand) {
    axis.execute(&cmd).unwrap_or_else(|e| panic!("{}: {} refused: {e}", axis.name(), cmd.name()));
}

/// Reset, enable, home, move to `target` and arrive.
fn reset_home_and_move(rc: &RunningCell, name: &str, target: f64) {
    let mut a = rc.axis(name).unwrap();
    exec(a.as_mut(), AxisCommand::FaultReset);
    exec(a.as_mut(), AxisCommand::Enable);
    exec(a.as_mut(), AxisCommand::Home);
    wait(a.as_mut(), Duration::from_secs(15), |s| s.flags.homed && !s.flags.moving);
    exec(a.as_mut(), AxisCommand::MoveAbsolute { target, profile: MotionProfile::default() });
    wait(a.as_mut(), Duration::from_secs(15), |s| !s.flags.moving && (s.position - target).abs() < 0.05);
}

/// Reads an unsigned object by SDO from another master on the bus (nothing else sends SDOs
/// to the node meanwhile: the test thread drives the station's reconnection too).
fn read_uint(probe: &Master, node: u8, index: u16, sub: u8) -> u64 {
    let raw = probe.sdo_upload(node, index, sub).unwrap_or_else(|e| panic!("0x{index:04X}:{sub}: {e}"));
    assert!((1..=8).contains(&raw.len()), "{raw:?}");
    raw.iter().rev().fold(0, |v, b| (v << 8) | u64::from(*b))
}

#[test]
fn a_restarted_drive_is_brought_up_again_and_homes_after_a_reset() {
    let dir = tempfile::tempdir().unwrap();
    let hub = hub_at("127.0.0.1:0".parse().unwrap());
    let uri = hub.uri();
    let mut sim2 = SimProcess::start(&uri, 2);
    let _sim3 = SimProcess::start(&uri, 3);
    let cell = cell(dir.path(), &uri, false);
    let rc = open_cell(&cell, CellOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    let (mut rec, alarms, faults) = reconnector(&rc);
    poll_until(&mut rec, Duration::from_secs(10), |ev| connected(ev, "drive2") && connected(ev, "drive3"));
    let probe = Master::new(motus_can::open_bus(&uri).unwrap());
    probe.set_sdo_timeout(Duration::from_secs(1));
    assert_eq!(read_uint(&probe, 2, 0x1016, 1), CONSUMER_ENTRY);
    reset_home_and_move(&rc, "wheel2", 2.0);

    // The drive restarts (its process is restarted): fresh object dictionary, 0x1016 = 0,
    // no PDO set, pre-operational, boot-up message on the bus.
    sim2.kill();
    let mut sim2 = SimProcess::start(&uri, 2);
    let restarted = Instant::now();
    let events =
        poll_until(&mut rec, Duration::from_secs(15), |ev| lost(ev, "drive2") && connected(ev, "drive2"));
    eprintln!("drive 2 brought up again {:?} after its restart: {events:?}", restarted.elapsed());
    assert!(!lost(&events, "drive3"), "the other drive is not disturbed: {events:?}");
    assert!(faults.faulted().is_empty(), "{:?}", faults.faulted());
    assert!(alarms.active().is_empty(), "{:?}", alarms.active());
    assert!(
        alarms
            .raised()
            .iter()
            .any(|a| a.code == AlarmCode::DeviceDisconnected && a.source == "device:drive2"),
        "the restart is in the alarm history: {:?}",
        alarms.raised()
    );
    // The bring-up ran again: heartbeat consumer and producer, and the node is operational.
    assert_eq!(read_uint(&probe, 2, 0x1016, 1), CONSUMER_ENTRY);
    assert_eq!(read_uint(&probe, 2, 0x1017, 0), 100);
    probe.wait_state(2, NmtState::Operational, Duration::from_secs(5)).unwrap();
    // Homing was lost with the restart; after a reset it homes and moves (PDOs work).
    assert!(!rc.axis("wheel2").unwrap().read_state().unwrap().flags.homed);
    reset_home_and_move(&rc, "wheel2", -1.0);
    // Brought up once: nothing more happens while it stays up.
    let t0 = Instant::now();
    let quiet = poll_until(&mut rec, Duration::from_secs(10), |_| t0.elapsed() > Duration::from_secs(2));
    assert!(quiet.is_empty(), "{quiet:?}");
    sim2.kill();
}

#[test]
fn the_devices_are_connected_again_after_the_hub_restarts() {
    let dir = tempfile::tempdir().unwrap();
    // The hub runs outside the cell (as `motus canbus serve`): the cell joins it, and its
    // simulated drives (simulate = true) run on it.
    let mut hub = hub_at("127.0.0.1:0".parse().unwrap());
    let addr = hub.local_addr();
    let uri = hub.uri();
    let cell = cell(dir.path(), &uri, true);
    let rc = open_cell(&cell, CellOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    let (mut rec, alarms, _faults) = reconnector(&rc);
    poll_until(&mut rec, Duration::from_secs(10), |ev| connected(ev, "drive2") && connected(ev, "drive3"));
    reset_home_and_move(&rc, "wheel3", 1.0);

    hub.stop();
    let events = poll_until(&mut rec, Duration::from_secs(10), |ev| lost(ev, "drive2") && lost(ev, "drive3"));
    eprintln!("hub stopped: {events:?}");
    assert!(alarms.is_active("device:drive2", AlarmCode::DeviceDisconnected));
    // Down for a while: the back-off grows to its cap.
    let down = Instant::now();
    poll_until(&mut rec, Duration::from_secs(10), |_| down.elapsed() > Duration::from_secs(3));
    assert!(
        rc.simulators().iter().all(|s| s.running),
        "the cell's drives outlive the hub: {:?}",
        rc.simulators()
    );

    let _hub = hub_at(addr);
    let restarted = Instant::now();
    let events = poll_until(&mut rec, Duration::from_secs(15), |ev| {
        connected(ev, "drive2") && connected(ev, "drive3")
    });
    eprintln!("connected again {:?} after the hub restarted: {events:?}", restarted.elapsed());
    assert!(alarms.active().is_empty(), "{:?}", alarms.active());
    // The drives stopped by themselves when the master's heartbeat stopped (fault 0x8130);
    // after a reset they home and move again.
    reset_home_and_move(&rc, "wheel3", -1.0);
    reset_home_and_move(&rc, "wheel2", 1.0);
}
