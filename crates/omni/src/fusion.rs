//! Wheel odometry fused with the optical-mouse sensor, and slip detection.
//!
//! The sensor is mounted **at the centre** of the chassis with its axes along the robot's
//! x and y, so it measures the robot-frame translation and nothing of a rotation about
//! the centre (a sensor off-centre would see `dtheta x offset` as well). It replaces the
//! seed's unsound rule ("new position = sensor/K - drive") with:
//!
//! * **Translation from the sensor.** Each update advances the fused pose by the
//!   sensor's translation (counts / counts-per-metre).
//! * **Rotation from the wheels.** Given the true translation `t`, every wheel gives an
//!   estimate of the rotation: `R dtheta = s_i - u_i . t` (see [`crate::kinematics`]).
//!   Without slip the three agree and their mean equals wheel odometry's rotation (it does
//!   not depend on `t`, so sensor quantisation does not disturb the heading). Once a wheel
//!   is known to slip, the mean of the other two is used.
//! * **Slip detection.** Over a window of travel, the wheel-only translation and the
//!   sensor's (both in the world frame) are compared; a disagreement beyond
//!   `absolute + relative * distance` is a [`SlipEvent`]. So is one wheel's rotation
//!   residual deviating from the other two's mean by more than
//!   `absolute + relative * (longest wheel travel)` (a slipping wheel that turns little
//!   hardly shows in the translation but turns the robot). The relative part absorbs a
//!   sensor scale error; slip below the tolerance is not attributed, and the heading error
//!   it causes is not corrected. The event names the slipping
//!   wheel when two wheels' window residuals agree and the third stands out; the window
//!   is then replayed from its start pose with the rotation of every step recomputed from
//!   the two good wheels (the window keeps each step's translation and residuals).
//!   A window that ends without disagreement clears the suspicion if the suspect wheel
//!   travelled at least 10 cm in it and agrees again.
//! * **No sensor data** (`None`): the wheels alone move the fused pose.
//!
//! One slipping wheel is handled; two slipping at once are detected but not attributed.

use serde::{Deserialize, Serialize};

use motus_mouse_protocol::Calibration;

use crate::kinematics::{robot_to_world, Geometry, Motion, Pose};
use crate::odometry::WheelOdometry;

/// When wheel odometry and the sensor disagree enough to call it slip.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SlipTolerance {
    /// Disagreement always tolerated, metres (default 5 mm).
    pub absolute_m: f64,
    /// Disagreement tolerated per metre travelled in the window (default 2 %).
    pub relative: f64,
    /// Travel after which a quiet window is restarted, metres (default 0.5 m).
    pub window_m: f64,
}

impl Default for SlipTolerance {
    fn default() -> Self {
        SlipTolerance { absolute_m: 0.005, relative: 0.02, window_m: 0.5 }
    }
}

/// Slip detected.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SlipEvent {
    /// Wheel-only versus sensor translation over the window, metres.
    pub disagreement_m: f64,
    /// Sensor travel over the window, metres.
    pub distance_m: f64,
    /// The slipping wheel (0, 1, 2 for wheels 1, 2, 3), when it can be told.
    pub wheel: Option<usize>,
    /// Heading correction applied to the fused pose, radians.
    pub heading_correction: f64,
}

/// The fused state.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct FusedPose {
    /// Best estimate: sensor translation, wheel rotation.
    pub pose: Pose,
    /// Dead reckoning from the wheels alone.
    pub wheel_only_pose: Pose,
    /// Slip events so far.
    pub slip_detected_count: u64,
    /// Disagreement in the current window at the last update, metres.
    pub last_disagreement: f64,
    /// The wheel currently believed to slip (0-based).
    pub suspect_wheel: Option<usize>,
}

/// A suspect wheel is cleared only after a quiet window in which it travelled this much
/// (metres): a wheel that hardly turns cannot show that it stopped slipping.
const MIN_EXERCISED_M: f64 = 0.1;

/// Steps kept per window at most (a longer window is restarted).
const MAX_WINDOW_STEPS: usize = 4096;

