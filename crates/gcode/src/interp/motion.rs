//! Motion: straight moves (G0/G1, G53) and arcs (G2/G3, I/J/K or R form, helices and
//! turns), emitted in program units with the same move in machine millimetres.

use super::cycles::Cycle;
use super::feed::FeedMode;
use super::{rotation, Interpreter};
use crate::arc;
use crate::block::Block;
use crate::canon::{ArcFeed, Canon, MachineMove, Plane, Pose};
use crate::error::{CompError, ErrorKind, KResult};

/// Modal motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Motion {
    Rapid,
    Feed,
    Cw,
    Ccw,
    /// A canned cycle (`cycles.rs`).
    Cycle(Cycle),
}

impl Interpreter<'_> {
    /// Machine millimetres of a program-units pose under the current offsets.
    pub(super) fn to_machine(&self, p: &Pose) -> Pose {
        let f = self.units.mm_per_unit();
        let o = self.origins.get(self.coord).copied().unwrap_or([0.0; 6]);
        // The G92 offset applies in the rotated frame, then the rotation, then the origin.
        let mut shifted: Pose = std::array::from_fn(|k| {
            p.get(k).copied().unwrap_or(0.0) + self.g92.get(k).copied().unwrap_or(0.0)
        });
        rotation::turn(&mut shifted, self.rot);
        let mut m = [0.0; 6];
        for (k, slot) in m.iter_mut().enumerate() {
            let v = shifted.get(k).copied().unwrap_or(0.0) + o.get(k).copied().unwrap_or(0.0);
            // Plus the tool length offset (already in machine units).
            let tool = self.tool.offset_mm.get(k).copied().unwrap_or(0.0);
            *slot = if k < 3 { v * f } else { v } + tool;
        }
        m
    }

    /// The tool length offset in force on axis `k`, in program units (LinuxCNC's
    /// `tool_offset`, which G53 and G28/G30 subtract from a machine position).
    pub(super) fn tool_offset_program(&self, k: usize) -> f64 {
        let tool = self.tool.offset_mm.get(k).copied().unwrap_or(0.0);
        if k < 3 {
            tool / self.units.mm_per_unit()
        } else {
            tool
        }
    }

    pub(super) fn origin(&self) -> Pose {
        self.origins.get(self.coord).copied().unwrap_or([0.0; 6])
    }

    /// Executes motion `m` with the block's axis words (`g53`: column of a G53 word).
    pub(super) fn motion(&mut self, m: Motion, b: &Block, g53: Option<u32>, mcol: u32) -> KResult<()> {
        let start = self.pos;
        let mut end = start;
        if let Some(col) = g53 {
            if !self.absolute {
                return Err((col, ErrorKind::G53Incremental));
            }
            if !matches!(m, Motion::Rapid | Motion::Feed) {
                return Err((col, ErrorKind::G53WithoutStraight));
            }
        }
        let origin = self.origin();
        for k in 0..6 {
            let (Some(v), Some(slot)) = (b.axes.get(k).copied().flatten(), end.get_mut(k)) else {
                continue;
            };
            *slot = if g53.is_some() {
                v - origin.get(k).copied().unwrap_or(0.0)
                    - self.g92.get(k).copied().unwrap_or(0.0)
                    - self.tool_offset_program(k)
            } else if self.absolute {
                v
            } else {
                *slot + v
            };
        }
        if g53.is_some() {
            // LinuxCNC's `find_ends`: X and Y through the active rotation (an axis not
            // named keeps the current point's machine position).
            let (cx, cy) = self.unrotated_xy(&start);
            let word = |k: usize| b.axes.get(k).copied().flatten();
            let x = word(0)
                .map_or(cx, |v| v - origin.first().copied().unwrap_or(0.0) - self.tool_offset_program(0));
            let y = word(1)
                .map_or(cy, |v| v - origin.get(1).copied().unwrap_or(0.0) - self.tool_offset_program(1));
            let (x, y) = rotation::rotate(x, y, -self.rot);
            let g92 = |k: usize| self.g92.get(k).copied().unwrap_or(0.0);
            rotation::set_xy(&mut end, (x - g92(0), y - g92(1)));
        }
        if b.has_polar() {
            // LinuxCNC: X and Y from the polar words, about the origin (G90) or from the
            // current point's own radius and angle (G91).
            let (x, y) = (start.first().copied().unwrap_or(0.0), start.get(1).copied().unwrap_or(0.0));
            let (r0, a0) = (x.hypot(y), y.atan2(x));
            let [pr, pa] = b.polar;
            let (radius, theta) = if self.absolute {
                (pr.unwrap_or(r0), pa.map_or(a0, f64::to_radians))
            } else {
                (r0 + pr.unwrap_or(0.0), a0 + pa.unwrap_or(0.0).to_radians())
            };
            if let Some(slot) = end.get_mut(0) {
                *slot = radius * theta.cos();
            }
            if let Some(slot) = end.get_mut(1) {
                *slot = radius * theta.sin();
            }
        }
        if matches!(m, Motion::Cw | Motion::Ccw) {
            if self.comp.arc_not_allowed {
                return Err((mcol, ErrorKind::CutterComp(CompError::ArcAfterExit)));
            }
        } else {
            self.comp.arc_not_allowed = false;
        }
        if self.comp.active() {
            if let Some(col) = g53 {
                return Err((col, ErrorKind::CutterComp(CompError::MachineCoordinates)));
            }
            if matches!(m, Motion::Rapid | Motion::Feed) {
                self.comp_straight(m == Motion::Rapid, b, end, mcol)?;
                self.pos = end;
                return Ok(());
            }
        }
        let ms = self.to_machine(&start);
        let me = self.to_machine(&end);
        match m {
            Motion::Rapid => {
                self.emit_move(Canon::StraightTraverse { end }, MachineMove::Traverse { start: ms, end: me });
            }
            Motion::Feed => {
                let length = straight_length(&start, &end);
                let feed = self.move_feed(length, b, 1, mcol)?;
                self.emit_move(Canon::StraightFeed { end }, MachineMove::Feed { start: ms, end: me, feed });
            }
            // Canned cycles are executed by `cycles.rs`, never here.
            Motion::Cycle(_) => return Ok(()),
            Motion::Cw | Motion::Ccw => {
                let cw = m == Motion::Cw;
                if self.feed_mode != FeedMode::InverseTime && self.feed == 0.0 {
                    return Err((mcol, ErrorKind::ZeroFeed(if cw { 2 } else { 3 })));
                }
                let (f, s, ax) = self.plane.axes();
                let get = |p: &Pose, k: usize| p.get(k).copied().unwrap_or(0.0);
                let turns = match b.p {
                    None => 1,
                    Some(p) => {
                        let r = p.round();
                        if (p - r).abs() > 0.0001 || !(1.0..=1e6).contains(&r) {
                            return Err((mcol, ErrorKind::ArcBadTurns));
                        }
                        // 1..=1e6, exact.
                        r as i32
                    }
                };
                let st = (get(&start, f), get(&start, s));
                let en = (get(&end, f), get(&end, s));
                let centre = if let Some(r) = b.r {
                    if b.ijk.iter().any(Option::is_some) {
                        return Err((mcol, ErrorKind::ArcMixedFormat));
                    }
                    arc::centre_r(self.units, st, en, r, cw).map_err(|k| (mcol, k))?
                } else {
                    // I, J, K index = X, Y, Z index.
                    if let Some(bad) = (0..3).find(|&k| k == ax && b.ijk.get(k).copied().flatten().is_some())
                    {
                        let name = match self.plane {
                            Plane::Xy => "XY",
                            Plane::Xz => "XZ",
                            Plane::Yz => "YZ",
                        };
                        return Err((
                            mcol,
                            ErrorKind::ArcWrongCentreWord(char::from(b'I' + bad as u8), name),
                        ));
                    }
                    if !b.ijk.iter().any(Option::is_some) {
                        return Err((mcol, ErrorKind::ArcMissingCentre));
                    }
                    let ci = b.ijk.get(f).copied().flatten().unwrap_or(0.0);
                    let cj = b.ijk.get(s).copied().flatten().unwrap_or(0.0);
                    let letters = match self.plane {
                        Plane::Xy => ('X', 'Y'),
                        Plane::Xz => ('Z', 'X'),
                        Plane::Yz => ('Y', 'Z'),
                    };
                    arc::centre_ijk(self.units, st, en, (ci, cj), self.arc_absolute, letters)
                        .map_err(|k| (mcol, k))?
                };
                let rotation = if cw { -turns } else { turns };
                if self.comp.active() {
                    self.comp_arc(b, end, centre, rotation, mcol)?;
                    self.pos = end;
                    return Ok(());
                }
                let arcf = ArcFeed {
                    first_end: en.0,
                    second_end: en.1,
                    first_centre: centre.0,
                    second_centre: centre.1,
                    rotation,
                    axis_end: get(&end, ax),
                    a: get(&end, 3),
                    b: get(&end, 4),
                    c: get(&end, 5),
                };
                let mut cpose = start;
                if let Some(v) = cpose.get_mut(f) {
                    *v = centre.0;
                }
                if let Some(v) = cpose.get_mut(s) {
                    *v = centre.1;
                }
                let mc = self.to_machine(&cpose);
                let length = arc_length(st, en, centre, rotation, get(&end, ax) - get(&start, ax));
                let feed = self.move_feed(length, b, if cw { 2 } else { 3 }, mcol)?;
                self.emit_move(
                    Canon::ArcFeed(arcf),
                    MachineMove::Arc {
                        start: ms,
                        end: me,
                        centre: [get(&mc, 0), get(&mc, 1), get(&mc, 2)],
                        plane: self.plane,
                        rotation,
                        feed,
                    },
                );
            }
        }
        self.pos = end;
        Ok(())
    }
}

