//! 1209A axes against two simulated controllers served in process on virtual time:
//! homing, POSITION and SPEED modes, limits clamping as the simulator does, ERROR on a limit
//! switch and recovery, ENABLE removal, and the 2 s command watchdog kept fed.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::*;
use motus_axis::{Axis, AxisCommand, AxisError, AxisState, Direction, FaultKind, MotionProfile};
use motus_nfv2::{AxisConfig, DeviceLimits, DriveConfig, IntentKind, Nfv2Axis, Nfv2Error, Scheduler};
use motus_nfv2_protocol::{DriveMode, DriveStatus};
use motus_nfv2_sim::LimitSwitch;
use std::sync::Arc;
use std::time::Duration;

fn scheduler(sim: &Sim) -> Arc<Scheduler> {
    let bus = sim.bus(Duration::from_millis(3));
    Arc::new(Scheduler::start(bus, vec![DriveConfig::new(1), DriveConfig::new(2)], fast_scheduler()).unwrap())
}

fn profile(velocity: f64, acceleration: f64) -> MotionProfile {
    MotionProfile { velocity: Some(velocity), acceleration: Some(acceleration), deceleration: None }
}

/// Polls the axis on virtual time until `done` (a fault fails the test); the last state.
fn wait_axis(
    sim: &Sim,
    axis: &mut Nfv2Axis,
    timeout: Duration,
    done: impl Fn(&AxisState) -> bool,
) -> AxisState {
    let mut last = None;
    let ok = sim.eventually(timeout, || {
        let s = axis.read_state().unwrap();
        assert!(s.faults.is_empty(), "{s:?}");
        let finished = done(&s);
        last = Some(s);
        finished
    });
    assert!(ok, "not done within {timeout:?}: {last:?}");
    last.unwrap()
}

#[test]
fn homing_then_position_and_speed_modes_on_two_controllers() {
    let sim = Sim::start(two_controllers());
    let sched = scheduler(&sim);
    let mut pan = Nfv2Axis::new(sched.drive(1).unwrap(), AxisConfig::new(1), "pan").unwrap();
    let mut tilt = Nfv2Axis::new(sched.drive(2).unwrap(), AxisConfig::new(2), "tilt").unwrap();
    // Power-on: mode ERROR, not homed; moves are refused before homing.
    let s = pan.read_state().unwrap();
    assert!(!s.flags.enabled && !s.flags.homed, "{s:?}");
    let refused = pan.execute(&AxisCommand::MoveAbsolute { target: 0.1, profile: MotionProfile::default() });
    assert!(matches!(refused, Err(AxisError::NotHomed { .. })), "{refused:?}");
    // The tilt starts closer to its HOME edge (at -20 000 counts) than the pan.
    sim.with(2, |c| c.place_axis(-15_000.0).unwrap());
    pan.execute(&AxisCommand::Home).unwrap();
    tilt.execute(&AxisCommand::Home).unwrap();
    for axis in [&mut pan, &mut tilt] {
        wait_axis(&sim, axis, Duration::from_secs(20), |s| s.flags.homed && !s.flags.moving);
    }
    for a in [1, 2] {
        // The hold was acknowledged; the drive switches at its next regulator cycle.
        let holding = || sim.with(a, |c| c.true_state().mode) == DriveMode::Position;
        assert!(sim.eventually(Duration::from_millis(100), holding), "homing ends holding in POSITION");
        let t = sim.with(a, |c| c.true_state());
        assert!(t.status.contains(DriveStatus::SYNCHRONIZED), "{t:?}");
        // The counter reads 0 at the edge of HOME (true position -20 000).
        assert!((t.position_counts + 20_000.0).abs() < 50.0 && t.counter.abs() < 50, "{t:?}");
    }
    // POSITION: 0.5 rad = 15 915.5 counts at 1 rad/s.
    pan.execute(&AxisCommand::MoveAbsolute { target: 0.5, profile: profile(1.0, 10.0) }).unwrap();
    wait_axis(&sim, &mut pan, Duration::from_secs(10), |s| s.flags.target_reached);
    // 0.5 rad is 15 915.5 counts: the target is 15 915, reached within the 5-count tolerance.
    let t = sim.with(1, |c| c.true_state());
    assert!((t.counter - 15_915).abs() <= 5, "{t:?}");
    let s = pan.read_state().unwrap();
    assert!((s.position_raw - 15_915).abs() <= 5, "{s:?}");
    // The tilt did not move meanwhile.
    assert!(sim.with(2, |c| c.true_state().counter).abs() < 50);
    // SPEED: jog the tilt at 0.2 rad/s = 6366 counts/s (637 units).
    tilt.execute(&AxisCommand::Jog { direction: Direction::Negative, profile: profile(0.2, 5.0) }).unwrap();
    sim.sleep(Duration::from_millis(800));
    let t = sim.with(2, |c| c.true_state());
    assert_eq!(t.mode, DriveMode::Speed);
    assert!((t.speed_counts_per_s + 6370.0).abs() < 200.0, "{t:?}");
    let s = tilt.read_state().unwrap();
    assert!(s.flags.moving && (s.velocity.unwrap() + 0.2).abs() < 0.02, "{s:?}");
    tilt.execute(&AxisCommand::Stop).unwrap();
    wait_axis(&sim, &mut tilt, Duration::from_secs(3), |s| !s.flags.moving);
    assert!(sim.with(2, |c| c.true_state().speed_counts_per_s).abs() < 100.0);
    // Relative move from the present position, then disable (mode ERROR).
    let before = tilt.read_state().unwrap().position;
    tilt.execute(&AxisCommand::MoveRelative { distance: 0.05, profile: profile(0.5, 5.0) }).unwrap();
    let moved = wait_axis(&sim, &mut tilt, Duration::from_secs(5), |s| s.flags.target_reached);
    assert!((moved.position - before - 0.05).abs() < 1e-3, "{moved:?}");
    tilt.execute(&AxisCommand::Disable).unwrap();
    assert!(
        sim.eventually(Duration::from_secs(1), || sim.with(2, |c| c.true_state().mode) == DriveMode::Error)
    );
    assert!(!tilt.read_state().unwrap().flags.enabled);
    // On virtual time no thread is ever held off the CPU: no answer is missed.
    let stats = sched.stats();
    eprintln!("{:?} of virtual time: {stats}", sim.clock.since_base());
    assert_eq!((stats.missed_answers, stats.overruns), (0, 0), "{stats}");
    assert!(stats.feasible, "{stats}");
}

