//! The driver against the simulated IclA drive (motus-icla-sim) on **virtual time**: the
//! CANopen master and the driver run on a [`VirtualClock`], the simulated drive is the
//! in-process peer of a [`motus_can::PairBus`] and answers every frame inside the send,
//! at the virtual instant the driver has slept to. The code under test is the production
//! path (`Drive` -> `CanopenDrive` -> `Master` -> `CanBus`); only the clock and the link
//! differ from a real bus. Nothing here depends on the host's load: positions at given
//! times are checked within an increment or two, and a test that simulates tens of
//! seconds of motion takes a fraction of a second of wall time.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_can::{CanFrame, PairBus};
use motus_canopen::{consumer_entry, Master, MasterEvent};
use motus_cia402::{CanopenDrive, Drive, DriveError, DriveIo, DriveSettings, IoError, MoveKind, Profile};
use motus_cia402_protocol::{Mode, PowerState};
use motus_clock::{Clock, VirtualClock};
use motus_icla_sim::{SharedDrives, SimConfig, SimDrive};
use std::sync::Arc;
use std::time::{Duration, Instant};

const NODE: u8 = 5;

struct Rig {
    clock: VirtualClock,
    drives: SharedDrives,
    master: Arc<Master>,
    drive: Drive<CanopenDrive>,
    wall: Instant,
    name: &'static str,
}

impl Drop for Rig {
    fn drop(&mut self) {
        // Printed with --nocapture: the wall time a simulated stretch took.
        println!(
            "{}: {:.1} s virtual in {:.3} s wall",
            self.name,
            self.clock.since_base().as_secs_f64(),
            self.wall.elapsed().as_secs_f64()
        );
    }
}

impl Rig {
    fn sim(&self) -> std::sync::MutexGuard<'_, Vec<SimDrive>> {
        motus_icla_sim::lock(&self.drives)
    }
    /// Virtual seconds since the start.
    fn t(&self) -> f64 {
        self.clock.since_base().as_secs_f64()
    }
}

fn rig(name: &'static str) -> Rig {
    let wall = Instant::now();
    let clock = VirtualClock::new();
    let (bus, drives): (Arc<PairBus<Vec<SimDrive>>>, _) =
        motus_icla_sim::pair(vec![SimDrive::new(SimConfig::node(NODE))], clock.shared());
    let master = Arc::new(Master::with_clock(bus, clock.shared()));
    let drive = Drive::new(CanopenDrive::new(Arc::clone(&master), NODE), DriveSettings::default());
    Rig { clock, drives, master, drive, wall, name }
}

/// The ideal trapezoidal profile from 0 over `dist` (> the ramps' distance) at time `t`.
fn trapezoid(dist: f64, p: &Profile, t: f64) -> f64 {
    let (v, a, d) = (f64::from(p.velocity), f64::from(p.acceleration), f64::from(p.deceleration));
    let (ta, td) = (v / a, v / d);
    let (da, dd) = (v * ta / 2.0, v * td / 2.0);
    let tc = (dist - da - dd) / v;
    if t <= 0.0 {
        0.0
    } else if t < ta {
        a * t * t / 2.0
    } else if t < ta + tc {
        da + v * (t - ta)
    } else if t < ta + tc + td {
        let u = t - ta - tc;
        da + v * tc + v * u - d * u * u / 2.0
    } else {
        dist
    }
}

