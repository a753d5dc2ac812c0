//! Reference points and the local offset, with LinuxCNC's semantics: G28/G30 (a rapid to
//! the programmed intermediate point, then the named axes, or all, to reference point 1
//! #5161-#5166 or 2 #5181-#5186), G28.1/G30.1 (store the current absolute position there)
//! and G52 (the local offset, which LinuxCNC keeps in the G92 offsets). As LinuxCNC's
//! `find_relative`, the reference's program position is net of the tool length offset.
//! The stored points are in the machine's units, millimetres and degrees.

use super::modal::G92Params;
use super::{rotation, Interpreter};
use crate::block::{g, Block};
use crate::canon::{Canon, MachineMove, Pose};

/// The first parameter of reference point 1 (G28) and 2 (G30).
const G28_PARAMS: usize = 5161;
const G30_PARAMS: usize = 5181;

impl Interpreter<'_> {
    /// G28 or G30: over the block's axis words (the intermediate point) to the reference.
    pub(super) fn go_to_reference(&mut self, code: u16, b: &Block) {
        let base = if code == g::G28 { G28_PARAMS } else { G30_PARAMS };
        let mut via = self.pos;
        for (k, slot) in via.iter_mut().enumerate() {
            if let Some(v) = b.axes.get(k).copied().flatten() {
                *slot = if self.absolute { v } else { *slot + v };
            }
        }
        self.traverse_to(via);
        let origin = self.origin();
        let mut end = via;
        for (k, slot) in end.iter_mut().enumerate() {
            if b.has_axes() && b.axes.get(k).copied().flatten().is_none() {
                continue;
            }
            let machine = self.params.get(base + k) / self.user_units_per_program_unit(k);
            *slot = machine
                - origin.get(k).copied().unwrap_or(0.0)
                - self.g92.get(k).copied().unwrap_or(0.0)
                - self.tool_offset_program(k);
        }
        // X and Y of the reference through the active rotation (LinuxCNC's
        // `find_relative`); an axis not named keeps the intermediate point's.
        let reference = |k: usize| self.params.get(base + k) / self.user_units_per_program_unit(k);
        let (rx, ry) = self.relative_xy(reference(0), reference(1));
        let named = |k: usize| !b.has_axes() || b.axes.get(k).copied().flatten().is_some();
        let x = if named(0) { rx } else { via.first().copied().unwrap_or(0.0) };
        let y = if named(1) { ry } else { via.get(1).copied().unwrap_or(0.0) };
        rotation::set_xy(&mut end, (x, y));
        self.traverse_to(end);
    }

    /// G28.1 or G30.1: the current absolute position becomes reference point 1 or 2.
    pub(super) fn store_reference(&mut self, code: u16) {
        let base = if code == g::G28_1 { G28_PARAMS } else { G30_PARAMS };
        let origin = self.origin();
        for k in 0..6 {
            let abs = self.pos.get(k).copied().unwrap_or(0.0)
                + origin.get(k).copied().unwrap_or(0.0)
                + self.g92.get(k).copied().unwrap_or(0.0)
                + self.tool_offset_program(k);
            self.params.set(base + k, abs * self.user_units_per_program_unit(k));
        }
        // X and Y through the active rotation (LinuxCNC's `convert_savehome`).
        let (x, y) = self.absolute_xy(&self.pos);
        for (k, v) in [(0, x), (1, y)] {
            self.params.set(base + k, v * self.user_units_per_program_unit(k));
        }
    }

    /// G52: the block's axis words become the local offset of those axes (the others keep
    /// theirs), whatever the distance mode.
    pub(super) fn set_local_offset(&mut self, b: &Block) {
        let mut new = self.g92;
        for (k, slot) in new.iter_mut().enumerate() {
            if let Some(v) = b.axes.get(k).copied().flatten() {
                *slot = v;
            }
        }
        self.set_g92(new, G92Params::Save);
    }

    /// A rapid to `end` (program units).
    fn traverse_to(&mut self, end: Pose) {
        let (ms, me) = (self.to_machine(&self.pos), self.to_machine(&end));
        self.emit_move(Canon::StraightTraverse { end }, MachineMove::Traverse { start: ms, end: me });
        self.pos = end;
    }
}
