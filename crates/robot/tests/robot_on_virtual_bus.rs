//! The robot on the virtual CAN bus (the socketcand hub on loopback TCP): LSS brings three
//! simulated drives from "unconfigured" to nodes 2, 3, 4 and sets the bit rate; the robot
//! homes, runs each demo program and returns to the origin; wheel slip is detected and
//! corrected by the optical-mouse sensor; a drive that goes silent stops every wheel.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_can::socketcand::{Hub, HubConfig, SocketcandBus};
use motus_can::CanBus;
use motus_canopen::{LssMode, Master};
use motus_icla_sim::SimConfig;
use motus_omni::{Program, Ramp, Robot, RobotConfig, WheelDrives};
use motus_robot::sensor::SensorReader;
use motus_robot::sim::{SimRobot, SimRobotConfig};
use motus_robot::{CanopenWheels, WheelSettings};
use std::sync::Arc;
use std::time::Duration;

fn hub() -> Hub {
    Hub::start(HubConfig { listen: "127.0.0.1:0".parse().unwrap(), bitrate: None, channel: "can0".into() })
        .unwrap()
}

fn connect(hub: &Hub) -> Arc<dyn CanBus> {
    Arc::new(SocketcandBus::connect(hub.local_addr(), "can0").unwrap())
}

#[test]
fn lss_configures_three_unconfigured_drives_as_nodes_2_3_4_and_sets_20_kbit() {
    let hub = hub();
    let drives = [101, 102, 103].map(SimConfig::unconfigured);
    let sim = SimRobot::start(connect(&hub), SimRobotConfig { drives, ..SimRobotConfig::seed() }).unwrap();
    let master = Master::new(connect(&hub));
    std::thread::sleep(Duration::from_millis(150));
    let mut found = Vec::new();
    for node in [2u8, 3, 4] {
        let id = master
            .lss_fastscan(Duration::from_millis(30))
            .unwrap()
            .expect("an unconfigured drive answers fastscan");
        found.push(id.serial);
        master.lss_configure_node_id(node).unwrap();
        master.lss_configure_bit_timing(20_000).unwrap();
        master.lss_store().unwrap();
        master.lss_switch_global(LssMode::Waiting).unwrap();
        master.wait_boot(node, Duration::from_secs(2)).unwrap();
    }
    found.sort_unstable();
    assert_eq!(found, vec![101, 102, 103]);
    assert!(master.lss_fastscan(Duration::from_millis(30)).unwrap().is_none(), "nobody is left unconfigured");
    let mut ids: Vec<_> = motus_icla_sim::lock(sim.drives()).iter().map(|d| d.node_id()).collect();
    ids.sort_unstable();
    assert_eq!(ids, vec![Some(2), Some(3), Some(4)]);
    // Bit rate: 50 kbit/s on all three, then back to the robot's 20 kbit/s (LSS table
    // index 7), each time configured, stored and activated on every node.
    for (bitrate, index) in [(50_000u32, 6u8), (20_000, 7)] {
        master.lss_switch_global(LssMode::Configuration).unwrap();
        master.lss_configure_bit_timing(bitrate).unwrap();
        master.lss_store().unwrap();
        master.lss_activate_bit_timing(50).unwrap();
        std::thread::sleep(Duration::from_millis(150));
        master.lss_switch_global(LssMode::Waiting).unwrap();
        for d in motus_icla_sim::lock(sim.drives()).iter() {
            assert_eq!(d.lss().bitrate(), bitrate, "node {:?}", d.node_id());
            assert_eq!(d.lss().stored().1, index, "stored table index");
        }
    }
}

fn robot_on(hub: &Hub, sim: &SimRobot) -> Robot<CanopenWheels> {
    let _ = sim;
    let master = Arc::new(Master::new(connect(hub)));
    let mut wheels = CanopenWheels::bring_up(master, &WheelSettings::default()).unwrap();
    wheels.home().unwrap();
    Robot::new(wheels, RobotConfig::default()).unwrap()
}

#[test]
fn every_demo_program_returns_each_wheel_to_within_1_inc_of_the_origin() {
    let hub = hub();
    let sim = SimRobot::start(connect(&hub), SimRobotConfig::seed()).unwrap();
    let mut robot = robot_on(&hub, &sim);
    for name in ["line", "square", "octagon"] {
        let program = Program::by_name(name).unwrap();
        robot.run_program(&program, Ramp::RAMP_1).unwrap();
        let p = robot.drives_mut().positions().unwrap();
        assert!(p.iter().all(|w| w.abs() <= 1), "{name}: wheels at {p:?}");
    }
    // The wheels are back exactly; the body is back within the path error that integer
    // wheel speeds cause (wheels of one move finish a few ms apart), a few millimetres.
    let truth = sim.true_pose();
    assert!(truth.x.hypot(truth.y) < 0.01 && truth.heading.abs() < 0.01, "{truth:?}");
}

