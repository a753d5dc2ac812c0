//! Tools, as LinuxCNC handles them with a non-random changer: T selects (`SELECT_TOOL`),
//! M6 changes (`START_CHANGE`, the spindle stopped, `CHANGE_TOOL` with the tool's place in
//! the table) and sets #5400-#5413 to the tool in the spindle; G43 (the spindle's tool, or tool H), G43.1 (the
//! block's axis words) and G49 set the tool length offset (`USE_TOOL_LENGTH_OFFSET`),
//! which moves the controlled point: the machine position stays, the program position
//! changes by the difference.

use super::Interpreter;
use crate::block::{g, Block};
use crate::canon::{Canon, Pose};
use crate::error::{CompError, ErrorKind, KResult};

/// The first of the parameters of the tool in the spindle (#5400 = its number).
const TOOL_PARAMS: usize = 5400;

/// A tool word's value as a tool number.
fn tool_number(v: f64, col: u32) -> KResult<u32> {
    let r = crate::expr::round(v);
    if (v - r).abs() > 0.0001 || !(0.0..=f64::from(u32::MAX)).contains(&r) {
        return Err((col, ErrorKind::BadToolNumber(v)));
    }
    // Whole and in range.
    Ok(r as u32)
}

impl Interpreter<'_> {
    /// The place (1-based) of tool `number` in the table; 0 for tool 0 (no tool).
    pub(super) fn tool_index(&self, number: u32, col: u32) -> KResult<usize> {
        if number == 0 {
            return Ok(0);
        }
        self.config
            .tools
            .iter()
            .position(|t| t.number == number)
            .map(|i| i + 1)
            .ok_or((col, ErrorKind::ToolNotFound(number)))
    }

    /// The block's T word (`SELECT_TOOL`).
    pub(super) fn select_tool(&mut self, b: &Block) -> KResult<()> {
        if b.m_tool.is_some() && self.comp.on() {
            return Err((b.first_col, ErrorKind::CutterComp(CompError::ToolChange)));
        }
        if let Some(t) = b.t {
            let number = tool_number(t, b.first_col)?;
            let index = self.tool_index(number, b.first_col)?;
            self.tool.selected = (number, index);
            self.emit(Canon::SelectTool { tool: number });
        }
        Ok(())
    }

    /// The block's M6: the selected tool into the spindle.
    pub(super) fn change_tool(&mut self, b: &Block) -> KResult<()> {
        if b.m_tool.is_some() {
            // LinuxCNC 2.9: the spindle stops for the change. Changing to the empty place
            // (T0) leaves the spindle's tool entry, and its number, as they were.
            self.emit(Canon::StartChange);
            self.spindle = 0;
            self.emit(Canon::StopSpindleTurning);
            let (number, index) = self.tool.selected;
            self.emit(Canon::ChangeTool { index });
            if index > 0 {
                self.tool.current = (number, index);
                self.publish_tool_params();
                self.technology_tool_changed();
            }
        }
        Ok(())
    }

    /// #5400-#5413: the spindle's tool number, offsets X..W, diameter, angles, orientation
    /// (the machine's units, as the table holds them).
    pub(super) fn publish_tool_params(&mut self) {
        let (number, index) = self.tool.current;
        let tool = index.checked_sub(1).and_then(|i| self.config.tools.get(i));
        let mut values: Vec<f64> = Vec::with_capacity(14);
        values.push(f64::from(number));
        values.extend(tool.map_or([0.0; 6], |t| t.offset));
        // U V W: no such axes here.
        values.extend([0.0; 3]);
        values.extend(
            tool.map_or([0.0; 4], |t| [t.diameter, t.front_angle, t.back_angle, f64::from(t.orientation)]),
        );
        for (k, v) in values.iter().enumerate() {
            self.params.set(TOOL_PARAMS + k, *v);
        }
    }

    /// G43 (H), G43.1 or G49.
    pub(super) fn tool_length_offset(&mut self, code: u16, b: &Block, col: u32) -> KResult<()> {
        if self.comp.on() {
            return Err((col, ErrorKind::CutterComp(CompError::ToolOffsetChange)));
        }
        let mm = self.units.mm_per_unit();
        let new_mm: Pose = match code {
            g::G43 => {
                // H0 or no H: the spindle's tool.
                let index = match b.h {
                    Some(h) => self.tool_index(tool_number(h, col)?, col)?,
                    None => 0,
                };
                let index = if index == 0 { self.tool.current.1 } else { index };
                index.checked_sub(1).and_then(|i| self.config.tools.get(i)).map_or([0.0; 6], |t| t.offset)
            }
            g::G43_1 => {
                let mut o = self.tool.offset_mm;
                for (k, slot) in o.iter_mut().enumerate() {
                    if let Some(v) = b.axes.get(k).copied().flatten() {
                        *slot = if k < 3 { v * mm } else { v };
                    }
                }
                o
            }
            _ => [0.0; 6],
        };
        let old = self.tool.offset_mm;
        let mut delta: Pose = std::array::from_fn(|k| {
            let f = if k < 3 { mm } else { 1.0 };
            (old.get(k).copied().unwrap_or(0.0) - new_mm.get(k).copied().unwrap_or(0.0)) / f
        });
        // The X/Y change is in the machine's frame: into the rotated program frame.
        let (dx, dy) = (delta.first().copied().unwrap_or(0.0), delta.get(1).copied().unwrap_or(0.0));
        super::rotation::set_xy(&mut delta, super::rotation::rotate(dx, dy, -self.rot));
        for (p, d) in self.pos.iter_mut().zip(delta) {
            *p += d;
        }
        self.tool.offset_mm = new_mm;
        self.tool.active = code != g::G49;
        let offset: Pose = std::array::from_fn(|k| {
            let v = new_mm.get(k).copied().unwrap_or(0.0);
            if k < 3 {
                v / mm
            } else {
                v
            }
        });
        self.emit(Canon::UseToolLengthOffset { offset });
        Ok(())
    }
}

/// The tools' state: selected and spindle tool (number, place in the table) and the tool
/// length offset in force (machine units).
#[derive(Debug, Clone, Default)]
pub(super) struct ToolState {
    pub(super) selected: (u32, usize),
    pub(super) current: (u32, usize),
    pub(super) offset_mm: Pose,
    pub(super) active: bool,
}
