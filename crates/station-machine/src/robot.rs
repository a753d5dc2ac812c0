//! The omni robot's go-to: the station's pose estimate (wheel odometry from the polled wheel
//! positions) and the synchronised wheel moves that take the robot to a point of the map.
//!
//! The estimate is what the station knows on real drives too: dead reckoning from the three
//! wheels' positions (the drives' 0x6064, read by the poller), with the omni crate's
//! kinematics. A go-to turns the motion from the estimated pose to the target
//! ([`Pose::motion_to`]) into one relative travel per wheel (inverse kinematics) and starts
//! the three moves with speeds and accelerations in proportion to their travels, so the
//! wheels start and end together and the robot follows the planned straight line (or arc,
//! when the heading changes). Every wheel move goes through the same checks as an axis move
//! (machine limits, a student's limits, E-stop, faults).

use motus_omni::kinematics::{Geometry, Pose};
use motus_omni::odometry::WheelOdometry;
use motus_station_web::BackendError;

/// The part of the floor the map shows and a go-to may aim at, metres
/// `[xmin, ymin, xmax, ymax]`: a target outside is refused for every user.
pub(crate) const ROBOT_AREA: [f64; 4] = [-2.0, -2.0, 2.0, 2.0];

/// The slowest speed (increments/s) and acceleration (increments/s^2) a wheel is commanded
/// with: a drive takes whole increments, and a wheel with a tiny share of the motion would
/// otherwise get 0 (refused). Such a wheel ends a little early: its travel is tiny.
const MIN_WHEEL_RATE_INC: f64 = 2.0;

/// The pose estimate of an omni group: wheel odometry on the wheel axes' positions.
#[derive(Debug)]
pub(crate) struct RobotEstimate {
    odometry: WheelOdometry,
    /// Device increments per axis unit of each wheel (the axis scale's inverse).
    inc_per_unit: [f64; 3],
    /// The wheel positions of the previous update (axis units) and their time, seconds.
    last: Option<([f64; 3], f64)>,
    /// Each wheel's largest plausible speed (axis units/s): a bigger jump between two
    /// updates is a new reference (homing), not travel.
    max_speed: [f64; 3],
    /// The target of the go-to in progress.
    pub(crate) target: Option<[f64; 2]>,
}

impl RobotEstimate {
    /// An estimate starting at the origin, for wheels with these scales (axis units per
    /// device increment) and maximum speeds (axis units/s).
    pub(crate) fn new(units_per_inc: [f64; 3], max_speed: [f64; 3]) -> RobotEstimate {
        RobotEstimate {
            odometry: WheelOdometry::new(Geometry::default(), Pose::default()),
            inc_per_unit: units_per_inc.map(|u| if u.is_finite() && u != 0.0 { 1.0 / u } else { 0.0 }),
            last: None,
            max_speed,
            target: None,
        }
    }

    /// The estimated pose.
    pub(crate) fn pose(&self) -> Pose {
        self.odometry.pose()
    }

    /// Integrates the wheel positions (axis units) read at `t` seconds. A wheel that jumped
    /// faster than it can move (its position was re-referenced) counts as not moved.
    pub(crate) fn update(&mut self, positions: [f64; 3], t: f64) {
        let Some((last, last_t)) = self.last.replace((positions, t)) else {
            return;
        };
        let dt = (t - last_t).max(0.0);
        let mut travel = [0.0; 3];
        for (i, d) in travel.iter_mut().enumerate() {
            let (p, l, inc, vmax) = (
                positions.get(i).copied().unwrap_or(0.0),
                last.get(i).copied().unwrap_or(0.0),
                self.inc_per_unit.get(i).copied().unwrap_or(0.0),
                self.max_speed.get(i).copied().unwrap_or(0.0),
            );
            let delta = p - l;
            let plausible = vmax * dt * 1.5 + 1.0 / inc.max(f64::MIN_POSITIVE);
            if delta.is_finite() && delta.abs() <= plausible {
                *d = self.odometry.geometry().inc_to_metres(delta * inc);
            }
        }
        let motion = self.odometry.geometry().forward(travel);
        let pose = self.odometry.pose().advance(motion);
        self.odometry.set_pose(pose);
    }

    /// The relative travel of each wheel (axis units) that takes the robot from the
    /// estimated pose to `(x, y)` at `heading` (the current heading when `None`).
    ///
    /// # Errors
    /// [`BackendError::Invalid`] for a target that is not finite or outside [`ROBOT_AREA`].
    pub(crate) fn travel_to(&self, x: f64, y: f64, heading: Option<f64>) -> Result<[f64; 3], BackendError> {
        let [xmin, ymin, xmax, ymax] = ROBOT_AREA;
        if !(x >= xmin && x <= xmax && y >= ymin && y <= ymax) {
            return Err(BackendError::invalid(
                "targets",
                format!("({x}, {y}) m is outside the robot's area [{xmin}, {xmax}] x [{ymin}, {ymax}] m"),
            ));
        }
        if heading.is_some_and(|h| !h.is_finite()) {
            return Err(BackendError::invalid(
                "targets",
                "the heading is not a finite number of radians".to_owned(),
            ));
        }
        let from = self.pose();
        let to = Pose::new(x, y, heading.unwrap_or(from.heading));
        let metres = self.odometry.geometry().inverse(from.motion_to(to));
        let mut travel = [0.0; 3];
        for ((t, m), inc) in travel.iter_mut().zip(metres).zip(self.inc_per_unit) {
            let increments = self.odometry.geometry().metres_to_inc(m);
            // Less than one increment: the drive cannot move it.
            if increments.abs() >= 1.0 && inc > 0.0 {
                *t = increments / inc;
            }
        }
        Ok(travel)
    }

