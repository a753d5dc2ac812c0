//! The simulated KV-01 arm on a real pseudo-terminal, served by a thread, and an arm
//! controller opened on it like on a real serial port.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use motus_kv01::{ArmConfig, Kv01Arm, Kv01Bus};
use motus_kv01_protocol::CrcMode;
use motus_kv01_sim::{LineOptions, SharedArm, SimLine};
use motus_serial::{BusConfig, BusMaster, LineSettings, PtyLink, SerialLink, ServeThread};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

pub const BAUD: u32 = 115_200;

/// Stops serving (first field: dropped first) before the folder of its pty goes.
pub struct Sim {
    _line: ServeThread<SimLine>,
    pub dir: tempfile::TempDir,
    pub path: PathBuf,
    pub arm: SharedArm,
}

impl Sim {
    pub fn start(options: LineOptions) -> Sim {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("arm");
        let pty = PtyLink::create(Some(&path), LineSettings::n81(BAUD)).unwrap();
        let line = SimLine::new(Box::new(pty), options).unwrap();
        let arm = line.arm();
        Sim { _line: ServeThread::spawn("kv01-sim", line, SimLine::run).unwrap(), dir, path, arm }
    }

    pub fn open(&self, config: ArmConfig, bus: BusConfig) -> Kv01Arm {
        open(&self.path, config, bus)
    }
}

pub fn open(path: &Path, config: ArmConfig, bus: BusConfig) -> Kv01Arm {
    let link = SerialLink::open(path.to_str().unwrap(), BAUD).unwrap();
    let bus = Kv01Bus::new(Arc::new(BusMaster::new(Box::new(link), bus)), CrcMode::Strict);
    Kv01Arm::start(bus, config).unwrap()
}

pub fn settle() {
    std::thread::sleep(Duration::from_millis(100));
}
