//! Acceptance 4 of the KV-01 issue: with 1 % corrupted bytes (both directions) and 1 %
//! dropped replies for 60 s (`MOTUS_KV01_FAULT_SECONDS` to change), no joint moves
//! unintentionally and the keep-alive never lapses: the longest gap between two correct
//! replies from each module stays below 700 ms, and no module latches "TO".
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::*;
use motus_kv01::ArmConfig;
use motus_kv01_sim::{lock, LineOptions};
use motus_serial::{BusConfig, FaultConfig};
use std::time::{Duration, Instant};

#[test]
fn one_percent_faults_for_a_minute() {
    let seconds: u64 =
        std::env::var("MOTUS_KV01_FAULT_SECONDS").ok().and_then(|s| s.parse().ok()).unwrap_or(60);
    let faults = FaultConfig { drop_rate: 0.01, corrupt_rate: 0.01, seed: 11 };
    let sim = Sim::start(LineOptions { faults, ..LineOptions::default() }.seeded(11));
    let arm = sim.open(ArmConfig::default(), BusConfig { margin: Duration::from_millis(10), retries: 3 });
    for j in 1..=5 {
        arm.power_up(j).unwrap();
    }
    let idle = [4usize, 5];
    let idle_start: Vec<f64> = idle.iter().map(|&j| lock(&sim.arm).joint_angles()[j - 1]).collect();
    let moves = [(1u8, 30.0), (2, -15.0), (3, 40.0), (1, -30.0), (2, 20.0), (3, -10.0)];
    let t0 = Instant::now();
    let mut k = 0;
    while t0.elapsed() < Duration::from_secs(seconds) {
        let (j, target) = moves[k % moves.len()];
        k += 1;
        let before = lock(&sim.arm).joint_angles();
        arm.move_joints(&[(j, target)], Some(30.0), Some(60.0)).unwrap();
        // While it moves, the idle joints stay where they are.
        while arm.joint(j).unwrap().moving {
            let now = lock(&sim.arm).joint_angles();
            for (n, &i) in idle.iter().enumerate() {
                assert!(
                    (now[i - 1] - idle_start[n]).abs() < 0.01,
                    "idle joint {i} moved: {} -> {}",
                    idle_start[n],
                    now[i - 1]
                );
            }
            // Joints not commanded in this move keep their angle.
            for other in 1..=3usize {
                if other != usize::from(j) {
                    assert!(
                        (now[other - 1] - before[other - 1]).abs() < 0.05,
                        "joint {other} moved unintentionally"
                    );
                }
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        let s = arm.joint(j).unwrap();
        assert!(s.fault.is_none(), "{s:?}");
        let truth = lock(&sim.arm).joint_angles()[usize::from(j) - 1];
        assert!((truth - target).abs() <= 0.1, "joint {j} ended at {truth} instead of {target}");
    }
    let mut worst = Duration::ZERO;
    for s in arm.joints() {
        assert!(
            s.longest_gap < Duration::from_millis(700),
            "joint {}: longest gap {:?}",
            s.joint,
            s.longest_gap
        );
        worst = worst.max(s.longest_gap);
        assert!(!lock(&sim.arm).state(s.joint).unwrap().timed_out, "module of joint {} latched TO", s.joint);
    }
    let stats = arm.bus().master().stats();
    eprintln!(
        "{k} moves in {seconds} s; longest gap between correct replies {worst:?}; {} transactions, {} corrupt frames, {} time-outs, {} retries",
        stats.totals.ok, stats.totals.corrupt_frames, stats.totals.timeouts, stats.totals.retries
    );
    assert!(stats.totals.corrupt_frames + stats.totals.timeouts > 0, "faults were injected and detected");
}
