//! The drilling technology task (specs/cnc.md, "Drilling technology"; the source's
//! `tk_TECH_VRT_FREZ`).
//!
//! Driven by its [`DrillingCmd`] (from an HMI or a higher task) or by the synchronous
//! M-functions M60..M64 of the CNC program; parameters in [`DrillingPara`] and, for M60
//! and M61, the external parameters EXW60 (spindle rpm), EXF61 (drilling speed, mm/min)
//! and EXF62 (drilling depth, mm), and Motus's pecking extension for G73/G83: EXF63 (peck
//! increment, mm; 0 = one pass) and EXB64 (1 = chip breaking: a 0.254 mm retract in the
//! hole; 0 = out of the hole to the tool approach height; either way back fast to 0.254 mm
//! above the depth reached). Status in [`DrillingInfo`].
//!
//! | M | job |
//! |---|---|
//! | M60 | drill one hole: spindle on at EXW60 and wait ready; if the working height is not known, search it with the plate's reference switch at search speed, else plate down fast to its approach height; tool approach at approach speed (re-measuring when the switch closes more than the tolerance away from the known height); clamp; drill at EXF61 to EXF62 (in EXF63 pecks); retract at retract speed; unclamp; stay with the plate above the material (hole sequence) or return to the start position |
//! | M61 | spindle on at EXW60, acknowledged when at speed |
//! | M62 | spindle off, acknowledged at standstill |
//! | M63 | activate drilling: decouple real X/Y from the virtual axes, shift them by `-drill_offset`, recouple; locks out cutting |
//! | M64 | activate cutting: spindle off, Z to the start position, shift back, recouple; locks out drilling |
//!
//! A synchronous M is acknowledged through [`DrillingOutputs::acknowledge`] (the caller
//! clears the bit, which resumes the program) when its job is done. If the job fails,
//! the task stays in [`State::Error`] with the bit still set (the program stays paused)
//! until `stop_technology`, after which the M is reported in [`DrillingOutputs::abort`].
//!
//! Z geometry used by the task (machine Z of the spindle nose, up positive): `z_switch`
//! is the Z where the plate's switch closes over the material (the working height,
//! "zero point"); the tool tip is `tool_tip_height` above the material there, so it
//! touches at `z_switch - tool_tip_height`; the plate touches at
//! `z_switch + reference_travel`.

mod state_machine;
mod types;

pub use state_machine::DrillingTask;
pub use types::{
    DrillingCmd, DrillingError, DrillingInfo, DrillingInputs, DrillingOutputs, DrillingPara, ErrorRecord,
    HoleSettings, Job, MSet, Mode, State, Technology, M_ACTIVATE_CUTTING, M_ACTIVATE_DRILLING, M_DRILL,
    M_SPINDLE_OFF, M_SPINDLE_ON,
};

#[cfg(test)]
mod tests;
