//! The controller against fake drives that move a simulated world (with and without
//! slip) and feed a sensor: programs come back to the start, `goto` reaches its target,
//! slip is corrected by the correction moves, a drive error quick-stops every wheel, a move
//! that does not finish times out. The controller's times (sensor settling, move time-outs)
//! are on a virtual clock.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::sync::Arc;
use std::time::Duration;

use motus_clock::{Clock, VirtualClock};
use motus_mouse_protocol::Calibration;
use motus_omni::sync_profile::WheelProfile;
use motus_omni::{
    Geometry, Pose, Program, Ramp, Robot, RobotConfig, RobotError, RobotWorld, SensorInput, SlipTolerance,
    WheelDrives,
};

#[derive(Debug, thiserror::Error)]
#[error("fake drive failure: {0}")]
struct FakeError(&'static str);

/// Three fake drives: a move advances in 10 polls; each poll turns the world's wheels by a
/// tenth and sends the true translation to the sensor input (whole counts, remainder
/// carried).
struct FakeDrives {
    world: RobotWorld,
    positions: [f64; 3],
    pending: Option<([f64; 3], u32)>,
    sensor: Option<Arc<SensorInput>>,
    owed: [f64; 2],
    moves: Vec<([i32; 3], [WheelProfile; 3])>,
    quick_stops: u32,
    fail_on_move: Option<usize>,
}

impl FakeDrives {
    fn new(slip: [f64; 3]) -> FakeDrives {
        let mut world = RobotWorld::new(Geometry::default(), Pose::default());
        world.set_slip(slip);
        FakeDrives {
            world,
            positions: [100.0, -200.0, 300.0],
            pending: None,
            sensor: None,
            owed: [0.0; 2],
            moves: Vec::new(),
            quick_stops: 0,
            fail_on_move: None,
        }
    }
}

impl WheelDrives for FakeDrives {
    type Error = FakeError;

    fn positions(&mut self) -> Result<[i32; 3], FakeError> {
        Ok(self.positions.map(|p| p.round() as i32))
    }

    fn move_relative(&mut self, travel: [i32; 3], profiles: [WheelProfile; 3]) -> Result<(), FakeError> {
        if self.fail_on_move == Some(self.moves.len()) {
            return Err(FakeError("node 3: EMCY 0x7310"));
        }
        self.moves.push((travel, profiles));
        self.pending = Some((travel.map(f64::from), 0));
        Ok(())
    }

    fn wait_reached(&mut self, _timeout: Duration) -> Result<bool, FakeError> {
        let Some((travel, done)) = self.pending.as_mut() else { return Ok(true) };
        let ds = travel.map(|t| t / 10.0);
        let m = self.world.apply_wheel_inc(ds);
        for (p, d) in self.positions.iter_mut().zip(ds) {
            *p += d;
        }
        *done += 1;
        let finished = *done == 10;
        if finished {
            self.pending = None;
        }
        if let Some(s) = &self.sensor {
            let cal = Calibration::default();
            self.owed[0] += cal.metres_to_counts(m.x);
            self.owed[1] += cal.metres_to_counts(m.y);
            let c = self.owed.map(f64::round);
            self.owed[0] -= c[0];
            self.owed[1] -= c[1];
            s.add_counts(c[0] as i32, c[1] as i32);
        }
        Ok(finished)
    }

    fn quick_stop(&mut self) -> Result<(), FakeError> {
        self.quick_stops += 1;
        self.pending = None;
        Ok(())
    }
}

fn robot(slip: [f64; 3]) -> Robot<FakeDrives> {
    // A tighter relative slip tolerance than the default 2 % (the fake sensor has no scale
    // error): with 2 %, 10 % slip on a wheel that turns little (the octagon's wheel 2 on
    // its first side: 12 cm of 1 m) is within tolerance, unattributed, and its 21 mrad
    // heading error is not corrected. A 2 m window lets a slow slip build up past the
    // absolute 5 mm before the window is restarted.
    let config = RobotConfig {
        tolerance: SlipTolerance { relative: 0.005, window_m: 2.0, ..SlipTolerance::default() },
        ..RobotConfig::default()
    };
    let mut r = Robot::with_clock(FakeDrives::new(slip), config, VirtualClock::new().shared()).unwrap();
    let input = r.sensor_input();
    r.drives_mut().sensor = Some(input);
    r
}

#[test]
fn square_without_slip_returns_to_start() {
    let mut r = robot([0.0; 3]);
    let start = r.drives_mut().positions().unwrap();
    r.run_program(&Program::square(), Ramp::RAMP_1).unwrap();
    let truth = r.drives_mut().world.pose();
    let p = r.pose();
    // Programs run wheel-exact (the wheels return to exactly their start); the body ends
    // within the few millimetres that the rounding of each move's wheel travel leaves.
    assert!(truth.distance_to(&Pose::default()) < 0.005, "{truth:?}");
    let w = r.drives_mut().positions().unwrap();
    assert_eq!(w, start, "every wheel back at its start");
    assert!(p.pose.distance_to(&truth) < 0.002);
    assert_eq!(p.slip_detected_count, 0);
    // First move: (1065, 0) Inc -> wheels (1065, -532.5, -532.5) rounded, profiles scaled
    // from ramp 1 (500 Inc/s, 1000, 400) by 1 and 0.5.
    let (travel, prof) = r.drives_mut().moves[0];
    assert_eq!(travel[0], 1065);
    assert!((travel[1] + 532).abs() <= 1 && (travel[2] + 532).abs() <= 1);
    assert_eq!(prof[0], WheelProfile { velocity: 500, acceleration: 1000, deceleration: 400 });
    assert_eq!(prof[1].velocity, 250);
}

#[test]
fn octagon_with_slip_is_corrected() {
    let mut r = robot([0.0, 0.1, 0.0]);
    r.run_program(&Program::octagon(), Ramp::SEED).unwrap();
    let truth = r.drives_mut().world.pose();
    let p = r.pose();
    // The fused pose is trusted and the correction moves bring the robot back.
    assert!(truth.distance_to(&Pose::default()) < 0.01, "true end {truth:?}, fused {p:?}");
    assert!(p.slip_detected_count > 0);
    assert!(p.wheel_only_pose.distance_to(&truth) > 0.05, "{p:?} vs {truth:?}");
    // More moves than the program's eight: corrections were needed.
    assert!(r.drives_mut().moves.len() > 8);
}

#[test]
fn goto_with_heading_and_via_origin() {
    let mut r = robot([0.1, 0.0, 0.0]);
    r.goto(1.0, 0.5, Some(std::f64::consts::FRAC_PI_2), false).unwrap();
    let truth = r.drives_mut().world.pose();
    assert!((truth.x - 1.0).abs() < 0.01 && (truth.y - 0.5).abs() < 0.01, "{truth:?}");
    assert!((truth.heading - std::f64::consts::FRAC_PI_2).abs() < 0.02, "{truth:?}");
    let before = r.drives_mut().moves.len();
    r.goto(-0.3, 0.2, None, true).unwrap();
    let truth = r.drives_mut().world.pose();
    assert!((truth.x + 0.3).abs() < 0.01 && (truth.y - 0.2).abs() < 0.01, "{truth:?}");
    assert!(r.drives_mut().moves.len() >= before + 2);
}

#[test]
fn drive_error_quick_stops_everything() {
    let mut r = robot([0.0; 3]);
    r.drives_mut().fail_on_move = Some(1);
    let e = r.run_program(&Program::line(), Ramp::RAMP_2).unwrap_err();
    assert!(matches!(e, RobotError::Drive { quick_stop_error: None, .. }), "{e}");
    assert!(e.to_string().contains("EMCY 0x7310"));
    assert_eq!(r.drives_mut().quick_stops, 1);
}

#[test]
fn invalid_inputs_are_refused() {
    let mut r = robot([0.0; 3]);
    assert!(matches!(r.goto(f64::NAN, 0.0, None, false), Err(RobotError::InvalidTarget(_))));
    let bad = Ramp { velocity: 0.0, ..Ramp::SEED };
    assert!(matches!(r.run_program(&Program::line(), bad), Err(RobotError::InvalidRamp(_))));
    assert!(r.drives_mut().moves.is_empty());
}

/// Drives whose moves never finish: each wait takes its whole time-out on the clock.
struct StuckDrives {
    clock: VirtualClock,
    quick_stops: u32,
}

impl WheelDrives for StuckDrives {
    type Error = FakeError;

    fn positions(&mut self) -> Result<[i32; 3], FakeError> {
        Ok([0; 3])
    }

    fn move_relative(&mut self, _: [i32; 3], _: [WheelProfile; 3]) -> Result<(), FakeError> {
        Ok(())
    }

    fn wait_reached(&mut self, timeout: Duration) -> Result<bool, FakeError> {
        self.clock.sleep(timeout);
        Ok(false)
    }

    fn quick_stop(&mut self) -> Result<(), FakeError> {
        self.quick_stops += 1;
        Ok(())
    }
}

#[test]
fn a_move_that_does_not_finish_times_out_on_the_clock_and_quick_stops() {
    let clock = VirtualClock::new();
    let drives = StuckDrives { clock: clock.clone(), quick_stops: 0 };
    let mut r = Robot::with_clock(drives, RobotConfig::default(), clock.shared()).unwrap();
    let t0 = clock.now();
    let e = r.goto(0.1, 0.0, None, false).unwrap_err();
    let RobotError::MoveTimeout { timeout, quick_stop_error: None } = e else { panic!("{e}") };
    // 1.5 times the planned trapezoid plus the 2 s margin, polled every 10 ms cycle.
    let waited = clock.elapsed(t0);
    assert!(timeout > Duration::from_secs(2), "{timeout:?}");
    assert!(waited > timeout && waited <= timeout + Duration::from_millis(10), "{waited:?} for {timeout:?}");
    assert_eq!(r.drives_mut().quick_stops, 1);
}
