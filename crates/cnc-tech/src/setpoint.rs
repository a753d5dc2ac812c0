//! Set-points the technology sends to the axes: a Z move and the X/Y coupling between
//! the CNC's virtual axes and the real gantry axes (specs/cnc.md, "Virtual axes ... coupled
//! 1:1 to the real axes; the coupling can be released ... to move the tool").

/// What the Z axis of the drilling unit should do this cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum ZCommand {
    /// Stay where it is.
    #[default]
    Hold,
    /// Move to `target` (mm, machine Z, up positive) at `speed` (mm/min), stop there.
    Move {
        /// Target position in mm.
        target: f64,
        /// Speed in mm/min (the axis may limit it further).
        speed: f64,
    },
}

/// The coupling of the real X/Y axes to the CNC's virtual X/Y axes.
///
/// Real = virtual + offset. While `coupled`, the offset stays as it is; while not, the
/// real axes move (at `shift_speed`) until real = virtual + `offset_target`.
/// "Decouple, move, recouple" is: `coupled = false` with the new target, wait until the
/// offset reached it, `coupled = true`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coupling {
    /// Whether the real axes follow the virtual ones 1:1.
    pub coupled: bool,
    /// Offset (real - virtual, mm) to reach while decoupled.
    pub offset_target: [f64; 2],
    /// Speed of the shifting move, mm/min.
    pub shift_speed: f64,
}

impl Default for Coupling {
    fn default() -> Self {
        Self { coupled: true, offset_target: [0.0, 0.0], shift_speed: 3000.0 }
    }
}
