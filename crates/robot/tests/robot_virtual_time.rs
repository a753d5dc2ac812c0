//! The robot against its simulation in one process, on **virtual time**: the CANopen
//! master ([`Master::with_threaded_clock`]), the wheels' driver and watchdog, the controller
//! and the sensor reader run on a threaded [`VirtualClock`] shared with the simulated robot
//! ([`SimRobot::in_process`]: three simulated IclA drives as the in-process peer of a
//! threaded `PairBus`, the world and the optical-mouse sensor). The code under test is the
//! production path (`Robot` -> `CanopenWheels` -> `Drive`/`CanopenDrive` -> `Master` ->
//! `CanBus`; `SensorReader` -> `FramedLink` -> `Link`); only the clock and the links differ
//! from the robot on a real bus. Time moves only when every thread waits, so the figures
//! below (when a loss is detected, when a bit rate switches) are exact and do not depend on
//! the host's load, and minutes of motion take seconds.
//!
//! LSS configures three drives as nodes 2, 3, 4 and sets the bit rate; every demo program
//! returns each wheel within 1 Inc of the origin; with wheel slip the fused pose stays
//! within 1 cm; a silent drive is detected within its consumer time and every wheel stops;
//! a drive fault stops the robot and is reset. `robot_on_virtual_bus.rs` keeps one smoke
//! test on the socketcand hub over TCP.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_can::pair::SETTLE;
use motus_canopen::{LssMode, Master};
use motus_clock::{Clock, VirtualClock};
use motus_icla_sim::SimConfig;
use motus_omni::{Program, Ramp, Robot, RobotConfig, WheelDrives, WheelProfile};
use motus_robot::sensor::SensorReader;
use motus_robot::sim::{SimRobot, SimRobotConfig};
use motus_robot::{CanopenWheels, WheelSettings};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A simulated robot and a master on one threaded virtual clock.
struct Rig {
    clock: VirtualClock,
    sim: SimRobot,
    master: Arc<Master>,
    wall: Instant,
    name: &'static str,
}

fn rig(name: &'static str, config: SimRobotConfig) -> Rig {
    let wall = Instant::now();
    let clock = VirtualClock::threaded();
    let sim = SimRobot::in_process(config, clock.shared()).unwrap();
    let master = Arc::new(Master::with_threaded_clock(sim.pair_bus().unwrap(), clock.shared()));
    Rig { clock, sim, master, wall, name }
}

impl Rig {
    /// Prints (with --nocapture) the virtual time the test simulated and the wall time it
    /// took. (Called at the end: while the threads are joined afterwards, time may move on.)
    fn report(&self) {
        println!(
            "{}: {:.3} s virtual in {:.2} s wall",
            self.name,
            self.clock.since_base().as_secs_f64(),
            self.wall.elapsed().as_secs_f64()
        );
    }

    /// Virtual time since the start.
    fn t(&self) -> Duration {
        self.clock.since_base()
    }

    fn drives(&self) -> std::sync::MutexGuard<'_, Vec<motus_icla_sim::SimDrive>> {
        motus_icla_sim::lock(self.sim.drives())
    }

    /// Polls `done` every millisecond of virtual time until it holds; fails with `what`
    /// after `timeout`. Returns the virtual time it took.
    fn eventually(&self, timeout: Duration, what: &str, mut done: impl FnMut() -> bool) -> Duration {
        let t0 = self.clock.now();
        while !done() {
            assert!(self.clock.elapsed(t0) < timeout, "{what} (waited {timeout:?} of virtual time)");
            self.clock.sleep(Duration::from_millis(1));
        }
        self.clock.elapsed(t0)
    }

    fn wheels(&self) -> CanopenWheels {
        CanopenWheels::bring_up(Arc::clone(&self.master), &WheelSettings::default()).unwrap()
    }

    fn robot(&self) -> Robot<CanopenWheels> {
        let mut wheels = self.wheels();
        wheels.home().unwrap();
        Robot::with_clock(wheels, RobotConfig::default(), self.clock.shared()).unwrap()
    }
}

