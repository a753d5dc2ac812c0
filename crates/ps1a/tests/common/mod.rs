//! A simulated PS1A line, and a host bus on it: on a real pseudo-terminal served by a
//! thread (real time), or in process on a [`SimLink`] (virtual time).
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use motus_axis::{Axis, AxisCommand, AxisError, AxisState, Scale};
use motus_clock::{SharedClock, VirtualClock};
use motus_ps1a::{AxisConfig, Ps1aAxis, Ps1aBus};
use motus_ps1a_protocol::{Acceleration, Parameters, U24};
use motus_ps1a_sim::{LineOptions, Modules, SimLine};
use motus_serial::{BusConfig, BusMaster, LineSettings, Link, NullLink, PtyLink, SerialLink, ServeThread};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};
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

/// A line's link the test can unplug and plug another simulated line into (a simulator
/// restart), while the host's bus master keeps it.
pub type Cable = Arc<Mutex<Box<dyn Link>>>;

/// A simulated line served in process on a virtual clock, with baud-rate pacing (every
/// exchange takes its wire time at 115200 Bd), and the host's bus on it.
pub struct Virtual {
    pub clock: VirtualClock,
    pub modules: Arc<Mutex<Modules>>,
    pub cable: Cable,
    pub bus: Ps1aBus,
}

/// The modules of `options` served in process on `clock`; the line's link and modules.
pub fn sim_link(options: LineOptions, clock: &VirtualClock) -> (Box<dyn Link>, Arc<Mutex<Modules>>) {
    let options = LineOptions { baud_pacing: true, ..options };
    let line = SimLine::with_clock(Box::new(NullLink::new(LineSettings::n81(BAUD))), options, clock.shared())
        .unwrap();
    let (link, modules) = line.into_sim_link();
    (Box::new(link), modules)
}

impl Virtual {
    pub fn start(options: LineOptions, config: BusConfig) -> Virtual {
        let clock = VirtualClock::new();
        let (link, modules) = sim_link(options, &clock);
        let cable: Cable = Arc::new(Mutex::new(link));
        let master = BusMaster::with_clock(Box::new(Arc::clone(&cable)), config, clock.shared());
        Virtual { clock, modules, cable, bus: Ps1aBus::new(Arc::new(master)) }
    }

    /// The simulated modules (the truth).
    pub fn modules(&self) -> MutexGuard<'_, Modules> {
        self.modules.lock().unwrap()
    }
}

/// Polls `axis` every 5 ms on `clock` until it stops moving or reports a fault (at most
/// 10 minutes of the clock's time); the last state. A read that got no reply in time (the
/// bus to blame: over a pty beside CPU hogs, three attempts of 101 ms once went unanswered)
/// is asked again within that bound; any other error fails.
pub fn wait_stopped(axis: &mut dyn Axis, clock: &SharedClock) -> AxisState {
    let t0 = clock.now();
    loop {
        let s = match axis.read_state() {
            Ok(s) => s,
            Err(e @ AxisError::Timeout { .. }) => {
                assert!(clock.elapsed(t0) < Duration::from_secs(600), "no answer for 10 minutes: {e}");
                clock.sleep(Duration::from_millis(5));
                continue;
            }
            Err(e) => panic!("reading the axis failed: {e}"),
        };
        if !s.flags.moving || !s.faults.is_empty() {
            return s;
        }
        assert!(clock.elapsed(t0) < Duration::from_secs(600), "still moving after 10 minutes: {s:?}");
        clock.sleep(Duration::from_millis(5));
    }
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

/// Waits on the clock of `bus` until `axis` stops moving, without a fault.
pub fn wait_idle(bus: &Ps1aBus, axis: &mut dyn Axis) -> AxisState {
    let s = wait_stopped(axis, bus.master().clock());
    assert!(s.faults.is_empty(), "{:?}", s.faults);
    s
}

pub fn prepare(bus: &Ps1aBus, addr: u8, max: u32) -> Ps1aAxis {
    bus.write_parameters(addr, fast_params(addr, max)).unwrap();
    let mut a = axis(bus, addr, max);
    a.execute(&AxisCommand::Enable).unwrap();
    a.execute(&AxisCommand::Home).unwrap();
    let s = wait_idle(bus, &mut a);
    assert!(s.flags.homed, "{s:?}");
    a
}

/// Metres for a position in device units (0.01 mm).
pub fn m(units: i64) -> f64 {
    units as f64 * 1e-5
}
