//! `motus sim icla` (simulated CiA 402 drives on a CAN bus, optionally forming the
//! omnidirectional robot) and `motus sim mouse` (the optical-mouse converter on a pty).

use crate::cli_can::{SimIclaArgs, SimMouseArgs};
use anyhow::{bail, Context, Result};
use motus_can::decorate::{FaultConfig, FaultyBus};
use motus_can::CanBus;
use motus_icla_sim::{lock, SimConfig, SimDrive};
use motus_mouse_protocol::DeviceType;
use motus_mouse_sim::{MouseSensor, SensorConfig};
use motus_robot::sim::{SimRobot, SimRobotConfig};
use motus_serial::{LineSettings, Link, PtyLink};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A scheduled fault: (node, after, code, clear after).
struct ScheduledFault {
    node: u8,
    at: Duration,
    code: Option<u16>,
    clear: Option<Duration>,
}

fn parse_schedule(text: &str, with_code: bool) -> Result<ScheduledFault> {
    let parts: Vec<&str> = text.split(':').collect();
    let num = |s: &str| super::canopen::number(s);
    let node = parts.first().context("node missing").and_then(|s| Ok(u8::try_from(num(s)?)?))?;
    let at = Duration::from_millis(parts.get(1).context("time missing").and_then(|s| num(s))?);
    let code = if with_code {
        let c = parts.get(2).context("code missing (hex, e.g. 0x4310)")?;
        Some(u16::try_from(num(c)?)?)
    } else {
        None
    };
    let clear = match parts.get(if with_code { 3 } else { 2 }) {
        Some(s) => Some(Duration::from_millis(num(s)?)),
        None => None,
    };
    Ok(ScheduledFault { node, at, code, clear })
}