#[test]
fn enable_then_a_profile_move_is_where_the_model_says_at_every_time() {
    let mut r = rig("profile move");
    r.drive.enable().unwrap();
    assert_eq!(r.drive.state().unwrap().0, PowerState::OperationEnabled);
    assert!(r.t() < 0.1, "enabling takes a few polls, not {} s", r.t());
    let p = Profile::ICLA_SEED;
    r.drive.set_profile(&p).unwrap();
    r.drive.set_mode(Mode::ProfilePosition).unwrap();
    let dist = 2000.0;
    let t0 = r.clock.now();
    r.drive.start_move(2000, MoveKind::Absolute, true).unwrap();
    assert_eq!(r.clock.now(), t0, "the set-point is acknowledged at the instant it is sent");
    // The motor follows the demand with a first-order lag of 10 ms: the actual position at
    // t is the profile's at t - lag, within the rounding of 0x6064 and a 1 ms step.
    let lag = r.sim()[0].config().lag_time;
    for ms in [50u64, 100, 248, 500, 1000, 2500, 4000, 6000, 7500, 8000, 8300, 8450] {
        r.clock.sleep_until(t0 + Duration::from_millis(ms));
        let t = ms as f64 / 1000.0;
        let expected = trapezoid(dist, &p, t - lag);
        let actual = r.drive.position().unwrap();
        assert!((f64::from(actual) - expected).abs() <= 1.5, "at {ms} ms: {actual}, model {expected:.2}");
        if ms == 4000 {
            assert_eq!(r.drive.velocity().unwrap(), 248, "cruise velocity");
        }
    }
    let ended = r.drive.wait_target_reached(Duration::from_secs(30)).unwrap();
    assert_eq!(ended, 2000);
    // Arrival: the ideal end (8.499 s) within a few polls (target reached means inside the
    // position window, so it may come a little before the last increment).
    let arrival = (r.clock.now() - t0).as_secs_f64();
    let ideal = f64::from(p.velocity) / 2.0
        * (1.0 / f64::from(p.acceleration) + 1.0 / f64::from(p.deceleration))
        + dist / f64::from(p.velocity);
    assert!((arrival - ideal).abs() < 0.05, "arrived after {arrival} s, ideal {ideal} s");
    // Relative move from the target.
    r.drive.start_move(-500, MoveKind::Relative, true).unwrap();
    assert_eq!(r.drive.wait_target_reached(Duration::from_secs(30)).unwrap(), 1500);
}

#[test]
fn homing_on_the_negative_limit_switch_and_on_the_current_position() {
    let mut r = rig("homing");
    r.drive.enable().unwrap();
    r.drive.run_velocity(150).unwrap();
    r.clock.sleep(Duration::from_secs(2));
    assert!(r.drive.velocity().unwrap() > 140);
    r.drive.halt().unwrap();
    r.drive.wait_standstill(Duration::from_secs(3)).unwrap();
    let before = r.t();
    // Method 17: search the negative switch (world -500) at 100 Inc/s, leave it at 20 Inc/s.
    r.drive.home(17, Duration::from_secs(60)).unwrap();
    let took = r.t() - before;
    // Home is the switch edge; the position is what the stop after it leaves (< 1 Inc).
    assert!(r.drive.position().unwrap().abs() <= 1);
    let world = r.sim()[0].world_position();
    assert!((world + 500.0).abs() < 2.0, "home at the switch edge, not {world}");
    assert!(took > 5.0 && took < 15.0, "homing over ~700 Inc at 100 Inc/s took {took} s");
    assert_eq!(r.drive.mode_display().unwrap(), Mode::ProfilePosition);
    // Method 35: the current position is home at once.
    r.drive.start_move(300, MoveKind::Absolute, true).unwrap();
    r.drive.wait_target_reached(Duration::from_secs(10)).unwrap();
    r.drive.home(35, Duration::from_secs(1)).unwrap();
    assert_eq!(r.drive.position().unwrap(), 0);
    r.drive.set_software_limits(-1000, 1000).unwrap();
    assert!(matches!(
        r.drive.start_move(1001, MoveKind::Absolute, true),
        Err(DriveError::BeyondLimit { .. })
    ));
    // Refusals by name: the IclA lists pp, pv, hm in 0x6502; 0x6041 is read-only.
    assert!(matches!(r.drive.set_mode(Mode::CyclicSyncPosition), Err(DriveError::ModeUnsupported { .. })));
    let e = r.drive.io().write(0x6041, 0, &[0, 0]).unwrap_err();
    assert!(e.to_string().contains("read-only") || e.to_string().contains("0x06010002"), "{e}");
}

