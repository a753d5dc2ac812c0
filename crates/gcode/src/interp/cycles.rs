//! Canned cycles in the XY plane (G73, G81, G82, G83, G85, G89 with G98/G99, L repeats and
//! G80), and path control (G61, G61.1, G64 P Q), with LinuxCNC's semantics: its
//! `convert_cycle_xy` and `convert_cycle_g8x` (moves, sticky Z/R/P/Q words, the initial
//! level kept for G98 until G80 or another motion, the exact-path mode around each cycle
//! block, the 0.010 inch rapid clearance of the peck cycles) and its error checks.

use super::drilling_technology::TechnologyHole;
use super::feed::FeedMode;
use super::motion::Motion;
use super::Interpreter;
use crate::block::{g, Block};
use crate::canon::{Canon, MachineMove, MotionControl, Plane, Pose, Units};
use crate::error::{ErrorKind, KResult};

/// A canned cycle (its G code as ten times its number).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Cycle {
    /// G73: peck drilling with chip breaking (a small rapid retract between pecks).
    G73,
    /// G81: drilling.
    G81,
    /// G82: drilling with a dwell at the bottom.
    G82,
    /// G83: peck drilling, out to the R plane between pecks.
    G83,
    /// G85: boring, feed out to the R plane.
    G85,
    /// G89: boring with a dwell at the bottom, feed out.
    G89,
}

impl Cycle {
    /// The cycle of G code `code` (ten times its number), if it is one.
    pub(super) fn from_code(code: u16) -> Option<Cycle> {
        Some(match code {
            g::G73 => Cycle::G73,
            g::G81 => Cycle::G81,
            g::G82 => Cycle::G82,
            g::G83 => Cycle::G83,
            g::G85 => Cycle::G85,
            g::G89 => Cycle::G89,
            _ => return None,
        })
    }

    /// Ten times the G number (`#<_motion_mode>`).
    pub(super) fn code(self) -> u16 {
        match self {
            Cycle::G73 => g::G73,
            Cycle::G81 => g::G81,
            Cycle::G82 => g::G82,
            Cycle::G83 => g::G83,
            Cycle::G85 => g::G85,
            Cycle::G89 => g::G89,
        }
    }
}

/// The peck cycles' rapid clearance above the last depth (LinuxCNC's G83_RAPID_DELTA).
const PECK_CLEARANCE_INCH: f64 = 0.010;

/// The most moves one canned-cycle block may make (L repeats times the moves of a hole).
pub const MAX_CYCLE_MOVES: u64 = 100_000;

/// The sticky words and levels of canned cycles.
#[derive(Debug, Clone, Default)]
pub(super) struct CycleState {
    /// G99 (retract to the R plane, LinuxCNC's default) or G98 (to the initial level).
    pub(super) retract_to_initial: bool,
    /// The Z where the current sequence of cycle blocks started (G98's level); cleared by
    /// G80 and by any other motion.
    pub(super) initial_level: Option<f64>,
    /// The last Z, R, P and Q words of a cycle block.
    pub(super) z: f64,
    pub(super) r: f64,
    pub(super) p: f64,
    pub(super) q: f64,
}

/// Path control in force (G61, G61.1, G64 P Q).
#[derive(Debug, Clone, Copy)]
pub(super) struct PathControl {
    pub(super) mode: MotionControl,
    pub(super) tolerance: f64,
    pub(super) naivecam: f64,
}

impl Default for PathControl {
    fn default() -> Self {
        PathControl { mode: MotionControl::Continuous, tolerance: 0.0, naivecam: 0.0 }
    }
}

