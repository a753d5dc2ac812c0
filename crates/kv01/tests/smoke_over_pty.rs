//! Smoke tests of the driver against the simulator over a real pseudo-terminal, on the
//! system clock (the behaviours themselves are checked on virtual time in `arm.rs` and
//! `faults.rs`). Time-outs are generous liveness bounds; figures are printed, not
//! asserted.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::*;
use motus_kv01::ArmConfig;
use motus_kv01_sim::{lock, ArmConfig as SimArmConfig, LineOptions};
use motus_serial::{BusConfig, FaultConfig};
use std::time::{Duration, Instant};

#[test]
fn a_joint_moves_over_a_pty() {
    let sim = PtySim::start(LineOptions::default());
    let arm = sim.open(ArmConfig::default(), BusConfig::default());
    arm.power_up(2).unwrap();
    let t0 = Instant::now();
    arm.move_joints(&[(2, 10.0)], Some(40.0), Some(80.0)).unwrap();
    let s = arm.wait_idle(&[2], Duration::from_secs(60)).unwrap();
    let truth = lock(&sim.arm).joint_angles()[1];
    eprintln!("moved to {:.3} deg (true {truth:.3}) in {:?}", s[0].angle_deg, t0.elapsed());
    assert!((truth - 10.0).abs() <= 0.1, "simulator's true angle {truth}");
}

#[test]
fn moves_complete_with_faults_injected_over_a_pty() {
    let faults = FaultConfig { drop_rate: 0.01, corrupt_rate: 0.01, seed: 11 };
    // A liveness margin: the modules' communication watchdog (700 ms) would latch a joint when
    // a loaded host delays the controller's commands beyond it (the watchdog itself is
    // checked in `motus-kv01-sim`'s `tests/safety.rs`).
    let mut arm = SimArmConfig::default();
    arm.cm.safety_timeout_ms = 3000.0;
    let sim = PtySim::start(LineOptions { faults, arm, ..LineOptions::default() }.seeded(11));
    let arm = sim.open(ArmConfig::default(), BusConfig { margin: Duration::from_millis(100), retries: 3 });
    arm.power_up(1).unwrap();
    for target in [5.0, -5.0] {
        arm.move_joints(&[(1, target)], Some(30.0), Some(60.0)).unwrap();
        if let Err(e) = arm.wait_idle(&[1], Duration::from_secs(60)) {
            let truth = lock(&sim.arm).joint_angles();
            panic!("{e:?}; the simulator's true angles {truth:?}; the host's view {:?}", arm.joints());
        }
    }
    let worst = arm.joints().iter().map(|s| s.longest_gap).max().unwrap_or_default();
    let stats = arm.bus().master().stats();
    eprintln!(
        "longest gap between correct replies {worst:?}; {} transactions, {} corrupt frames, {} time-outs, {} retries",
        stats.totals.ok, stats.totals.corrupt_frames, stats.totals.timeouts, stats.totals.retries
    );
    assert!(arm.joints().iter().all(|s| s.fault.is_none()), "{:?}", arm.joints());
}
