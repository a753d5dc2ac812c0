//! Canned cycles as jobs of the seed's drilling technology ([`CycleOutput::DrillingTechnology`]).
//!
//! The seed's drilling unit (specs/cnc.md) owns its Z: a pressure plate finds the material
//! surface, and the technology task drills one hole per M60 with the spindle speed, drilling
//! speed and depth of its external parameters (EXW60, EXF61, EXF62). A machine configured so
//! runs G81, G73 and G83 as that job instead of moving a Z axis on the path:
//!
//! * per hole, a rapid of X and Y to the hole (Z stays where it is), then
//!   `EXW60` = the spindle speed (S, rpm), `EXF61` = the feed (mm/min),
//!   `EXF62` = the depth below the material surface (mm), `EXF63` = the peck increment
//!   (mm, 0: one pass), `EXB64` = 1 for G73's chip breaking (a short retract in the hole)
//!   or 0 (out of the hole between pecks, G83), and the synchronous `M60`;
//! * the material surface is Z 0 of the coordinate system in force: the hole's bottom is its
//!   Z word (after G91's R + Z), so the depth is `-Z`; R only keeps LinuxCNC's checks
//!   (the unit approaches the surface itself, at its own approach height);
//! * G82, G85 and G89 are refused: the unit cannot dwell at the bottom or feed out;
//! * M6 with a tool activates the drilling technology (`M63`, which shifts X/Y by the
//!   cutting-to-drilling tool offset; nothing happens when it is already active).
//!
//! The calls are the ones an M-function program of the seed writes by hand, so a G-code
//! drilling job and its M-function version drive the unit identically.

use super::cycles::Cycle;
use super::Interpreter;
use crate::canon::{Canon, ExArray, ExValue, MSync, Units};
use crate::error::{ErrorKind, KResult};

/// How canned cycles (G73, G81-G89) reach the machine ([`crate::InterpreterConfig::cycles`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum CycleOutput {
    /// As LinuxCNC moves them: rapids and feeds of Z on the path (a mill's spindle axis).
    #[default]
    Motion,
    /// As jobs of the seed's drilling technology (see the module documentation).
    DrillingTechnology,
}

/// M60: the technology drills one hole.
pub const M_DRILL_HOLE: u16 = 60;
/// M63: the technology is activated (X/Y shifted to the drilling tool).
pub const M_ACTIVATE_DRILLING: u16 = 63;
/// EXW60: spindle speed, rpm.
pub const EXW_SPINDLE_RPM: u8 = 60;
/// EXF61: drilling speed, mm/min.
pub const EXF_DRILLING_SPEED: u8 = 61;
/// EXF62: drilling depth below the material surface, mm.
pub const EXF_DRILLING_DEPTH: u8 = 62;
/// EXF63: peck increment, mm (0: the whole depth in one pass).
pub const EXF_PECK_INCREMENT: u8 = 63;
/// EXB64: 1 = chip breaking between pecks (G73), 0 = out of the hole (G83).
pub const EXB_CHIP_BREAK: u8 = 64;

/// One hole of a cycle block, in program units (the interpreter's).
pub(super) struct TechnologyHole {
    /// The hole's position in the program's coordinates.
    pub(super) x: f64,
    pub(super) y: f64,
    /// The bottom's Z (program coordinates; the surface is Z 0).
    pub(super) bottom: f64,
    /// The peck increment (program units; 0: one pass).
    pub(super) peck: f64,
    /// The feed, mm/min.
    pub(super) feed_mm_per_min: f64,
}

impl Interpreter<'_> {
    /// Whether canned cycles go to the drilling technology.
    pub(super) fn cycles_on_technology(&self) -> bool {
        self.config.cycles == CycleOutput::DrillingTechnology
    }

    /// Refuses a cycle the drilling unit cannot do, before any call of its block.
    pub(super) fn check_technology_cycle(&self, cycle: Cycle, col: u32) -> KResult<()> {
        if matches!(cycle, Cycle::G82 | Cycle::G85 | Cycle::G89) {
            return Err((col, ErrorKind::CycleNotOnTechnology(cycle.code() / 10)));
        }
        let rpm = self.rpm.round();
        if !(1.0..=f64::from(i16::MAX)).contains(&rpm) {
            return Err((col, ErrorKind::TechnologySpindleSpeed(self.rpm)));
        }
        Ok(())
    }

    /// One hole as the technology's job: X/Y over it, its parameters, M60.
    pub(super) fn technology_hole(&mut self, cycle: Cycle, hole: &TechnologyHole, col: u32) -> KResult<()> {
        if hole.bottom >= 0.0 {
            return Err((col, ErrorKind::HoleNotBelowSurface(hole.bottom)));
        }
        let mm = match self.units {
            Units::Mm => 1.0,
            Units::Inch => 25.4,
        };
        let z = self.pos.get(2).copied().unwrap_or(0.0);
        self.cycle_move(None, hole.x, hole.y, z);
        let peck = if matches!(cycle, Cycle::G73 | Cycle::G83) { hole.peck * mm } else { 0.0 };
        // The range was checked by `check_technology_cycle`; the others are f32 values.
        let rpm = self.rpm.round().clamp(1.0, f64::from(i16::MAX)) as i16;
        let f = |v: f64| ExValue::F(v as f32);
        for (array, index, value) in [
            (ExArray::W, EXW_SPINDLE_RPM, ExValue::W(rpm)),
            (ExArray::F, EXF_DRILLING_SPEED, f(hole.feed_mm_per_min)),
            (ExArray::F, EXF_DRILLING_DEPTH, f(-hole.bottom * mm)),
            (ExArray::F, EXF_PECK_INCREMENT, f(peck)),
            (ExArray::B, EXB_CHIP_BREAK, ExValue::B(i8::from(cycle == Cycle::G73))),
        ] {
            self.emit(Canon::ExternalParameter { array, index, value });
        }
        self.emit(Canon::MFunction { number: M_DRILL_HOLE, sync: MSync::Sync });
        Ok(())
    }

    /// After M6 put a tool in the spindle: the drilling technology takes the machine.
    pub(super) fn technology_tool_changed(&mut self) {
        if self.cycles_on_technology() {
            self.emit(Canon::MFunction { number: M_ACTIVATE_DRILLING, sync: MSync::Sync });
        }
    }
}