#[derive(Debug, Clone, Default)]
struct Window {
    start: Pose,
    /// Each step's sensor translation and residuals, for the replay.
    steps: Vec<([f64; 2], [f64; 3])>,
    wheel_world: [f64; 2],
    distance: f64,
    wheel_travel: [f64; 3],
    sensor_robot: [f64; 2],
    used_theta: f64,
}

/// The fusion filter.
#[derive(Debug, Clone)]
pub struct Fusion {
    geometry: Geometry,
    calibration: Calibration,
    tolerance: SlipTolerance,
    odometry: WheelOdometry,
    fused: Pose,
    suspect: Option<usize>,
    window: Window,
    slip_count: u64,
    last_disagreement: f64,
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

/// For wheel `i`: the spread of the other two residuals and `i`'s deviation from their
/// mean.
fn outlier(r: &[f64; 3], i: usize) -> (f64, f64) {
    let others: Vec<f64> = r.iter().enumerate().filter(|(j, _)| *j != i).map(|(_, v)| *v).collect();
    match (others.first(), others.get(1), r.get(i)) {
        (Some(a), Some(b), Some(v)) => ((a - b).abs(), (v - (a + b) / 2.0).abs()),
        _ => (0.0, 0.0),
    }
}

impl Fusion {
    /// A filter starting at `pose`; the first update only records the wheel positions.
    #[must_use]
    pub fn new(geometry: Geometry, calibration: Calibration, tolerance: SlipTolerance, pose: Pose) -> Fusion {
        Fusion {
            geometry,
            calibration,
            tolerance,
            odometry: WheelOdometry::new(geometry, pose),
            fused: pose,
            suspect: None,
            window: Window { start: pose, ..Window::default() },
            slip_count: 0,
            last_disagreement: 0.0,
        }
    }

    /// Sets both poses (e.g. after homing) and clears the window and the suspicion.
    pub fn reset(&mut self, pose: Pose) {
        self.odometry.set_pose(pose);
        self.fused = pose;
        self.suspect = None;
        self.window = Window { start: pose, ..Window::default() };
    }

    /// The fused state.
    #[must_use]
    pub fn state(&self) -> FusedPose {
        FusedPose {
            pose: self.fused,
            wheel_only_pose: self.odometry.pose(),
            slip_detected_count: self.slip_count,
            last_disagreement: self.last_disagreement,
            suspect_wheel: self.suspect,
        }
    }

    /// Per-wheel rotation residuals `s_i - u_i . t` (metres).
    fn residuals(&self, travel: [f64; 3], t: [f64; 2]) -> [f64; 3] {
        let ut = self.geometry.inverse(Motion::new(t[0], t[1], 0.0));
        [travel[0] - ut[0], travel[1] - ut[1], travel[2] - ut[2]]
    }

    /// Rotation (rad) from residuals: the mean of all wheels, or of the two not suspected.
    fn rotation(&self, r: [f64; 3], suspect: Option<usize>) -> f64 {
        let good: Vec<f64> =
            r.iter().enumerate().filter(|(i, _)| Some(*i) != suspect).map(|(_, v)| *v).collect();
        mean(&good) / self.geometry.radius
    }