/// The length of a straight move (program units): X Y Z, or the rotary axes' travel for a
/// rotary-only move (as LinuxCNC's inverse-time rate takes it).
pub(super) fn straight_length(a: &Pose, b: &Pose) -> f64 {
    let d = |k: usize| b.get(k).copied().unwrap_or(0.0) - a.get(k).copied().unwrap_or(0.0);
    let linear = (d(0).powi(2) + d(1).powi(2) + d(2).powi(2)).sqrt();
    if linear > 0.0 {
        linear
    } else {
        (d(3).powi(2) + d(4).powi(2) + d(5).powi(2)).sqrt()
    }
}

/// The length of an arc from `st` to `en` about `centre` (in its plane) with `rotation`
/// (signed turns, LinuxCNC's), rising `axial` along the plane's normal: the helix's length.
pub(super) fn arc_length(
    st: (f64, f64),
    en: (f64, f64),
    centre: (f64, f64),
    rotation: i32,
    axial: f64,
) -> f64 {
    use std::f64::consts::TAU;
    let radius = (st.0 - centre.0).hypot(st.1 - centre.1);
    let alpha = (st.1 - centre.1).atan2(st.0 - centre.0);
    let mut beta = (en.1 - centre.1).atan2(en.0 - centre.0);
    let theta = if rotation > 0 {
        if beta <= alpha {
            beta += TAU;
        }
        beta - alpha + f64::from(rotation - 1) * TAU
    } else {
        let mut alpha = alpha;
        if alpha <= beta {
            alpha += TAU;
        }
        beta - alpha + f64::from(rotation + 1) * TAU
    };
    (radius * theta).hypot(axial)
}