#[test]
fn lss_configures_three_unconfigured_drives_as_nodes_2_3_4_and_sets_20_kbit() {
    let drives = [101, 102, 103].map(SimConfig::unconfigured);
    let r = rig("LSS", SimRobotConfig { drives, ..SimRobotConfig::seed() });
    let m = &r.master;
    let mut found = Vec::new();
    for node in [2u8, 3, 4] {
        let t0 = r.t();
        let id = m.lss_fastscan(Duration::from_millis(30)).unwrap().expect("an unconfigured drive answers");
        println!("fastscan found serial {} in {:?} of virtual time", id.serial, r.t() - t0);
        found.push(id.serial);
        m.lss_configure_node_id(node).unwrap();
        m.lss_configure_bit_timing(20_000).unwrap();
        m.lss_store().unwrap();
        m.lss_switch_global(LssMode::Waiting).unwrap();
        // The new node id takes effect with a reset: the drive boots as `node` (its first
        // boot-up as that node, which may come within the switch's own send).
        m.wait_boots(node, 1, Duration::from_secs(2)).unwrap();
    }
    found.sort_unstable();
    assert_eq!(found, vec![101, 102, 103]);
    // Nobody answers any more: the scan ends after its first step's time-out.
    let t0 = r.t();
    assert!(m.lss_fastscan(Duration::from_millis(30)).unwrap().is_none(), "nobody is left unconfigured");
    assert_eq!(r.t() - t0, Duration::from_millis(30), "one unanswered step");
    let mut ids: Vec<_> = r.drives().iter().map(|d| d.node_id()).collect();
    ids.sort_unstable();
    assert_eq!(ids, vec![Some(2), Some(3), Some(4)]);
    // An LSS confirmation nobody gives fails after exactly its time-out of virtual time
    // (counted from its request, whose send settles for a nanosecond: see `SETTLE`).
    let t0 = r.t();
    let e = m.lss_inquire_node_id().unwrap_err();
    assert!(e.to_string().contains("inquire node-ID"), "{e}");
    assert_eq!(r.t() - t0, Duration::from_millis(500) + SETTLE);
    // Bit rate: 50 kbit/s on all three, then back to the robot's 20 kbit/s (LSS table
    // index 7), each time configured, stored and activated on every node: the drives switch
    // 50 ms after the activation (their next millisecond step after it), then stay silent
    // for another 50 ms (CiA 305), so the master waits that out before the next service.
    for (bitrate, index) in [(50_000u32, 6u8), (20_000, 7)] {
        m.lss_switch_global(LssMode::Configuration).unwrap();
        m.lss_configure_bit_timing(bitrate).unwrap();
        m.lss_store().unwrap();
        m.lss_activate_bit_timing(50).unwrap();
        let took = r.eventually(Duration::from_secs(1), "bit rate not activated", || {
            r.drives().iter().all(|d| d.lss().bitrate() == bitrate)
        });
        println!("{bitrate} bit/s active after {took:?}");
        assert!(took >= Duration::from_millis(50) && took <= Duration::from_millis(51), "{took:?}");
        r.clock.sleep(Duration::from_millis(50));
        m.lss_switch_global(LssMode::Waiting).unwrap();
        for d in r.drives().iter() {
            assert_eq!(d.lss().bitrate(), bitrate, "node {:?}", d.node_id());
            assert_eq!(d.lss().stored().1, index, "stored table index");
        }
    }
    r.report();
}

#[test]
fn every_demo_program_returns_each_wheel_to_within_1_inc_of_the_origin() {
    let r = rig("demo programs", SimRobotConfig::seed());
    let mut robot = r.robot();
    for name in ["line", "square", "octagon"] {
        let t0 = r.t();
        let program = Program::by_name(name).unwrap();
        robot.run_program(&program, Ramp::RAMP_1).unwrap();
        let p = robot.drives_mut().positions().unwrap();
        println!("{name}: {:.2} s of virtual time, wheels at {p:?}", (r.t() - t0).as_secs_f64());
        assert!(p.iter().all(|w| w.abs() <= 1), "{name}: wheels at {p:?}");
    }
    // The wheels are back exactly; the body is back within the path error that integer
    // wheel speeds cause (wheels of one move finish a few ms apart), a few millimetres.
    let truth = r.sim.true_pose();
    println!("true pose at the end: {truth:?}");
    assert!(truth.x.hypot(truth.y) < 0.01 && truth.heading.abs() < 0.01, "{truth:?}");
    r.report();
}