    /// Each wheel's slowest commandable speed (axis units/s) and acceleration (axis units/s^2).
    pub(crate) fn min_rates(&self) -> [f64; 3] {
        self.inc_per_unit.map(|inc| if inc > 0.0 { MIN_WHEEL_RATE_INC / inc } else { 0.0 })
    }
}

/// Speeds and accelerations of wheel moves with `travel` that start and end together: the
/// longest travel gets `speed` and `acceleration`, the others the same fractions of them, but
/// never less than the wheel's `min` rate. `None` for a wheel that does not move.
pub(crate) fn synchronised(
    travel: [f64; 3],
    speed: f64,
    acceleration: f64,
    min: [f64; 3],
) -> [Option<(f64, f64)>; 3] {
    let longest = travel.iter().fold(0.0f64, |a, t| a.max(t.abs()));
    let mut out = [None; 3];
    for ((o, t), m) in out.iter_mut().zip(travel).zip(min) {
        if t != 0.0 && longest > 0.0 {
            let k = t.abs() / longest;
            *o = Some(((speed * k).max(m), (acceleration * k).max(m)));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    /// The demo cell's wheels: 2*pi/213.33 rad per increment.
    const RAD_PER_INC: f64 = 0.029_452_431;

    fn estimate() -> RobotEstimate {
        RobotEstimate::new([RAD_PER_INC; 3], [20.0; 3])
    }

    #[test]
    fn the_travel_to_a_point_brings_the_odometry_there() {
        let mut e = estimate();
        e.update([0.0; 3], 0.0);
        let travel = e.travel_to(0.5, -0.3, None).unwrap();
        // Proportional wheel motion in 100 steps, as the synchronised moves do.
        for k in 1..=100 {
            let f = f64::from(k) / 100.0;
            e.update(travel.map(|t| t * f), f64::from(k) * 0.01);
        }
        let p = e.pose();
        assert!((p.x - 0.5).abs() < 1e-6 && (p.y + 0.3).abs() < 1e-6, "{p:?}");
        assert!(p.heading.abs() < 1e-9);
    }

    #[test]
    fn a_turn_and_a_move_reach_the_target_heading() {
        let mut e = estimate();
        e.update([0.0; 3], 0.0);
        let travel = e.travel_to(-1.0, 0.4, Some(1.2)).unwrap();
        for k in 1..=200 {
            let f = f64::from(k) / 200.0;
            e.update(travel.map(|t| t * f), f64::from(k) * 0.01);
        }
        let p = e.pose();
        assert!(
            (p.x + 1.0).abs() < 1e-6 && (p.y - 0.4).abs() < 1e-6 && (p.heading - 1.2).abs() < 1e-6,
            "{p:?}"
        );
    }

    #[test]
    fn targets_outside_the_area_or_not_finite_are_refused() {
        let e = estimate();
        for (x, y, h) in
            [(2.5, 0.0, None), (0.0, -9.0, None), (f64::NAN, 0.0, None), (0.0, 0.0, Some(f64::INFINITY))]
        {
            let err = e.travel_to(x, y, h).unwrap_err();
            assert!(matches!(err, BackendError::Invalid { .. }), "{err:?}");
        }
    }

    #[test]
    fn a_re_referenced_wheel_is_not_travel() {
        let mut e = estimate();
        e.update([100.0, 0.0, 0.0], 0.0);
        // Homing set wheel 1 to 0 within 50 ms: 100 rad in 50 ms is not a wheel's motion.
        e.update([0.0, 0.0, 0.0], 0.05);
        assert_eq!(e.pose(), Pose::default());
    }

    #[test]
    fn synchronised_moves_scale_with_their_travel() {
        let s = synchronised([2.0, -1.0, 0.0], 4.0, 10.0, [0.0; 3]);
        assert_eq!(s, [Some((4.0, 10.0)), Some((2.0, 5.0)), None]);
        assert_eq!(synchronised([0.0; 3], 4.0, 10.0, [0.0; 3]), [None, None, None]);
        // A wheel with a tiny share still gets a speed its drive accepts.
        let s = synchronised([2.0, 0.001, 0.0], 4.0, 10.0, [0.05; 3]);
        assert_eq!(s[1], Some((0.05, 0.05)));
    }

    #[test]
    fn a_wheel_with_less_than_one_increment_is_not_commanded_and_the_others_get_commandable_rates() {
        let e = estimate();
        // Along y, wheel 1 (driving along x) has almost nothing to do.
        let travel = e.travel_to(0.0002, 0.5, None).unwrap();
        assert_eq!(travel[0], 0.0, "{travel:?}");
        assert!(travel[1].abs() > 1.0 && travel[2].abs() > 1.0, "{travel:?}");
        let min = e.min_rates();
        for (t, r) in travel.iter().zip(synchronised(travel, 5.0, 10.0, min)) {
            if let Some((v, a)) = r {
                assert!(v / RAD_PER_INC >= 1.0 && a / RAD_PER_INC >= 1.0, "{t}: {v} {a}");
            }
        }
    }
}
