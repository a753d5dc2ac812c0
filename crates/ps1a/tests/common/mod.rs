//! A simulated PS1A line on a real pseudo-terminal, served by a thread, and a host bus
//! opened on it like any serial port.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use motus_axis::{wait_until, Axis, AxisCommand, Scale};
use motus_ps1a::{AxisConfig, Ps1aAxis, Ps1aBus};
use motus_ps1a_protocol::{Acceleration, Parameters, U24};
use motus_ps1a_sim::{LineOptions, SimLine};
use motus_serial::{BusConfig, BusMaster, LineSettings, PtyLink, SerialLink, ServeThread};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

pub const BAUD: u32 = 115_200;

pub struct Sim {
    pub path: PathBuf,
    line: ServeThread<SimLine>,
}

impl Sim {
    pub fn start(path: &Path, options: LineOptions) -> Sim {
        let pty = PtyLink::create(Some(path), LineSettings::n81(BAUD)).unwrap();
        let line = SimLine::new(Box::new(pty), options).unwrap();
        Sim { path: path.to_path_buf(), line: ServeThread::spawn("ps1a-sim", line, SimLine::run).unwrap() }
    }

    /// Stops the simulator and returns it (its modules can then be inspected).
    pub fn stop(self) -> SimLine {
        self.line.stop().unwrap()
    }
}

pub fn bus(path: &Path, config: BusConfig) -> Ps1aBus {
    let link = SerialLink::open(path.to_str().unwrap(), BAUD).unwrap();
    Ps1aBus::new(Arc::new(BusMaster::new(Box::new(link), config)))
}

/// Fast homing parameters for tests (the factory VNRB of 10 takes seconds).
pub fn fast_params(addr: u8, max: u32) -> Parameters {
    Parameters {
        address: addr,
        max_position: U24::new(max).unwrap(),
        vnrb: 200,
        anrb: Acceleration::new(10).unwrap(),
        vnnb: 20,
        annb: Acceleration::new(10).unwrap(),
        ..Parameters::default()
    }
}

pub fn axis(bus: &Ps1aBus, addr: u8, max: u32) -> Ps1aAxis {
    let config = AxisConfig {
        addr,
        max_position: U24::new(max).unwrap(),
        speed: 2000,
        acceleration: Acceleration::new(10).unwrap(),
        scale: Scale::HUNDREDTH_MM,
        ..AxisConfig::default()
    };
    Ps1aAxis::new(bus.clone(), config)
}

pub fn wait_idle(axis: &mut dyn Axis) -> motus_axis::AxisState {
    let motus_axis::WaitOutcome::Done(s) = wait_until(
        axis,
        "motion",
        Duration::from_secs(60),
        Duration::from_millis(5),
        |s| !s.flags.moving,
        |_| {},
    )
    .unwrap();
    s
}

pub fn prepare(bus: &Ps1aBus, addr: u8, max: u32) -> Ps1aAxis {
    bus.write_parameters(addr, fast_params(addr, max)).unwrap();
    let mut a = axis(bus, addr, max);
    a.execute(&AxisCommand::Enable).unwrap();
    a.execute(&AxisCommand::Home).unwrap();
    let s = wait_idle(&mut a);
    assert!(s.flags.homed, "{s:?}");
    a
}

/// Metres for a position in device units (0.01 mm).
pub fn m(units: i64) -> f64 {
    units as f64 * 1e-5
}