    /// One update: new wheel positions (Inc) and the sensor counts received since the
    /// previous update (`None` when no sensor data is available).
    pub fn update(&mut self, positions: [i32; 3], sensor_counts: Option<(i32, i32)>) -> Option<SlipEvent> {
        let step = self.odometry.update(positions);
        let Some((cx, cy)) = sensor_counts else {
            self.fused = self.fused.advance(step.motion);
            self.restart_window();
            return None;
        };
        let t = [
            self.calibration.counts_to_metres(f64::from(cx)),
            self.calibration.counts_to_metres(f64::from(cy)),
        ];
        let r = self.residuals(step.travel, t);
        let theta = self.rotation(r, self.suspect);
        let before = self.fused;
        self.fused = before.advance(Motion::new(t[0], t[1], theta));
        // Wheel-only translation over the same step, in the world frame at the fused
        // heading (mid-step), for the comparison.
        let (wx, wy) = robot_to_world(step.motion.x, step.motion.y, before.heading + theta / 2.0);
        let w = &mut self.window;
        w.wheel_world[0] += wx;
        w.wheel_world[1] += wy;
        w.distance += t[0].hypot(t[1]);
        for (acc, s) in w.wheel_travel.iter_mut().zip(step.travel) {
            *acc += s;
        }
        w.sensor_robot[0] += t[0];
        w.sensor_robot[1] += t[1];
        w.used_theta += theta;
        w.steps.push((t, r));
        let sensor_world = [self.fused.x - w.start.x, self.fused.y - w.start.y];
        let disagreement = (w.wheel_world[0] - sensor_world[0]).hypot(w.wheel_world[1] - sensor_world[1]);
        self.last_disagreement = disagreement;
        // The same disagreement seen wheel by wheel: one wheel's rotation residual
        // against the other two (more sensitive to a slipping wheel that turns little,
        // whose main effect is on the heading).
        let wr = self.residuals(self.window.wheel_travel, self.window.sensor_robot);
        let deviation = (0..3).map(|i| outlier(&wr, i).1).fold(0.0, f64::max);
        let travel = self.window.wheel_travel.iter().fold(0.0f64, |m, s| m.max(s.abs()));
        let w = &self.window;
        if disagreement > self.tolerance.absolute_m + self.tolerance.relative * w.distance
            || deviation > self.tolerance.absolute_m + self.tolerance.relative * travel
        {
            let event = self.slip_event(disagreement);
            self.restart_window();
            return Some(event);
        }
        if w.distance > self.tolerance.window_m || w.steps.len() >= MAX_WINDOW_STEPS {
            if let Some(s) = self.suspect {
                let r = self.residuals(self.window.wheel_travel, self.window.sensor_robot);
                let others: Vec<f64> =
                    r.iter().enumerate().filter(|(i, _)| *i != s).map(|(_, v)| *v).collect();
                let dev = r.get(s).map_or(0.0, |v| (v - mean(&others)).abs());
                let exercised = self.window.wheel_travel.get(s).map_or(0.0, |v| v.abs()) > MIN_EXERCISED_M;
                if exercised && dev < self.tolerance.absolute_m {
                    tracing::info!(wheel = s + 1, "wheel no longer slips");
                    self.suspect = None;
                }
            }
            self.restart_window();
        }
        None
    }

    fn restart_window(&mut self) {
        self.window = Window { start: self.fused, ..Window::default() };
    }

    /// Attributes the window's disagreement to a wheel and corrects the heading.
    fn slip_event(&mut self, disagreement: f64) -> SlipEvent {
        self.slip_count += 1;
        let w = std::mem::take(&mut self.window);
        let r = self.residuals(w.wheel_travel, w.sensor_robot);
        // The outlier is the wheel whose removal leaves the closest pair.
        let mut best: Option<(usize, f64, f64)> = None;
        for i in 0..3 {
            let (spread, dev) = outlier(&r, i);
            if best.map_or(true, |(_, s, _)| spread < s) {
                best = Some((i, spread, dev));
            }
        }
        let wheel = best.and_then(|(i, spread, dev)| {
            (dev > (2.0 * spread).max(self.tolerance.absolute_m / 10.0)).then_some(i)
        });
        let mut correction = 0.0;
        if let Some(i) = wheel {
            self.suspect = Some(i);
            // Replay the window with the rotation from the two good wheels.
            let mut pose = w.start;
            for (t, r) in &w.steps {
                pose = pose.advance(Motion::new(t[0], t[1], self.rotation(*r, Some(i))));
            }
            correction = pose.heading - self.fused.heading;
            self.fused = pose;
        }
        tracing::warn!(
            disagreement_m = disagreement,
            distance_m = w.distance,
            wheel = wheel.map(|i| i + 1),
            heading_correction = correction,
            "wheel slip detected"
        );
        SlipEvent {
            disagreement_m: disagreement,
            distance_m: w.distance,
            wheel,
            heading_correction: correction,
        }
    }
}