#[test]
fn a_quick_stop_mid_move_stops_on_the_quick_stop_ramp_and_the_drive_recovers() {
    let mut r = rig("quick stop");
    r.drive.enable().unwrap();
    let p = Profile::ICLA_SEED;
    r.drive.set_profile(&p).unwrap();
    // Option 2: quick-stop ramp (0x6085), then "switch on disabled".
    r.drive.set_quick_stop_option(2).unwrap();
    r.drive.set_quick_stop_deceleration(4000).unwrap();
    r.drive.set_mode(Mode::ProfilePosition).unwrap();
    let t0 = r.clock.now();
    r.drive.start_move(5000, MoveKind::Absolute, true).unwrap();
    r.clock.sleep(Duration::from_secs(2));
    let lag = r.sim()[0].config().lag_time;
    let at_stop = trapezoid(5000.0, &p, 2.0 - lag);
    r.drive.quick_stop().unwrap();
    r.drive.wait_state(PowerState::SwitchOnDisabled).unwrap();
    // 248 Inc/s stopped at 4000 Inc/s^2: 62 ms and 7.7 Inc.
    let stopping = (r.clock.now() - t0).as_secs_f64() - 2.0;
    assert!(stopping > 0.05 && stopping < 0.1, "stopped after {stopping} s");
    r.clock.sleep(Duration::from_millis(100));
    assert_eq!(r.drive.velocity().unwrap(), 0);
    let stopped_at = f64::from(r.drive.position().unwrap());
    let expected = at_stop + 248.0 * 248.0 / (2.0 * 4000.0);
    assert!((stopped_at - expected).abs() <= 3.0, "stopped at {stopped_at}, model {expected:.1}");
    r.drive.enable().unwrap();
    assert_eq!(r.drive.mode_display().unwrap(), Mode::ProfilePosition);
}

#[test]
fn a_blocked_load_and_an_injected_fault_are_reported_and_reset() {
    let mut r = rig("faults");
    r.drive.enable().unwrap();
    r.drive.set_following_error(50, 100).unwrap();
    r.sim()[0].set_load_blocked(true);
    r.drive.start_move(2000, MoveKind::Absolute, true).unwrap();
    let t0 = r.t();
    let e = r.drive.wait_target_reached(Duration::from_secs(5)).unwrap_err();
    assert!(matches!(e, DriveError::FollowingError { .. } | DriveError::Fault { .. }), "{e}");
    // Beyond the 50 Inc window after ~0.32 s of ramp, for 100 ms: seen within a poll.
    let seen = r.t() - t0;
    assert!(seen > 0.3 && seen < 0.5, "following error seen after {seen} s");
    r.drive.wait_state(PowerState::Fault).unwrap();
    assert_eq!(r.drive.error_code(), Some(0x8611));
    r.sim()[0].set_load_blocked(false);
    r.drive.fault_reset().unwrap();
    r.drive.enable().unwrap();
    // A fault whose cause persists: the reset is refused until the cause is gone.
    r.sim()[0].inject_fault(0x4310);
    assert!(matches!(r.drive.enable(), Err(DriveError::Fault { code: Some(0x4310), .. })));
    let before = r.clock.now();
    assert!(matches!(r.drive.fault_reset(), Err(DriveError::FaultPersists { .. })));
    let waited = r.clock.now() - before;
    let s = r.drive.settings().clone();
    assert!(
        waited >= s.transition_timeout
            && waited <= s.transition_timeout + s.fault_reset_pulse + s.poll_interval * 2
    );
    r.sim()[0].clear_fault_cause();
    r.drive.fault_reset().unwrap();
    r.drive.enable().unwrap();
}