#[test]
fn limits_clamp_as_the_simulator_does() {
    let sim = Sim::start(two_controllers());
    let sched = scheduler(&sim);
    let drive = sched.drive(1).unwrap();
    drive.enable().unwrap();
    drive
        .set_limits(DeviceLimits {
            position: Some((-10_000, 10_000)),
            max_speed: Some(2_000),
            max_current_ma: None,
            max_acceleration: Some(400_000),
        })
        .unwrap();
    // A target beyond the position limit at a speed beyond the speed limit: the drive
    // clamps both and says so (status bits 10 and 11).
    drive.move_to(30_000, Some(5_000), None).unwrap();
    let mut flagged = DriveStatus(0);
    let mut top_speed: f64 = 0.0;
    let ok = sim.eventually(Duration::from_secs(5), || {
        let s = drive.snapshot();
        flagged.0 |= s.raw_status.map_or(0, |w| w.0);
        top_speed = top_speed.max(sim.with(1, |c| c.true_state().speed_counts_per_s));
        s.position.is_some_and(|p| (p.counts - 10_000).abs() <= 5) && !s.moving
    });
    assert!(ok, "{:?}", drive.snapshot());
    assert!(
        flagged.contains(DriveStatus::POSITION_LIMIT) && flagged.contains(DriveStatus::SPEED_LIMIT),
        "{flagged}"
    );
    // The speed loop overshoots the clamped reference by a few percent at the end of the ramp.
    assert!(top_speed <= 20_000.0 * 1.05, "true speed {top_speed} counts/s beyond the 2000-unit limit");
    assert!((sim.with(1, |c| c.true_state().counter) - 10_000).abs() <= 5);
    // SPEED mode towards the lower limit: clamped to the speed limit, and the ramp stops
    // at the position limit.
    drive.jog(-5_000, None).unwrap();
    assert!(sim.eventually(Duration::from_secs(3), || {
        let t = sim.with(1, |c| c.true_state());
        t.counter < 0 && (t.speed_counts_per_s + 20_000.0).abs() < 600.0
    }));
    assert!(sim
        .eventually(Duration::from_secs(5), || sim.with(1, |c| c.true_state().speed_counts_per_s).abs()
            < 50.0));
    let end = sim.with(1, |c| c.true_state().counter);
    assert!((-10_050..=-9_900).contains(&end), "stopped at {end}");
    // The axis refuses targets beyond its soft limits on the host instead.
    let mut config = AxisConfig::new(1);
    config.soft_limits = Some((-0.1, 0.1));
    config.require_home = false;
    let mut axis = Nfv2Axis::new(drive.clone(), config, "pan").unwrap();
    let r = axis.execute(&AxisCommand::MoveAbsolute { target: 0.2, profile: MotionProfile::default() });
    assert!(matches!(r, Err(AxisError::BeyondLimit { .. })), "{r:?}");
}

