//! The simulated KV-01 arm and the arm controller in one process on virtual time ([`Rig`]:
//! the simulator's serve step runs inline in the driver's threads through a `SimLink`, on a
//! threaded virtual clock), and the simulator on a real pseudo-terminal served by a thread
//! ([`PtySim`], for the smoke tests).
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_clock::{Clock, VirtualClock};
use motus_kv01::{ArmConfig, Kv01Arm, Kv01Bus};
use motus_kv01_protocol::CrcMode;
use motus_kv01_sim::{lock, LineOptions, SharedArm, SimLine};
use motus_serial::{BusConfig, BusMaster, LineSettings, PtyLink, SerialLink, ServeThread};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

pub const BAUD: u32 = 115_200;

/// The driver's bus and the simulated arm on one threaded virtual clock. The test thread
/// takes part in the clock: it waits with [`Rig::sleep`], never on the wall clock.
pub struct Rig {
    pub clock: VirtualClock,
    /// The simulated arm (lock it with [`lock`]).
    pub sim: SharedArm,
    /// The line's bus master; every arm opened on the rig shares it.
    pub bus: Kv01Bus,
    /// Time zero of the simulation.
    start: Instant,
}

impl Rig {
    pub fn new(options: LineOptions, bus: BusConfig) -> Rig {
        let clock = VirtualClock::threaded();
        let (link, sim) = SimLine::sim_link(options, LineSettings::n81(BAUD), clock.shared()).unwrap();
        let start = link.start();
        let master = BusMaster::with_clock(Box::new(link), bus, clock.shared());
        Rig { clock, sim, bus: Kv01Bus::new(Arc::new(master), CrcMode::Strict), start }
    }

    /// The simulated arm with default options and a default bus.
    pub fn default_arm() -> Rig {
        Rig::new(LineOptions::default(), BusConfig::default())
    }

    /// Starts an arm controller on the rig's line (on the rig's clock, the bus master's).
    pub fn open(&self, config: ArmConfig) -> Kv01Arm {
        Kv01Arm::start(self.bus.clone(), config).unwrap()
    }

    /// Waits `d` of virtual time (the controller keeps running meanwhile).
    pub fn sleep(&self, d: Duration) {
        self.clock.sleep(d);
    }

    /// A few controller cycles.
    pub fn settle(&self) {
        self.sleep(Duration::from_millis(100));
    }

    /// Virtual time since `t0`.
    pub fn since(&self, t0: Instant) -> Duration {
        self.clock.elapsed(t0)
    }

    /// Brings the simulated arm up to now (the line does so on every transaction; this is
    /// for a silent line).
    pub fn tick(&self) {
        let now = self.clock.elapsed(self.start);
        lock(&self.sim).advance_to(now);
    }

    /// The simulator's true angle of joint `j`, degrees.
    pub fn truth(&self, j: u8) -> f64 {
        lock(&self.sim).joint_angles()[usize::from(j) - 1]
    }
}

/// The simulator on a real pty served by its own thread (stops serving, first field:
/// dropped first, before the folder of its pty goes).
pub struct PtySim {
    _line: ServeThread<SimLine>,
    pub dir: tempfile::TempDir,
    pub path: PathBuf,
    pub arm: SharedArm,
}

impl PtySim {
    pub fn start(options: LineOptions) -> PtySim {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("arm");
        let pty = PtyLink::create(Some(&path), LineSettings::n81(BAUD)).unwrap();
        let line = SimLine::new(Box::new(pty), options).unwrap();
        let arm = line.arm();
        PtySim { _line: ServeThread::spawn("kv01-sim", line, SimLine::run).unwrap(), dir, path, arm }
    }

    /// An arm controller opened on the pty like on a real serial port (system clock).
    pub fn open(&self, config: ArmConfig, bus: BusConfig) -> Kv01Arm {
        open_port(&self.path, config, bus)
    }
}

pub fn open_port(path: &Path, config: ArmConfig, bus: BusConfig) -> Kv01Arm {
    let link = SerialLink::open(path.to_str().unwrap(), BAUD).unwrap();
    let bus = Kv01Bus::new(Arc::new(BusMaster::new(Box::new(link), bus)), CrcMode::Strict);
    Kv01Arm::start(bus, config).unwrap()
}
