//! The driver against the simulated IclA drive (motus-icla-sim) through the CANopen master
//! on an in-process bus: the same code path as on a real bus, minus the socket.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_can::{CanBus, MemoryHub};
use motus_canopen::Master;
use motus_canopen_protocol::cia402::{Mode, PowerState};
use motus_cia402::{CanopenDrive, Drive, DriveError, DriveIo, DriveSettings, MoveKind, Profile};
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
    let (d, s) = (Arc::clone(&drives), Arc::clone(&stop));
    std::thread::spawn(move || motus_icla_sim::run_shared(sim_bus, d, s));
    let master = Arc::new(Master::new(Arc::new(hub.connect())));
    std::thread::sleep(Duration::from_millis(50));
    let mut io = CanopenDrive::new(master, 5);
    io.use_pdos().unwrap();
    let drive = Drive::new(io, DriveSettings::default());
    Rig { drives, stop, drive }
}

#[test]
fn enable_move_quick_stop_and_recover() {
    let mut r = rig();
    let d = &mut r.drive;
    d.enable().unwrap();
    d.set_profile(&Profile::ICLA_SEED).unwrap();
    d.start_move(500, MoveKind::Absolute, true).unwrap();
    assert_eq!(d.wait_target_reached(Duration::from_secs(10)).unwrap(), 500);
    d.start_move(-200, MoveKind::Relative, true).unwrap();
    assert_eq!(d.wait_target_reached(Duration::from_secs(10)).unwrap(), 300);
    // Quick stop with option 2 (quick-stop ramp, then switch on disabled) mid-move.
    d.set_quick_stop_option(2).unwrap();
    d.set_quick_stop_deceleration(4000).unwrap();
    d.start_move(5000, MoveKind::Absolute, true).unwrap();
    std::thread::sleep(Duration::from_millis(500));
    d.quick_stop().unwrap();
    d.wait_state(PowerState::SwitchOnDisabled).unwrap_or_else(|_| {
        std::thread::sleep(Duration::from_millis(500));
        d.wait_state(PowerState::SwitchOnDisabled).unwrap()
    });
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(motus_icla_sim::lock(&r.drives)[0].velocity(), 0);
    let stopped_at = d.position().unwrap();
    assert!(stopped_at > 300 && stopped_at < 5000, "{stopped_at}");
    r.drive.enable().unwrap();
    assert_eq!(r.drive.mode_display().unwrap(), Mode::ProfilePosition);
}

#[test]
fn homing_velocity_limits_and_refusals() {
    let mut r = rig();
    let d = &mut r.drive;
    d.enable().unwrap();
    d.run_velocity(200).unwrap();
    std::thread::sleep(Duration::from_millis(400));
    assert!(d.velocity().unwrap() > 0);
    d.halt().unwrap();
    d.wait_standstill(Duration::from_secs(3)).unwrap();
    d.home(35, Duration::from_secs(5)).unwrap();
    assert_eq!(d.position().unwrap(), 0);
    d.set_software_limits(-1000, 1000).unwrap();
    assert!(matches!(d.start_move(1001, MoveKind::Absolute, true), Err(DriveError::BeyondLimit { .. })));
    // Unsupported mode: the IclA lists pp, pv, hm in 0x6502.
    assert!(matches!(d.set_mode(Mode::CyclicSyncPosition), Err(DriveError::ModeUnsupported { .. })));
    // A read-only object refuses a write, by name.
    let e = d.io().write(0x6041, 0, &[0, 0]).unwrap_err();
    assert!(e.to_string().contains("read-only") || e.to_string().contains("0x06010002"), "{e}");
}

#[test]
fn a_blocked_load_gives_a_following_error_fault_that_resets_when_freed() {
    let mut r = rig();
    r.drive.enable().unwrap();
    r.drive.set_following_error(50, 100).unwrap();
    motus_icla_sim::lock(&r.drives)[0].set_load_blocked(true);
    r.drive.start_move(2000, MoveKind::Absolute, true).unwrap();
    let e = r.drive.wait_target_reached(Duration::from_secs(5)).unwrap_err();
    assert!(matches!(e, DriveError::FollowingError { .. } | DriveError::Fault { .. }), "{e}");
    std::thread::sleep(Duration::from_millis(200));
    let (state, _) = r.drive.state().unwrap();
    assert_eq!(state, PowerState::Fault);
    assert_eq!(r.drive.error_code(), Some(0x8611));
    motus_icla_sim::lock(&r.drives)[0].set_load_blocked(false);
    r.drive.fault_reset().unwrap();
    r.drive.enable().unwrap();
}