impl Interpreter<'_> {
    /// G61, G61.1 or G64 (with its P and Q words).
    pub(super) fn set_path_control(&mut self, code: u16, b: &Block) {
        match code {
            g::G61 => {
                self.path.mode = MotionControl::ExactPath;
                self.emit(Canon::SetMotionControlMode { mode: MotionControl::ExactPath, tolerance: 0.0 });
            }
            g::G61_1 => {
                self.path.mode = MotionControl::ExactStop;
                self.emit(Canon::SetMotionControlMode { mode: MotionControl::ExactStop, tolerance: 0.0 });
            }
            _ => {
                // G64: P is the path tolerance (0 = none), Q the naive-CAM tolerance (P
                // when only P is given).
                let tolerance = b.p.unwrap_or(0.0).max(0.0);
                let naivecam = b.q.map_or(tolerance, |q| q.max(0.0));
                self.path = PathControl { mode: MotionControl::Continuous, tolerance, naivecam };
                self.emit(Canon::SetMotionControlMode { mode: MotionControl::Continuous, tolerance });
                self.emit(Canon::SetNaivecamTolerance { tolerance: naivecam });
            }
        }
    }

    /// Executes one block of canned cycle `cycle`; `first`: the previous motion mode was not
    /// this cycle (its Z, R and P or Q words are then required).
    pub(super) fn cycle(&mut self, cycle: Cycle, b: &Block, first: bool, col: u32) -> KResult<()> {
        if self.plane != Plane::Xy {
            return Err((col, ErrorKind::CycleOutsideXy));
        }
        for (k, letter) in [(3, 'A'), (4, 'B'), (5, 'C')] {
            if b.axes.get(k).copied().flatten().is_some() {
                return Err((col, ErrorKind::RotaryInCycle(letter)));
            }
        }
        let repeats = match b.l {
            None => 1,
            Some(l) => {
                let r = crate::expr::round(l);
                if (l - r).abs() > 0.0001 {
                    return Err((col, ErrorKind::NonInteger(l)));
                }
                if r < 1.0 {
                    return Err((col, ErrorKind::CycleRepeats));
                }
                // At least 1 here; an absurd count is bounded by the step budget's caller.
                r.min(1e9) as u64
            }
        };
        if first && b.r.is_none() {
            return Err((col, ErrorKind::CycleWithoutR));
        }
        if self.feed_mode == FeedMode::InverseTime {
            return Err((col, ErrorKind::CycleInverseTime));
        }
        if self.feed == 0.0 {
            return Err((col, ErrorKind::CycleZeroFeed));
        }
        if first && b.axes.get(2).copied().flatten().is_none() {
            return Err((col, ErrorKind::CycleWithoutZ));
        }
        let word = |v: Option<f64>, sticky: f64| v.unwrap_or(sticky);
        let z_word = word(b.axes.get(2).copied().flatten(), self.cycles.z);
        let r_word = word(b.r, self.cycles.r);
        let get = |p: &Pose, k: usize| p.get(k).copied().unwrap_or(0.0);
        let current_z = get(&self.pos, 2);
        let mut old_z = *self.cycles.initial_level.get_or_insert(current_z);
        let (mut x, mut y, dx, dy, r, bottom) = if self.absolute {
            let x = b.axes.first().copied().flatten().unwrap_or(get(&self.pos, 0));
            let y = b.axes.get(1).copied().flatten().unwrap_or(get(&self.pos, 1));
            (x, y, 0.0, 0.0, r_word, z_word)
        } else {
            let dx = b.axes.first().copied().flatten().unwrap_or(0.0);
            let dy = b.axes.get(1).copied().flatten().unwrap_or(0.0);
            let r = r_word + old_z;
            (get(&self.pos, 0), get(&self.pos, 1), dx, dy, r, r + z_word)
        };
        if r < bottom {
            return Err((col, ErrorKind::CycleRBelowZ));
        }
        let (dwell, delta) = match cycle {
            Cycle::G82 | Cycle::G89 => {
                if first && b.p.is_none() {
                    return Err((col, ErrorKind::CycleWithoutP(cycle.code() / 10)));
                }
                (word(b.p, self.cycles.p), 0.0)
            }
            Cycle::G73 | Cycle::G83 => {
                if first && b.q.is_none() {
                    return Err((col, ErrorKind::CycleWithoutQ(cycle.code() / 10)));
                }
                let q = word(b.q, self.cycles.q);
                if q <= 0.0 {
                    return Err((col, ErrorKind::CycleQNotPositive(q)));
                }
                (0.0, q)
            }
            _ => (0.0, 0.0),
        };
        // One block's moves are bounded (LinuxCNC has no bound: a huge L or a tiny Q would
        // make millions of moves from one line).
        let per_hole = match cycle {
            Cycle::G73 | Cycle::G83 => ((r - bottom) / delta).ceil().max(1.0) * 3.0 + 4.0,
            _ => 5.0,
        };
        let moves = per_hole * repeats as f64;
        if moves > MAX_CYCLE_MOVES as f64 {
            return Err((col, ErrorKind::CycleTooManyMoves(MAX_CYCLE_MOVES)));
        }
        if self.cycles_on_technology() {
            self.check_technology_cycle(cycle, col)?;
            let feed_mm_per_min = self.move_feed(0.0, b, 1, col)?;
            for _ in 0..repeats {
                x += dx;
                y += dy;
                let hole = TechnologyHole { x, y, bottom, peck: delta, feed_mm_per_min };
                self.technology_hole(cycle, &hole, col)?;
            }
            self.remember_cycle_words(cycle, z_word, r_word, dwell, delta);
            return Ok(());
        }
        let feed = Some(self.move_feed(0.0, b, 1, col)?);
        // Below the R plane: straight up to it first, where the tool is.
        let mut level = current_z;
        if old_z < r {
            self.cycle_move(None, get(&self.pos, 0), get(&self.pos, 1), r);
            old_z = r;
            level = r;
        }
        let clear = if self.cycles.retract_to_initial { old_z } else { r };
        let saved = self.path;
        if saved.mode != MotionControl::ExactPath {
            self.emit(Canon::SetMotionControlMode { mode: MotionControl::ExactPath, tolerance: 0.0 });
        }
        let clearance = match self.units {
            Units::Mm => PECK_CLEARANCE_INCH * 25.4,
            Units::Inch => PECK_CLEARANCE_INCH,
        };
        for _ in 0..repeats {
            x += dx;
            y += dy;
            // Over to the hole at the higher of where the tool is and the retract level,
            // then down to the R plane (as rs274 2.9 moves).
            let over = level.max(clear);
            self.cycle_move(None, x, y, over);
            if over != r {
                self.cycle_move(None, x, y, r);
            }
            // Pecks first (G73: a small rapid back; G83: out to R and down again).
            if matches!(cycle, Cycle::G73 | Cycle::G83) {
                let mut depth = r - delta;
                while depth > bottom {
                    self.cycle_move(feed, x, y, depth);
                    if cycle == Cycle::G83 {
                        self.cycle_move(None, x, y, r);
                    }
                    self.cycle_move(None, x, y, depth + clearance);
                    depth -= delta;
                }
            }
            // Then to the bottom at the feed, a dwell (G82, G89), and out: G85 feeds back
            // to R, G89 feeds out to the retract level, the others rapid out.
            self.cycle_move(feed, x, y, bottom);
            if matches!(cycle, Cycle::G82 | Cycle::G89) {
                self.emit(Canon::Dwell { seconds: dwell });
            }
            if cycle == Cycle::G85 {
                self.cycle_move(feed, x, y, r);
            }
            self.cycle_move(if cycle == Cycle::G89 { feed } else { None }, x, y, clear);
            level = clear;
        }
        self.remember_cycle_words(cycle, z_word, r_word, dwell, delta);
        if saved.mode != MotionControl::ExactPath {
            self.emit(Canon::SetMotionControlMode { mode: saved.mode, tolerance: saved.tolerance });
            self.emit(Canon::SetNaivecamTolerance { tolerance: saved.naivecam });
        }
        Ok(())
    }

    /// The sticky words of a cycle block, for the blocks after it.
    fn remember_cycle_words(&mut self, cycle: Cycle, z: f64, r: f64, dwell: f64, delta: f64) {
        self.cycles.z = z;
        self.cycles.r = r;
        match cycle {
            Cycle::G82 | Cycle::G89 => self.cycles.p = dwell,
            Cycle::G73 | Cycle::G83 => self.cycles.q = delta,
            _ => {}
        }
    }

    /// One straight move of a cycle to (`x`, `y`, `z`), the other axes where they are: at
    /// `feed` (mm/min), or a rapid when `None`.
    pub(super) fn cycle_move(&mut self, feed: Option<f64>, x: f64, y: f64, z: f64) {
        let start = self.pos;
        let mut end = start;
        for (k, v) in [(0, x), (1, y), (2, z)] {
            if let Some(slot) = end.get_mut(k) {
                *slot = v;
            }
        }
        let (ms, me) = (self.to_machine(&start), self.to_machine(&end));
        match feed {
            None => {
                self.emit_move(Canon::StraightTraverse { end }, MachineMove::Traverse { start: ms, end: me });
            }
            Some(feed) => {
                self.emit_move(Canon::StraightFeed { end }, MachineMove::Feed { start: ms, end: me, feed });
            }
        }
        self.pos = end;
    }

    /// The motion mode changes to `m`: a motion that is not a cycle ends the sequence of
    /// cycle blocks (the next cycle takes its initial level afresh).
    pub(super) fn set_motion_mode(&mut self, m: Option<Motion>) {
        if !matches!(m, Some(Motion::Cycle(_))) {
            self.cycles.initial_level = None;
        }
        self.motion = m;
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use crate::{interpret, ErrorKind};

    #[test]
    fn one_block_cannot_make_millions_of_moves() {
        for prog in
            ["G0 Z5 F100\nG83 X1 Z-1000 R1 Q0.00001\nM2\n", "G0 Z5 F100\nG81 X1 Z-1 R1 L99999999\nM2\n"]
        {
            let e = interpret(prog).unwrap_err();
            assert_eq!(e.line, 2, "{e}");
            assert_eq!(e.kind, ErrorKind::CycleTooManyMoves(super::MAX_CYCLE_MOVES), "{e}");
        }
        // A long but reasonable peck cycle is fine: 1000 pecks.
        assert!(interpret("G0 Z5 F100\nG83 X1 Z-999 R1 Q1\nM2\n").is_ok());
    }
}
