//! `motus robot --bus <uri> ...`: the omnidirectional robot's supervisory commands.

use crate::cli_can::{RobotAction, RobotArgs};
use anyhow::{bail, Context, Result};
use motus_can::decorate::cycle_load;
use motus_can::CanFrame;
use motus_omni::controller::WheelDrives;
use motus_omni::{Program, Ramp, Robot, RobotConfig};
use motus_robot::sensor::SensorReader;
use motus_robot::{CanopenWheels, WheelSettings};
use std::time::Duration;

fn ramp(text: &str) -> Result<Ramp> {
    Ok(match text {
        "1" => Ramp::RAMP_1,
        "2" => Ramp::RAMP_2,
        "seed" => Ramp::SEED,
        other => bail!("--ramp {other:?}: expected 1, 2 or seed"),
    })
}

/// Runs a `robot` command.
pub fn run(a: RobotArgs) -> Result<()> {
    if let RobotAction::BusLoad { cycle_ms } = a.action {
        return bus_load(&a.nodes, cycle_ms);
    }
    let uri = a.bus.as_deref().context("--bus <uri> is needed (e.g. socketcand://127.0.0.1:29536/can0)")?;
    let nodes: [u8; 3] =
        a.nodes.as_slice().try_into().map_err(|_| anyhow::anyhow!("--nodes needs exactly three node ids"))?;
    let master = super::canopen::open_master(uri)?;
    if let RobotAction::Stop = a.action {
        for n in nodes {
            master.send_pdo(0x200 + u32::from(n), &0x0002u16.to_le_bytes())?;
        }
        println!("quick stop sent to nodes {nodes:?}");
        return Ok(());
    }
    let settings = WheelSettings { nodes, ..WheelSettings::default() };
    let mut wheels = CanopenWheels::bring_up(master, &settings).context("robot bring-up failed")?;
    if a.home {
        wheels.home()?;
    }
    let config = RobotConfig { ramp: ramp(&a.ramp)?, ..RobotConfig::default() };
    let mut robot = Robot::new(wheels, config).map_err(|e| anyhow::anyhow!("{e}"))?;
    let _reader = match &a.mouse {
        Some(path) => {
            Some(SensorReader::start(path, robot.sensor_input()).with_context(|| format!("--mouse {path}"))?)
        }
        None => None,
    };
    let result = match &a.action {
        RobotAction::Demo { program } => {
            let p = Program::by_name(program)
                .with_context(|| format!("unknown program {program:?} (line, square, octagon, zero)"))?;
            robot.run_program(&p, ramp(&a.ramp)?)
        }
        RobotAction::Goto { x, y, heading, via_origin } => {
            robot.goto(*x, *y, heading.map(f64::to_radians), *via_origin)
        }
        RobotAction::Pose | RobotAction::Stop | RobotAction::BusLoad { .. } => Ok(()),
    };
    // Give the sensor a last packet, then report.
    std::thread::sleep(Duration::from_millis(30));
    let pose = robot.refresh().map_err(|e| anyhow::anyhow!("{e}"))?;
    let wheels = robot.drives_mut().positions()?;
    if a.json {
        println!(
            "{{\"x\":{:.4},\"y\":{:.4},\"heading_deg\":{:.3},\"wheel_only\":{{\"x\":{:.4},\"y\":{:.4},\"heading_deg\":{:.3}}},\"slips\":{},\"wheels\":[{},{},{}]}}",
            pose.pose.x, pose.pose.y, pose.pose.heading.to_degrees(),
            pose.wheel_only_pose.x, pose.wheel_only_pose.y, pose.wheel_only_pose.heading.to_degrees(),
            pose.slip_detected_count, wheels[0], wheels[1], wheels[2]
        );
    } else {
        println!(
            "pose x {:.4} m, y {:.4} m, heading {:.2} deg (wheel odometry alone: {:.4}, {:.4}, {:.2} deg; {} slip events); wheels {:?} Inc",
            pose.pose.x, pose.pose.y, pose.pose.heading.to_degrees(),
            pose.wheel_only_pose.x, pose.wheel_only_pose.y, pose.wheel_only_pose.heading.to_degrees(),
            pose.slip_detected_count, wheels
        );
    }
    result.map_err(|e| anyhow::anyhow!("{e}"))
}

/// The robot's bus cost per control cycle: SYNC + 3 TPDO2 (statusword + position) +
/// 3 RPDO2 (controlword + target), at the seed's 20 kbit/s and at 1 Mbit/s.
fn bus_load(nodes: &[u8], cycle_ms: f64) -> Result<()> {
    if !(cycle_ms.is_finite() && cycle_ms > 0.0) {
        bail!("--cycle-ms must be positive");
    }
    let mut frames = vec![CanFrame::new(0x080, &[])?];
    for n in nodes {
        frames.push(CanFrame::new(0x280 + u32::from(*n), &[0; 6])?);
        frames.push(CanFrame::new(0x300 + u32::from(*n), &[0; 6])?);
    }
    let period = Duration::from_secs_f64(cycle_ms / 1000.0);
    for bitrate in [20_000u32, 1_000_000] {
        let l = cycle_load(&frames, period, bitrate);
        println!(
            "{} kbit/s: {} frames, {} bits worst case, busy {:.2} ms of a {cycle_ms} ms cycle = {:.1} %{}",
            bitrate / 1000,
            frames.len(),
            l.bits,
            l.busy.as_secs_f64() * 1000.0,
            l.fraction * 100.0,
            if l.fraction > 1.0 { " -- DOES NOT FIT" } else { "" }
        );
    }
    Ok(())
}
