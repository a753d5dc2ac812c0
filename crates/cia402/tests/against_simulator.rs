//! Smoke test on real time: the driver against the simulated IclA drive (motus-icla-sim)
//! served by its own runtime thread (`run_shared`) on an in-process bus, with the PDO set
//! (RPDO controlword, TPDO statusword cache), as on a real bus minus the socket. It checks
//! function only, with generous liveness time-outs; the behaviour (where-at-t, homing,
//! quick stop, faults, heartbeat lease, refusals) is tested on virtual time in
//! `virtual_time.rs`, where nothing depends on the host's load.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_can::{CanBus, MemoryHub};
use motus_canopen::Master;
use motus_cia402::{CanopenDrive, Drive, DriveSettings, MoveKind, Profile};
use motus_cia402_protocol::{Mode, PowerState};
use motus_icla_sim::{SharedDrives, SimConfig, SimDrive};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Duration;

struct Rig {
    drives: SharedDrives,
    stop: Arc<AtomicBool>,
    drive: Drive<CanopenDrive>,
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
    }
}

fn rig() -> Rig {
    let hub = MemoryHub::new();
    let drives: SharedDrives = Arc::new(Mutex::new(vec![SimDrive::new(SimConfig::node(5))]));
    let stop = Arc::new(AtomicBool::new(false));
    let sim_bus: Arc<dyn CanBus> = Arc::new(hub.connect());
    let master = Arc::new(Master::new(Arc::new(hub.connect())));
    let (d, s) = (Arc::clone(&drives), Arc::clone(&stop));
    std::thread::spawn(move || motus_icla_sim::run_shared(sim_bus, d, s));
    // The drive's boot-up message (liveness bound only).
    master.wait_boots(5, 1, Duration::from_secs(10)).expect("no boot-up");
    let mut io = CanopenDrive::new(master, 5);
    io.use_pdos().unwrap();
    let drive = Drive::new(io, DriveSettings::default());
    Rig { drives, stop, drive }
}

#[test]
fn enable_move_and_disable_over_pdos_on_real_time() {
    let mut r = rig();
    let d = &mut r.drive;
    d.enable().unwrap();
    d.set_profile(&Profile::ICLA_SEED).unwrap();
    d.start_move(300, MoveKind::Absolute, true).unwrap();
    // ~1.4 s of motion; the time-out is a liveness bound only.
    assert_eq!(d.wait_target_reached(Duration::from_secs(30)).unwrap(), 300);
    assert_eq!(motus_icla_sim::lock(&r.drives)[0].position(), 300);
    assert_eq!(d.mode_display().unwrap(), Mode::ProfilePosition);
    d.disable().unwrap();
    assert_eq!(d.state().unwrap().0, PowerState::ReadyToSwitchOn);
}