#[test]
fn the_drive_stops_when_the_masters_heartbeat_lease_expires() {
    let mut r = rig("heartbeat lease");
    const MASTER: u8 = 0x7F;
    let lease = Duration::from_millis(300);
    r.drive.io().write(0x1016, 1, &consumer_entry(MASTER, lease).to_le_bytes()).unwrap();
    let heartbeat = CanFrame::new(0x700 + u32::from(MASTER), &[0x05]).unwrap();
    r.drive.enable().unwrap();
    r.drive.run_velocity(200).unwrap();
    // Heartbeats every 100 ms for 2 s: the drive runs.
    let mut last = r.clock.now();
    for _ in 0..20 {
        r.master.send_frame(&heartbeat).unwrap();
        last = r.clock.now();
        r.clock.sleep(Duration::from_millis(100));
        assert_eq!(r.drive.state().unwrap().0, PowerState::OperationEnabled);
    }
    assert!(r.drive.velocity().unwrap() > 190);
    // The heartbeats stop: the fault reaction starts once the lease is overdue.
    let reacted = loop {
        let (state, _) = r.drive.state().unwrap();
        if state != PowerState::OperationEnabled {
            assert!(matches!(state, PowerState::FaultReactionActive | PowerState::Fault), "{state:?}");
            break r.clock.now() - last;
        }
        assert!(r.clock.now() - last < Duration::from_secs(2), "no reaction");
        r.clock.sleep(Duration::from_millis(1));
    };
    assert!(reacted > lease && reacted <= lease + Duration::from_millis(2), "reacted after {reacted:?}");
    r.drive.wait_state(PowerState::Fault).unwrap();
    r.clock.sleep(Duration::from_millis(100));
    let stopped_at = r.drive.position().unwrap();
    r.clock.sleep(Duration::from_secs(1));
    assert_eq!(r.drive.position().unwrap(), stopped_at, "the axis stands still");
    assert_eq!(r.drive.velocity().unwrap(), 0);
    assert_eq!(r.drive.error_code(), Some(motus_icla_sim::drive::HEARTBEAT_ERROR));
    // Heartbeats back: the fault resets and the drive enables again.
    r.master.send_frame(&heartbeat).unwrap();
    r.drive.fault_reset().unwrap();
    r.master.send_frame(&heartbeat).unwrap();
    r.drive.enable().unwrap();
}

#[test]
fn the_master_notices_a_lost_drive_heartbeat_and_an_sdo_times_out_on_virtual_time() {
    let r = rig("master heartbeat and SDO time-out");
    let events = r.master.events();
    r.drive.state().unwrap(); // boots the drive (boot-up at time zero)
    r.master.monitor_heartbeat(NODE, Duration::from_millis(1500));
    // The drive's heartbeat (every 1000 ms) keeps it alive for 5 s; the driver's thread
    // moves time in steps and reads the drive after each (so the heartbeats are sent).
    for _ in 0..50 {
        r.clock.sleep(Duration::from_millis(100));
        r.drive.state().unwrap();
    }
    assert!(!r.master.heartbeat_lost(NODE));
    r.sim()[0].set_heartbeat_stopped(true);
    let stopped = r.clock.now();
    for _ in 0..20 {
        r.clock.sleep(Duration::from_millis(100));
        r.drive.state().unwrap();
    }
    // The receive thread reports it (a wall-time liveness bound only).
    let lost = loop {
        match events.recv_timeout(Duration::from_secs(10)).expect("heartbeat loss reported") {
            MasterEvent::HeartbeatLost { node, last_seen } => break (node, last_seen),
            _ => continue,
        }
    };
    assert_eq!(lost.0, NODE);
    assert!(lost.1 <= stopped && stopped - lost.1 <= Duration::from_millis(1000));
    // A silent SDO server: the transfer fails after exactly its time-out of virtual time.
    r.master.set_sdo_timeout(Duration::from_millis(200));
    r.sim()[0].set_drop_sdo_replies(true);
    let before = r.clock.now();
    let e = r.drive.position().unwrap_err();
    assert!(matches!(e, DriveError::Io(IoError::Timeout { .. })), "{e}");
    assert_eq!(r.clock.now() - before, Duration::from_millis(200));
    r.sim()[0].set_drop_sdo_replies(false);
    assert_eq!(r.drive.position().unwrap(), 0);
}
