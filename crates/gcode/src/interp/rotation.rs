//! Rotation of the coordinate systems about Z (G10 L2 R), as LinuxCNC 2.9 applies it.
//!
//! Each system G54..G59.3 has a rotation in degrees, parameter #5230 + 20 k (#5230 for G54,
//! #5250 for G55, ...), set by `G10 L2 P.. R..` (R is refused with L20). The active
//! system's rotation turns the XY plane of the program about the system's origin: a
//! program position `p` is at machine `origin + R(p + g92) + tool`, so the G92/G52 offset
//! is applied in the rotated frame (LinuxCNC's `get_abs_position`). The canonical calls
//! stay in unrotated program coordinates (`SET_XY_ROTATION` tells the machine); the
//! [`crate::MachineMove`]s, `#<_abs_x>`/`#<_abs_y>` and the current position after a
//! change of system are rotated. The helpers mirror LinuxCNC's `rotate`,
//! `find_current_in_system` and `find_relative`.

use super::{origin_param, Interpreter};
use crate::canon::Pose;

/// LinuxCNC's `rotate`: `(x, y)` turned by `degrees` counter-clockwise.
pub(super) fn rotate(x: f64, y: f64, degrees: f64) -> (f64, f64) {
    // No rotation, the common case: nothing to compute (LinuxCNC's cos 0 = 1, sin 0 = 0
    // give the same values).
    if degrees == 0.0 {
        return (x, y);
    }
    let t = degrees.to_radians();
    let (s, c) = t.sin_cos();
    (x * c - y * s, x * s + y * c)
}

/// The rotation parameter of coordinate system `k` (0 = G54): #5230 + 20 k.
pub(super) fn rotation_param(k: usize) -> usize {
    origin_param(k) + 9
}

fn at(p: &Pose, k: usize) -> f64 {
    p.get(k).copied().unwrap_or(0.0)
}

/// Sets the X and Y of `p`.
pub(super) fn set_xy(p: &mut Pose, (x, y): (f64, f64)) {
    let [px, py, ..] = p;
    (*px, *py) = (x, y);
}

/// Turns the X and Y of `p` by `degrees` in place.
pub(super) fn turn(p: &mut Pose, degrees: f64) {
    let [x, y, ..] = p;
    (*x, *y) = rotate(*x, *y, degrees);
}

impl Interpreter<'_> {
    /// The stored rotation of coordinate system `k`, degrees.
    pub(super) fn rotation_of(&self, k: usize) -> f64 {
        self.params.get(rotation_param(k))
    }

    /// The XY of program position `p` in the unrotated frame of the active system, before
    /// its origin: `R(p + g92)`.
    pub(super) fn unrotated_xy(&self, p: &Pose) -> (f64, f64) {
        rotate(at(p, 0) + at(&self.g92, 0), at(p, 1) + at(&self.g92, 1), self.rot)
    }

    /// LinuxCNC's `find_current_in_system`: the current point in system `k`'s coordinates
    /// (its origin and rotation, net of the G92 offset), program units.
    pub(super) fn current_in_system(&self, k: usize) -> Pose {
        let origin = self.origin();
        let target = self.origins.get(k).copied().unwrap_or([0.0; 6]);
        let mut c: Pose = std::array::from_fn(|a| at(&self.pos, a) + at(&self.g92, a));
        turn(&mut c, self.rot);
        for (a, v) in c.iter_mut().enumerate() {
            *v += at(&origin, a);
            *v -= at(&target, a);
        }
        turn(&mut c, -self.rotation_of(k));
        for (a, v) in c.iter_mut().enumerate() {
            *v -= at(&self.g92, a);
        }
        c
    }

    /// The active system's origin becomes `new` and its rotation `rot` (G10 on the active
    /// system, the program end): the current point is moved as LinuxCNC's
    /// `convert_setup` moves it (rotated without the G92 offset).
    pub(super) fn rebase_current(&mut self, new: &Pose, rot: f64) {
        let old = self.origin();
        turn(&mut self.pos, self.rot);
        for (a, v) in self.pos.iter_mut().enumerate() {
            *v += at(&old, a);
            *v -= at(new, a);
        }
        turn(&mut self.pos, -rot);
        self.rot = rot;
    }

    /// LinuxCNC's `find_relative` for X and Y: the program XY of the machine XY `(mx, my)`
    /// (program units, the tool length offset included).
    pub(super) fn relative_xy(&self, mx: f64, my: f64) -> (f64, f64) {
        let origin = self.origin();
        let (x, y) = rotate(
            mx - at(&origin, 0) - self.tool_offset_program(0),
            my - at(&origin, 1) - self.tool_offset_program(1),
            -self.rot,
        );
        (x - at(&self.g92, 0), y - at(&self.g92, 1))
    }

    /// The machine XY (program units, the tool length offset included) of program
    /// position `p`: LinuxCNC's `get_abs_position` for X and Y.
    pub(super) fn absolute_xy(&self, p: &Pose) -> (f64, f64) {
        let origin = self.origin();
        let (x, y) = self.unrotated_xy(p);
        (x + at(&origin, 0) + self.tool_offset_program(0), y + at(&origin, 1) + self.tool_offset_program(1))
    }
}