#[test]
fn limit_switch_error_and_recovery() {
    let sim = Sim::start(two_controllers());
    let sched = scheduler(&sim);
    let drive = sched.drive(1).unwrap();
    let mut config = AxisConfig::new(1);
    config.require_home = false;
    let mut axis = Nfv2Axis::new(drive.clone(), config, "pan").unwrap();
    axis.execute(&AxisCommand::Enable).unwrap();
    drive.jog(3_000, None).unwrap();
    sim.sleep(Duration::from_millis(200));
    sim.with(1, |c| c.set_limit_switch(LimitSwitch::Up, Some(true)));
    assert!(
        sim.eventually(Duration::from_secs(1), || sim.with(1, |c| c.true_state().mode) == DriveMode::Error)
    );
    assert!(sim.eventually(Duration::from_secs(1), || drive.snapshot().intent == IntentKind::Faulted));
    let s = axis.read_state().unwrap();
    assert!(s.flags.limit_positive && !s.flags.enabled, "{s:?}");
    assert_eq!(s.faults.first().map(|f| f.kind), Some(FaultKind::LimitSwitch), "{s:?}");
    assert!(s.faults[0].reason.contains("LIM_POS"), "{s:?}");
    // Nothing is sent that could leave ERROR; moves are refused while the fault is latched.
    sim.sleep(Duration::from_millis(200));
    assert_eq!(sim.with(1, |c| c.true_state().mode), DriveMode::Error);
    assert!(matches!(drive.move_to(0, None, None), Err(Nfv2Error::Device { .. })));
    // Recovery: fault reset (leaves ERROR, holds), then only moves away from the switch.
    axis.execute(&AxisCommand::FaultReset).unwrap();
    assert!(sim
        .eventually(Duration::from_secs(1), || sim.with(1, |c| c.true_state().mode) == DriveMode::Position));
    let here = drive.snapshot().position.unwrap().counts;
    let towards = drive.move_to(here + 5_000, None, None);
    assert!(
        matches!(&towards, Err(Nfv2Error::Device { reason, .. }) if reason.contains("limit switch")),
        "{towards:?}"
    );
    drive.move_to(here - 5_000, None, None).unwrap();
    let s = drive.wait_idle(Duration::from_secs(5)).unwrap();
    assert!((s.position.unwrap().counts - (here - 5_000)).abs() <= 5, "{s:?}");
    sim.with(1, |c| c.set_limit_switch(LimitSwitch::Up, None));
    assert!(sim.eventually(Duration::from_secs(1), || !drive.snapshot().limit_up));
    drive.move_to(here, None, None).unwrap();
    assert!(drive.wait_idle(Duration::from_secs(5)).is_ok());
}

