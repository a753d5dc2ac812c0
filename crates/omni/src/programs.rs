//! The seed's demo programs and speed ramps (specs/omni-robot.md, "Demo programs").
//!
//! Moves are relative, in the robot frame, in Inc of robot translation (wheel increments:
//! 565 Inc = 1 m; 1065 Inc = 5 wheel revolutions = 188.4 cm).

use serde::{Deserialize, Serialize};

/// One step of a program.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "step", rename_all = "snake_case")]
pub enum Step {
    /// A relative move in the robot frame, Inc.
    Relative {
        /// Forward, Inc.
        x: i32,
        /// Left, Inc.
        y: i32,
    },
    /// Back to the program's start pose (the origin of the world frame).
    ReturnToZero,
}

/// A named sequence of steps.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Program {
    /// Name (`line`, `square`, `octagon`, `return_to_zero`).
    pub name: String,
    /// The steps, in order.
    pub steps: Vec<Step>,
}

fn relative(name: &str, moves: &[(i32, i32)]) -> Program {
    Program { name: name.to_string(), steps: moves.iter().map(|&(x, y)| Step::Relative { x, y }).collect() }
}

impl Program {
    /// Line: (+1065, 0) then (-1065, 0).
    #[must_use]
    pub fn line() -> Program {
        relative("line", &[(1065, 0), (-1065, 0)])
    }

    /// Square: (1065, 0), (0, -1065), (-1065, 0), (0, 1065).
    #[must_use]
    pub fn square() -> Program {
        relative("square", &[(1065, 0), (0, -1065), (-1065, 0), (0, 1065)])
    }

    /// The octagon (the robot's own outline), with the spec's correction: the printed
    /// last two moves are swapped so that every turn has the same direction.
    #[must_use]
    pub fn octagon() -> Program {
        relative(
            "octagon",
            &[
                (536, -230),
                (536, 230),
                (230, 536),
                (-230, 536),
                (-536, 230),
                (-536, -230),
                (-230, -536),
                (230, -536),
            ],
        )
    }

    /// The octagon as the seed prints it (last two moves swapped; not convex). Kept to
    /// document the correction.
    #[must_use]
    pub fn octagon_as_printed() -> Program {
        let mut p = Program::octagon();
        p.steps.swap(6, 7);
        p.name = "octagon_as_printed".to_string();
        p
    }

    /// Return to zero.
    #[must_use]
    pub fn return_to_zero() -> Program {
        Program { name: "return_to_zero".to_string(), steps: vec![Step::ReturnToZero] }
    }

    /// The seed's programs: line, square, octagon, return to zero.
    #[must_use]
    pub fn all() -> Vec<Program> {
        vec![Program::line(), Program::square(), Program::octagon(), Program::return_to_zero()]
    }

    /// A program by name.
    #[must_use]
    pub fn by_name(name: &str) -> Option<Program> {
        Program::all().into_iter().find(|p| p.name == name)
    }

    /// Sum of the relative moves, Inc.
    #[must_use]
    pub fn sum(&self) -> (i64, i64) {
        self.steps.iter().fold((0, 0), |(sx, sy), s| match *s {
            Step::Relative { x, y } => (sx + i64::from(x), sy + i64::from(y)),
            Step::ReturnToZero => (sx, sy),
        })
    }
}

/// Profile for the longest wheel of a move: velocity (Inc/s), acceleration and
/// deceleration (Inc/s^2).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Ramp {
    /// Inc/s.
    pub velocity: f64,
    /// Inc/s^2.
    pub acceleration: f64,
    /// Inc/s^2.
    pub deceleration: f64,
}

impl Ramp {
    /// The seed's profile: 248 Inc/s (70 rpm), 1000 Inc/s^2, 400 Inc/s^2.
    pub const SEED: Ramp = Ramp { velocity: 248.0, acceleration: 1000.0, deceleration: 400.0 };
    /// "Ramp 1": 500 Inc/s (the seed gives no ramp accelerations; the seed profile's are
    /// used).
    pub const RAMP_1: Ramp = Ramp { velocity: 500.0, acceleration: 1000.0, deceleration: 400.0 };
    /// "Ramp 2": 200 Inc/s, same accelerations.
    pub const RAMP_2: Ramp = Ramp { velocity: 200.0, acceleration: 1000.0, deceleration: 400.0 };

    /// True when every value is finite and positive.
    #[must_use]
    pub fn is_valid(&self) -> bool {
        [self.velocity, self.acceleration, self.deceleration].iter().all(|v| v.is_finite() && *v > 0.0)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    fn moves(p: &Program) -> Vec<(i64, i64)> {
        p.steps
            .iter()
            .filter_map(|s| match *s {
                Step::Relative { x, y } => Some((i64::from(x), i64::from(y))),
                Step::ReturnToZero => None,
            })
            .collect()
    }

    /// Cross products of consecutive moves (cyclic).
    fn turns(p: &Program) -> Vec<i64> {
        let m = moves(p);
        (0..m.len())
            .map(|i| {
                let (a, b) = (m[i], m[(i + 1) % m.len()]);
                a.0 * b.1 - a.1 * b.0
            })
            .collect()
    }

    #[test]
    fn every_program_returns_to_its_start() {
        for p in Program::all() {
            assert_eq!(p.sum(), (0, 0), "{}", p.name);
        }
        assert_eq!(Program::octagon_as_printed().sum(), (0, 0));
    }

    #[test]
    fn corrected_octagon_is_convex_and_printed_one_is_not() {
        // Every turn of the corrected octagon is to the left (cross product > 0), and the
        // turns add up to one full revolution.
        let t = turns(&Program::octagon());
        assert!(t.iter().all(|&c| c > 0), "{t:?}");
        let m = moves(&Program::octagon());
        let total: f64 = (0..8)
            .map(|i| {
                let (a, b) = (m[i], m[(i + 1) % 8]);
                let cross = (a.0 * b.1 - a.1 * b.0) as f64;
                let dot = (a.0 * b.0 + a.1 * b.1) as f64;
                cross.atan2(dot)
            })
            .sum();
        assert!((total - std::f64::consts::TAU).abs() < 1e-9);
        // Printed order: directions 293 deg then 247 deg -> a right turn and a reversal.
        let t = turns(&Program::octagon_as_printed());
        assert!(t.iter().any(|&c| c < 0));
        let m = moves(&Program::octagon_as_printed());
        let deg = |v: (i64, i64)| (v.1 as f64).atan2(v.0 as f64).to_degrees().rem_euclid(360.0);
        assert!((deg(m[6]) - 293.2).abs() < 0.1 && (deg(m[7]) - 246.8).abs() < 0.1);
    }

    #[test]
    fn ramps() {
        assert_eq!(Ramp::SEED.velocity, 248.0);
        assert_eq!(Ramp::RAMP_1.velocity, 500.0);
        assert_eq!(Ramp::RAMP_2.velocity, 200.0);
        assert!(Ramp::SEED.is_valid() && !Ramp { velocity: 0.0, ..Ramp::SEED }.is_valid());
        assert_eq!(Program::by_name("square"), Some(Program::square()));
    }
}
