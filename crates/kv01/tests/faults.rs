//! Acceptance 4 of the KV-01 issue, in one process on virtual time: with 1 % corrupted
//! bytes (both directions) and 1 % dropped replies (seeded) for a minute
//! (`MOTUS_KV01_FAULT_SECONDS` to change), no joint moves unintentionally, every move
//! ends within a tenth of a degree, and the keep-alive never lapses: the longest gap
//! between two correct replies from each module stays below 700 ms, and no module latches
//! "TO".
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::*;
use motus_clock::Clock;
use motus_kv01::ArmConfig;
use motus_kv01_sim::{lock, LineOptions};
use motus_serial::{BusConfig, FaultConfig};
use std::time::{Duration, Instant};

/// What a run of [`one_percent_faults_for`] saw.
#[derive(Debug, PartialEq)]
struct Figures {
    moves: usize,
    longest_gap: Duration,
    transactions: u64,
    corrupt_frames: u64,
    timeouts: u64,
    retries: u64,
}

#[test]
fn one_percent_faults_for_a_minute() {
    let seconds: u64 =
        std::env::var("MOTUS_KV01_FAULT_SECONDS").ok().and_then(|s| s.parse().ok()).unwrap_or(60);
    let f = one_percent_faults_for(seconds);
    assert!(f.moves >= 6, "every move of the cycle ran at least once: {f:?}");
    assert!(f.corrupt_frames + f.timeouts > 0, "faults were injected and detected: {f:?}");
}

#[test]
fn the_same_seed_gives_the_same_run() {
    let a = one_percent_faults_for(5);
    let b = one_percent_faults_for(5);
    assert_eq!(a, b);
}

/// Moves joints 1-3 in turn for `seconds` of virtual time with 1 % faults (seed 11),
/// checking every move and the idle joints, then the keep-alive.
fn one_percent_faults_for(seconds: u64) -> Figures {
    let wall = Instant::now();
    let faults = FaultConfig { drop_rate: 0.01, corrupt_rate: 0.01, seed: 11 };
    let rig = Rig::new(
        LineOptions { faults, ..LineOptions::default() }.seeded(11),
        BusConfig { margin: Duration::from_millis(10), retries: 3 },
    );
    let arm = rig.open(ArmConfig::default());
    for j in 1..=5 {
        arm.power_up(j).unwrap();
    }
    let idle = [4usize, 5];
    let idle_start: Vec<f64> = idle.iter().map(|&j| lock(&rig.sim).joint_angles()[j - 1]).collect();
    let moves = [(1u8, 30.0), (2, -15.0), (3, 40.0), (1, -30.0), (2, 20.0), (3, -10.0)];
    let t0 = rig.clock.now();
    let mut k = 0;
    while rig.since(t0) < Duration::from_secs(seconds) {
        let (j, target) = moves[k % moves.len()];
        k += 1;
        let before = lock(&rig.sim).joint_angles();
        arm.move_joints(&[(j, target)], Some(30.0), Some(60.0)).unwrap();
        // While it moves, the idle joints stay where they are.
        let started = rig.clock.now();
        while arm.joint(j).unwrap().moving {
            assert!(rig.since(started) < Duration::from_secs(30), "the move of joint {j} never ends");
            let now = lock(&rig.sim).joint_angles();
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
            rig.sleep(Duration::from_millis(5));
        }
        let s = arm.joint(j).unwrap();
        assert!(s.fault.is_none(), "{s:?}");
        let truth = rig.truth(j);
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
        assert!(!lock(&rig.sim).state(s.joint).unwrap().timed_out, "module of joint {} latched TO", s.joint);
    }
    let stats = arm.bus().master().stats();
    eprintln!(
        "{k} moves in {seconds} s of virtual time ({:?} of wall time); longest gap between correct replies {worst:?}; \
         {} transactions, {} corrupt frames, {} time-outs, {} retries",
        wall.elapsed(),
        stats.totals.ok,
        stats.totals.corrupt_frames,
        stats.totals.timeouts,
        stats.totals.retries
    );
    Figures {
        moves: k,
        longest_gap: worst,
        transactions: stats.totals.ok,
        corrupt_frames: stats.totals.corrupt_frames,
        timeouts: stats.totals.timeouts,
        retries: stats.totals.retries,
    }
}