#[test]
fn with_wheel_slip_the_fused_pose_stays_within_1_cm_of_the_truth() {
    let r = rig("wheel slip", SimRobotConfig::seed());
    let mut robot = r.robot();
    let link = r.sim.take_sensor_link().unwrap();
    let _reader = SensorReader::start_on(link, robot.sensor_input(), r.clock.shared()).unwrap();
    // Wheel 2 delivers only 85 % of its travel to the floor.
    r.sim.set_slip([0.0, 0.15, 0.0]);
    robot.run_program(&Program::by_name("square").unwrap(), Ramp::RAMP_1).unwrap();
    r.clock.sleep(Duration::from_millis(50));
    let fused = robot.refresh().unwrap();
    let truth = r.sim.true_pose();
    let err = |p: motus_omni::Pose| (p.x - truth.x).hypot(p.y - truth.y);
    println!(
        "truth {truth:?}\nfused {:?} (error {:.4} m)\nwheel-only {:?} (error {:.4} m), {} slip events",
        fused.pose,
        err(fused.pose),
        fused.wheel_only_pose,
        err(fused.wheel_only_pose),
        fused.slip_detected_count
    );
    assert!(fused.slip_detected_count > 0, "the slip was detected");
    assert!(err(fused.pose) < 0.01, "fused pose within 1 cm of the truth");
    assert!(err(fused.wheel_only_pose) > 0.01, "wheel odometry alone is off by more");
    // The robot corrected its path: it is back near the origin.
    assert!(truth.x.hypot(truth.y) < 0.02, "{truth:?}");
    r.report();
}

#[test]
fn a_silent_drive_is_detected_within_its_consumer_time_and_every_wheel_stops() {
    let r = rig("silent drive", SimRobotConfig::seed());
    let settings = WheelSettings::default();
    let mut wheels = r.wheels();
    wheels.home().unwrap();
    let p = WheelProfile { velocity: 500, acceleration: 1000, deceleration: 400 };
    wheels.move_relative([5000, -2500, -2500], [p; 3]).unwrap();
    r.clock.sleep(Duration::from_millis(600));
    r.drives()[1].set_silent(true);
    // The drive's heartbeat comes every third of the consumer time (100 ms): the last one
    // came at most 100 ms before the silence, and the loss is reported the instant the
    // consumer time (300 ms) after it has passed.
    let detected =
        r.eventually(Duration::from_secs(2), "lost drive not detected", || wheels.stop_reason().is_some());
    let reason = wheels.stop_reason().unwrap();
    println!(
        "detected {detected:?} after the silence (consumer time {:?}): {reason}",
        settings.heartbeat_timeout
    );
    assert!(reason.contains("node 3") && reason.contains("heartbeat"), "{reason}");
    assert!(reason.contains("last seen 300.001ms ago"), "reported at the consumer time: {reason}");
    let period = settings.heartbeat_timeout / 3;
    assert!(
        detected > settings.heartbeat_timeout - period && detected <= settings.heartbeat_timeout,
        "detected {detected:?} after the silence"
    );
    // Every wheel stops on its quick-stop ramp (500 Inc/s at 2000 Inc/s^2: 0.25 s).
    let stopped = r.eventually(Duration::from_secs(1), "a wheel still turns", || {
        r.drives().iter().all(|d| d.velocity() == 0)
    });
    println!("every wheel stopped {stopped:?} after the detection");
    assert!(stopped <= Duration::from_millis(260), "{stopped:?}");
    // Further motion is refused with the reason.
    let e = wheels.move_relative([10, 10, 10], [p; 3]).unwrap_err();
    assert!(e.to_string().contains("node 3"), "{e}");
    r.report();
}

#[test]
fn a_drive_fault_stops_the_robot_and_is_reset_once_its_cause_is_gone() {
    let r = rig("drive fault", SimRobotConfig::seed());
    let mut wheels = r.wheels();
    let p = WheelProfile { velocity: 500, acceleration: 1000, deceleration: 400 };
    wheels.move_relative([3000, -1500, -1500], [p; 3]).unwrap();
    r.clock.sleep(Duration::from_millis(300));
    r.drives()[0].inject_fault(0x4310);
    // The EMCY leaves with the drive's next millisecond step; the watchdog quick-stops every
    // wheel at that instant.
    let reacted =
        r.eventually(Duration::from_secs(1), "EMCY not acted on", || wheels.stop_reason().is_some());
    println!("EMCY acted on after {reacted:?}");
    assert!(reacted <= Duration::from_millis(1), "{reacted:?}");
    let reason = wheels.stop_reason().unwrap();
    assert!(reason.contains("node 2") && reason.contains("4310"), "{reason}");
    let stopped = r.eventually(Duration::from_secs(1), "a wheel still turns", || {
        r.drives().iter().all(|d| d.velocity() == 0)
    });
    println!("every wheel stopped {stopped:?} after the reaction");
    // Cause still present: the fault reset is refused, by name.
    let e = wheels.enable().unwrap_err();
    assert!(e.to_string().contains("fault reset refused"), "{e}");
    r.drives()[0].clear_fault_cause();
    wheels.enable().unwrap();
    wheels.move_relative([100, -50, -50], [p; 3]).unwrap();
    let t0 = r.t();
    assert!(wheels.wait_reached(Duration::from_secs(5)).unwrap());
    println!("short move after the reset took {:?}", r.t() - t0);
    r.report();
}