#[test]
fn enable_removal_stops_within_one_regulator_cycle() {
    let sim = Sim::start(two_controllers());
    let sched = scheduler(&sim);
    let drive = sched.drive(1).unwrap();
    drive.enable().unwrap();
    drive.jog(3_000, Some(400_000)).unwrap();
    sim.sleep(Duration::from_millis(400));
    // Remove ENABLE at a regulator cycle boundary and run exactly one more cycle.
    let (before, after) = sim.with(1, |c| {
        let before = c.true_state();
        c.set_enable(false);
        c.advance_to(before.time + Duration::from_millis(1));
        (before, c.true_state())
    });
    assert!(before.bridge_on && before.speed_counts_per_s > 29_000.0, "{before:?}");
    assert_eq!(after.time - before.time, Duration::from_millis(1));
    assert!(!after.bridge_on && after.mode == DriveMode::Error, "{after:?}");
    assert!(after.current_a.abs() < 0.05, "torque gone within the cycle: {after:?}");
    // The axis coasts down; the host reports the E-stop with its reason.
    assert!(
        sim.eventually(Duration::from_secs(1), || {
            drive.snapshot().faults.first().is_some_and(|f| f.kind == FaultKind::EmergencyStop)
        }),
        "{:?}",
        drive.snapshot()
    );
    assert!(sim
        .eventually(Duration::from_secs(2), || sim.with(1, |c| c.true_state().speed_counts_per_s).abs()
            < 1.0));
    // Closing the loop again restarts nothing.
    sim.with(1, |c| c.set_enable(true));
    sim.sleep(Duration::from_millis(300));
    let t = sim.with(1, |c| c.true_state());
    assert!(t.mode == DriveMode::Error && !t.bridge_on, "{t:?}");
    assert!(!drive.snapshot().enabled);
    // A fault reset does.
    drive.fault_reset().unwrap();
    assert!(sim.eventually(Duration::from_secs(1), || drive.snapshot().enabled));
    assert_eq!(sim.with(1, |c| c.true_state().mode), DriveMode::Position);
}

#[test]
fn enabling_without_enable_input_fails_with_the_reason() {
    let sim = Sim::start(two_controllers());
    let sched = scheduler(&sim);
    let drive = sched.drive(2).unwrap();
    sim.with(2, |c| c.set_enable(false));
    let t0 = sim.now();
    let r = drive.enable();
    assert!(matches!(&r, Err(Nfv2Error::Device { reason, .. }) if reason.contains("ENABLE")), "{r:?}");
    // It waited its confirmation time-out (1 s) for the status to leave ERROR, in
    // virtual time.
    let waited = sim.now() - t0;
    assert!(waited >= Duration::from_secs(1) && waited < Duration::from_millis(1_100), "{waited:?}");
}

#[test]
fn the_command_watchdog_never_trips_while_jogging() {
    let sim = Sim::start(two_controllers());
    let sched = scheduler(&sim);
    let drive = sched.drive(2).unwrap();
    drive.enable().unwrap();
    drive.jog(-400, None).unwrap();
    // Longer than the drive's 2 s watchdog: the speed is re-sent every cycle.
    sim.sleep(Duration::from_millis(2_600));
    let t = sim.with(2, |c| c.true_state());
    assert!((t.speed_counts_per_s + 4_000.0).abs() < 150.0, "{t:?}");
    assert!(!t.status.contains(DriveStatus::COMMUNICATION_FAULT), "{t:?}");
    drive.stop().unwrap();
    assert!(drive.wait_idle(Duration::from_secs(2)).is_ok());
}

#[test]
fn without_the_cycle_the_command_watchdog_stops_a_jog() {
    // The other side of the watchdog test: stopping the scheduler stops the frames, and
    // the drive zeroes its speed set-point 2 s later (status bit 7).
    let sim = Sim::start(two_controllers());
    let sched = scheduler(&sim);
    let drive = sched.drive(2).unwrap();
    drive.enable().unwrap();
    drive.jog(-400, None).unwrap();
    sim.sleep(Duration::from_millis(500));
    sched.shutdown();
    sim.sleep(Duration::from_millis(1_500));
    assert!((sim.with(2, |c| c.true_state().speed_counts_per_s) + 4_000.0).abs() < 150.0);
    sim.sleep(Duration::from_millis(1_000));
    let t = sim.with(2, |c| c.true_state());
    assert!(t.speed_counts_per_s.abs() < 150.0, "{t:?}");
    assert!(t.status.contains(DriveStatus::COMMUNICATION_FAULT), "{t:?}");
}
