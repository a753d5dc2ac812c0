//! The KV-01 driver against the simulated arm over a real pty (acceptance 2-4 of the
//! KV-01 issue).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::*;
use motus_kv01::ArmConfig;
use motus_kv01_sim::{lock, LineOptions};
use motus_serial::BusConfig;
use std::time::Duration;

#[test]
fn enable_release_move_and_back() {
    let sim = Sim::start(LineOptions::default());
    let arm = sim.open(ArmConfig::default(), BusConfig::default());
    arm.power_up(2).unwrap();
    settle();
    let s = arm.joint(2).unwrap();
    assert!(s.enabled && s.status.brake_released, "{s:?}");
    arm.move_joints(&[(2, 30.0)], None, None).unwrap();
    let s = arm.wait_idle(&[2], Duration::from_secs(30)).unwrap();
    let truth = lock(&sim.arm).joint_angles()[1];
    assert!((s[0].angle_deg - 30.0).abs() <= 0.1, "{s:?}");
    assert!((truth - 30.0).abs() <= 0.1, "simulator's true angle {truth}");
}

#[test]
fn status_is_fresh_right_after_brake_release() {
    let sim = Sim::start(LineOptions::default());
    let arm = sim.open(ArmConfig::default(), BusConfig::default());
    for _ in 0..5 {
        arm.power_up(2).unwrap();
        let s = arm.joint(2).unwrap();
        assert!(s.enabled && s.status.brake_released, "{s:?}");
        arm.move_joints(&[(2, 20.0)], None, None).unwrap();
        arm.stop(2).unwrap();
        arm.disable(2).unwrap();
        let s = arm.joint(2).unwrap();
        assert!(!s.enabled && !s.status.brake_released, "{s:?}");
    }
}