fn robot_with_sensor(hub: &Hub, sim: &SimRobot) -> (Robot<CanopenWheels>, SensorReader) {
    let robot = robot_on(hub, sim);
    let path = sim.mouse_path().unwrap().to_string_lossy().to_string();
    let reader = SensorReader::start(&path, robot.sensor_input()).unwrap();
    (robot, reader)
}

#[test]
fn with_wheel_slip_the_fused_pose_stays_within_1_cm_of_the_truth() {
    let hub = hub();
    let dir = tempfile::tempdir().unwrap();
    let cfg = SimRobotConfig { mouse_link: Some(dir.path().join("mouse")), ..SimRobotConfig::seed() };
    let sim = SimRobot::start(connect(&hub), cfg).unwrap();
    let (mut robot, _reader) = robot_with_sensor(&hub, &sim);
    // Wheel 2 delivers only 85 % of its travel to the floor.
    sim.set_slip([0.0, 0.15, 0.0]);
    robot.run_program(&Program::by_name("square").unwrap(), Ramp::RAMP_1).unwrap();
    std::thread::sleep(Duration::from_millis(50));
    let fused = robot.refresh().unwrap();
    let truth = sim.true_pose();
    let err = |p: motus_omni::Pose| (p.x - truth.x).hypot(p.y - truth.y);
    eprintln!(
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
}

#[test]
fn a_silent_drive_is_detected_within_its_consumer_time_and_every_wheel_stops() {
    let hub = hub();
    let sim = SimRobot::start(connect(&hub), SimRobotConfig::seed()).unwrap();
    let master = Arc::new(Master::new(connect(&hub)));
    let settings = WheelSettings::default();
    let mut wheels = CanopenWheels::bring_up(master, &settings).unwrap();
    wheels.home().unwrap();
    let p = motus_omni::WheelProfile { velocity: 500, acceleration: 1000, deceleration: 400 };
    wheels.move_relative([5000, -2500, -2500], [p; 3]).unwrap();
    std::thread::sleep(Duration::from_millis(600));
    let silenced = std::time::Instant::now();
    motus_icla_sim::lock(sim.drives())[1].set_silent(true);
    // Wait for the watchdog.
    while wheels.stop_reason().is_none() {
        assert!(silenced.elapsed() < Duration::from_secs(2), "lost drive not detected");
        std::thread::sleep(Duration::from_millis(1));
    }
    let detected = silenced.elapsed();
    let reason = wheels.stop_reason().unwrap();
    eprintln!("detected after {detected:?}: {reason}");
    assert!(reason.contains("node 3") && reason.contains("heartbeat"), "{reason}");
    // Consumer time 300 ms after the last heartbeat (every 100 ms): at most ~400 ms.
    assert!(detected <= settings.heartbeat_timeout + Duration::from_millis(150), "{detected:?}");
    // The other wheels stop on their quick-stop ramp (2000 Inc/s^2 from 500 Inc/s: 0.25 s).
    std::thread::sleep(Duration::from_millis(500));
    let g = motus_icla_sim::lock(sim.drives());
    for i in [0, 2] {
        assert_eq!(g[i].velocity(), 0, "wheel {} still turning", i + 1);
    }
    drop(g);
    // Further motion is refused with the reason.
    let e = wheels.move_relative([10, 10, 10], [p; 3]).unwrap_err();
    assert!(e.to_string().contains("node 3"), "{e}");
}

#[test]
fn a_drive_fault_stops_the_robot_and_is_reset_once_its_cause_is_gone() {
    let hub = hub();
    let sim = SimRobot::start(connect(&hub), SimRobotConfig::seed()).unwrap();
    let master = Arc::new(Master::new(connect(&hub)));
    let mut wheels = CanopenWheels::bring_up(master, &WheelSettings::default()).unwrap();
    let p = motus_omni::WheelProfile { velocity: 500, acceleration: 1000, deceleration: 400 };
    wheels.move_relative([3000, -1500, -1500], [p; 3]).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    motus_icla_sim::lock(sim.drives())[0].inject_fault(0x4310);
    let t = std::time::Instant::now();
    while wheels.stop_reason().is_none() {
        assert!(t.elapsed() < Duration::from_secs(1), "EMCY not acted on");
        std::thread::sleep(Duration::from_millis(1));
    }
    let reason = wheels.stop_reason().unwrap();
    assert!(reason.contains("node 2") && reason.contains("4310"), "{reason}");
    std::thread::sleep(Duration::from_millis(500));
    assert!(motus_icla_sim::lock(sim.drives()).iter().all(|d| d.velocity() == 0));
    // Cause still present: the fault reset is refused, by name.
    let e = wheels.enable().unwrap_err();
    assert!(e.to_string().contains("fault reset refused"), "{e}");
    motus_icla_sim::lock(sim.drives())[0].clear_fault_cause();
    wheels.enable().unwrap();
    wheels.move_relative([100, -50, -50], [p; 3]).unwrap();
    assert!(wheels.wait_reached(Duration::from_secs(5)).unwrap());
}