/// Runs `motus sim icla`.
pub fn icla(a: SimIclaArgs) -> Result<()> {
    if let Some(path) = &a.write_eds {
        let eds = SimDrive::new(SimConfig::node(a.node.unwrap_or(127))).eds();
        std::fs::write(path, eds).with_context(|| format!("cannot write {}", path.display()))?;
        println!("EDS written to {}", path.display());
        return Ok(());
    }
    let uri = a.bus.as_deref().context("--bus <uri> is needed")?;
    let mut configs: Vec<SimConfig> = a.nodes.iter().map(|n| SimConfig::node(*n)).collect();
    configs.extend(a.unconfigured.iter().map(|s| SimConfig::unconfigured(*s)));
    if configs.is_empty() {
        configs.push(SimConfig::node(a.node.unwrap_or(127)));
    }
    for c in &mut configs {
        c.boot_delay = Duration::from_millis(a.boot_delay_ms);
        if !(1..=127).contains(&c.node_id) && c.node_id != motus_icla_sim::config::UNCONFIGURED {
            bail!("node id {} outside 1..=127", c.node_id);
        }
    }
    if !(0.0..=1.0).contains(&a.corrupt_rate) {
        bail!("--corrupt-rate must be between 0 and 1");
    }
    let mut bus: Arc<dyn CanBus> = motus_can::open_bus(uri).with_context(|| format!("cannot join {uri}"))?;
    if a.corrupt_rate > 0.0 {
        bus = Arc::new(FaultyBus::new(
            bus,
            FaultConfig { corrupt: a.corrupt_rate, on_send: true, ..FaultConfig::default() },
        ));
    }
    let stop = super::stop_flag()?;
    let robot = a.robot_mouse.is_some() || !a.slip.is_empty();
    let description: Vec<String> = configs
        .iter()
        .map(|c| {
            if c.node_id == 0xFF {
                format!("unconfigured serial {}", c.identity.serial)
            } else {
                format!("node {}", c.node_id)
            }
        })
        .collect();
    let (drives, robot, drives_thread) = if robot {
        let [d1, d2, d3]: [SimConfig; 3] = configs
            .try_into()
            .map_err(|_| anyhow::anyhow!("the robot needs exactly three drives (--nodes 2,3,4)"))?;
        let slip: [f64; 3] = match a.slip.as_slice() {
            [] => [0.0; 3],
            [s1, s2, s3] => [*s1, *s2, *s3],
            _ => bail!("--slip needs three values, e.g. 0.1,0,0"),
        };
        if slip.iter().any(|s| !(0.0..1.0).contains(s)) {
            bail!("--slip values must be in 0..1");
        }
        let mouse_link = match &a.robot_mouse {
            Some(spec) => Some(spec.strip_prefix("pty:").context("--robot-mouse expects pty:PATH")?.into()),
            None => None,
        };
        let cfg = SimRobotConfig { drives: [d1, d2, d3], slip, mouse_link, ..SimRobotConfig::seed() };
        let robot = SimRobot::start(bus, cfg)?;
        (Arc::clone(robot.drives()), Some(robot), None)
    } else {
        let drives: motus_icla_sim::SharedDrives =
            Arc::new(std::sync::Mutex::new(configs.into_iter().map(SimDrive::new).collect()));
        let (d, s) = (Arc::clone(&drives), Arc::clone(&stop));
        let t = std::thread::spawn(move || motus_icla_sim::run_shared(bus, d, s));
        (drives, None, Some(t))
    };
    eprintln!("simulated IclA drives ready on {uri}: {}; Ctrl-C to stop", description.join(", "));
    let silence =
        a.silence.as_deref().map(|s| parse_schedule(s, false)).transpose().context("--silence NODE:MS")?;
    let fault = a
        .fault
        .as_deref()
        .map(|s| parse_schedule(s, true))
        .transpose()
        .context("--fault NODE:MS:CODE[:CLEAR]")?;
    let start = Instant::now();
    let (mut silenced, mut faulted, mut cleared) = (false, false, false);
    let mut drives_thread = drives_thread;
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(5));
        // The bus closed (the hub stopped): the drives are cut off; exit, as a process
        // supervisor expects, instead of running on with nothing to serve.
        let failure = match drives_thread.take_if(|t| t.is_finished()) {
            Some(t) => match t.join() {
                Ok(Ok(())) => None,
                Ok(Err(e)) => Some(e.to_string()),
                Err(_) => Some("the drives' thread panicked".to_owned()),
            },
            None => robot.as_ref().and_then(SimRobot::bus_failure),
        };
        if let Some(reason) = failure {
            bail!("the CAN bus {uri} is gone ({reason}): the simulated drives stop; start the simulator again when the bus is back");
        }
        let t = start.elapsed();
        let mut g = lock(&drives);
        if let Some(s) = &silence {
            if !silenced && t >= s.at {
                if let Some(d) = g.iter_mut().find(|d| d.node_id() == Some(s.node)) {
                    d.set_silent(true);
                    eprintln!("fault injection: node {} silent", s.node);
                }
                silenced = true;
            }
        }
        if let Some(f) = &fault {
            if !faulted && t >= f.at {
                if let Some(d) = g.iter_mut().find(|d| d.node_id() == Some(f.node)) {
                    d.inject_fault(f.code.unwrap_or(0x4310));
                    eprintln!("fault injection: node {} fault 0x{:04X}", f.node, f.code.unwrap_or(0));
                }
                faulted = true;
            }
            if faulted && !cleared && f.clear.is_some_and(|c| t >= f.at + c) {
                if let Some(d) = g.iter_mut().find(|d| d.node_id() == Some(f.node)) {
                    d.clear_fault_cause();
                    eprintln!("fault injection: node {} fault cause cleared", f.node);
                }
                cleared = true;
            }
        }
    }
    Ok(())
}

/// Runs `motus sim mouse`: the converter on a pty, moving at a constant scripted velocity.
pub fn mouse(a: SimMouseArgs) -> Result<()> {
    let path = a.link.strip_prefix("pty:").context("--link expects pty:PATH")?;
    let [vx, vy] = a.velocity.as_slice() else { bail!("--velocity needs x,y in mm/s") };
    let (vx, vy) = (*vx / 1000.0, *vy / 1000.0);
    let device = DeviceType::from_byte(u8::try_from(a.device).context("--device must be one ASCII letter")?);
    let config = SensorConfig { device, garbage_rate: a.garbage_rate, ..SensorConfig::default() };
    let mut sensor = MouseSensor::new(config)?;
    let motion = sensor.motion();
    let mut link = PtyLink::create(Some(Path::new(path)), LineSettings::n81(9600))
        .with_context(|| format!("cannot create the pty link {path}"))?;
    let stop = super::stop_flag()?;
    let feeder_stop = Arc::new(AtomicBool::new(false));
    let fs = Arc::clone(&feeder_stop);
    std::thread::spawn(move || {
        let step = Duration::from_millis(5);
        while !fs.load(Ordering::Relaxed) {
            std::thread::sleep(step);
            motion.add_displacement(vx * step.as_secs_f64(), vy * step.as_secs_f64());
        }
    });
    eprintln!("simulated mouse converter ready on {path}; Ctrl-C to stop");
    let stats = motus_mouse_sim::serve(&mut link as &mut dyn Link, &mut sensor, &stop)?;
    feeder_stop.store(true, Ordering::Relaxed);
    eprintln!("mouse converter stopped: {stats:?}");
    Ok(())
}
