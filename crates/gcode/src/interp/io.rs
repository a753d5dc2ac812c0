//! LinuxCNC's I/O and pallet M-codes, for a machine in the LinuxCNC dialect
//! ([`MCodeDialect::LinuxCnc`]): M60 (pallet shuttle, then a program stop), M61 Q (the
//! spindle's tool declared), M62/M63 P (digital output on/off with the next move), M64/M65
//! P (at once), M66 P|E L Q (wait on an input), M67/M68 E Q (analog output with the next
//! move / at once). In the seed's dialect these numbers are M-functions.
//!
//! As in LinuxCNC, M62-M68 form one modal group (one per block), executed after the T word
//! and before M6/M61; M60 belongs with M0/M1/M2/M30 at the end of the block; M61 with M6.

use super::Interpreter;
use crate::block::Block;
use crate::canon::{Canon, WaitMode};
use crate::error::{CompError, ErrorKind, KResult};

/// What M60-M68 mean on a machine ([`crate::InterpreterConfig::m_codes`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MCodeDialect {
    /// The seed's: every M number other than M0-M9 and M30 is a machine M-function
    /// ([`Canon::MFunction`]); the seed's drilling machine uses M60-M64 for its own
    /// functions (M63 activates the drilling technology). An E word is an error.
    #[default]
    Seed,
    /// LinuxCNC's: M60 pallet change, M61 Q set the current tool, M62-M68 digital and
    /// analog I/O with their P, E, L and Q words (the other numbers stay M-functions).
    LinuxCnc,
}

/// The LinuxCNC I/O codes of a block, taken out of its M-functions.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct IoCodes {
    /// M62-M68 (modal group 5: one per block).
    pub(super) io: Option<u16>,
    /// M61.
    pub(super) set_tool: bool,
    /// M60.
    pub(super) pallet: bool,
}

impl IoCodes {
    /// The block has M62-M66 (users of a P word).
    pub(super) fn uses_p(&self) -> bool {
        matches!(self.io, Some(62..=66))
    }

    /// The block has M66-M68 or M61 (users of a Q word).
    pub(super) fn uses_q(&self) -> bool {
        matches!(self.io, Some(66..=68)) || self.set_tool
    }

    /// The block has M66 (the user of an L word).
    pub(super) fn uses_l(&self) -> bool {
        self.io == Some(66)
    }

    /// The block has M66-M68 (users of an E word).
    pub(super) fn uses_e(&self) -> bool {
        matches!(self.io, Some(66..=68))
    }
}

/// LinuxCNC's `round_to_int` of a word, as an `i32` (a value out of range is an error).
fn round_to_int(v: f64, col: u32) -> KResult<i32> {
    let r = (v + 0.5).floor();
    if !(f64::from(i32::MIN)..=f64::from(i32::MAX)).contains(&r) {
        return Err((col, ErrorKind::NonInteger(v)));
    }
    // In the i32 range, whole.
    Ok(r as i32)
}

impl Interpreter<'_> {
    /// In the LinuxCNC dialect, takes M60-M68 out of the block's M-functions (checking
    /// their modal groups); in the seed's, leaves the block as it is.
    pub(super) fn take_io_codes(&self, b: &mut Block) -> KResult<IoCodes> {
        let mut codes = IoCodes::default();
        if self.config.m_codes != MCodeDialect::LinuxCnc {
            return Ok(codes);
        }
        let mut conflict = None;
        let (stop, tool) = (b.m_stop.is_some(), b.m_tool.is_some());
        b.m_user.retain(|&(m, col)| {
            let clash = match m {
                60 => std::mem::replace(&mut codes.pallet, true) || stop,
                61 => std::mem::replace(&mut codes.set_tool, true) || tool,
                62..=68 => codes.io.replace(m).is_some(),
                _ => return true,
            };
            if clash && conflict.is_none() {
                conflict = Some(col);
            }
            false
        });
        if let Some(col) = conflict {
            return Err((col, ErrorKind::MModalConflict));
        }
        Ok(codes)
    }

    /// M62-M68 (after the T word, before M6/M61), as LinuxCNC's `convert_m` checks and
    /// executes them.
    pub(super) fn io_words(&mut self, b: &Block, codes: IoCodes) -> KResult<()> {
        let col = b.first_col;
        let bad = |msg: &'static str| (col, ErrorKind::BadIo(msg));
        if let (Some(m), true) = (codes.io, self.comp.on()) {
            // LinuxCNC refuses I/O while compensated moves are held back.
            let e = match m {
                62 | 63 => CompError::MotionDigitalOutput,
                64 | 65 => CompError::AuxDigitalOutput,
                66 if b.e.is_some() => CompError::AnalogInputWait,
                66 => CompError::DigitalInputWait,
                67 => CompError::MotionAnalogOutput,
                _ => CompError::AuxAnalogOutput,
            };
            return Err((col, ErrorKind::CutterComp(e)));
        }
        match codes.io {
            Some(m @ 62..=65) => {
                let p = b.p.ok_or(bad(match m {
                    62 => "No valid P word with M62",
                    63 => "No valid P word with M63",
                    64 => "No valid P word with M64",
                    _ => "No valid P word with M65",
                }))?;
                let index = round_to_int(p, col)?;
                self.emit(Canon::DigitalOutput { index, on: m % 2 == 0, with_motion: m < 64 });
            }
            Some(66) => self.wait_input(b)?,
            Some(m @ (67 | 68)) => {
                let msg =
                    if m == 67 { "Invalid analog index with M67" } else { "Invalid analog index with M68" };
                let index = round_to_int(b.e.ok_or(bad(msg))?, col)?;
                if index < 0 {
                    return Err(bad(msg));
                }
                // LinuxCNC sends its "no Q" value, -1: here a missing value is an error.
                let value = b.q.ok_or(bad("Q word (the value) missing with M67/M68"))?;
                self.emit(Canon::AnalogOutput { index, value, with_motion: m == 67 });
            }
            _ => {}
        }
        Ok(())
    }

    /// M66: checks in LinuxCNC's order, then `WAIT`.
    fn wait_input(&mut self, b: &Block) -> KResult<()> {
        let col = b.first_col;
        let bad = |msg: &'static str| (col, ErrorKind::BadIo(msg));
        if b.p.is_some() && b.e.is_some() {
            return Err(bad("Invalid to select both a digital and an analog input with M66"));
        }
        let l = b.l.map(|l| round_to_int(l, col)).transpose()?;
        // LinuxCNC's missing Q reads as -1.
        let q = b.q.unwrap_or(-1.0);
        if q <= 0.0 && l.is_some_and(|l| l > 0) {
            return Err(bad("Zero timeout with wait type != immediate return"));
        }
        if b.e.is_some() && l.is_some_and(|l| l != 0) {
            return Err(bad("Can't select analog input with wait type != immediate return"));
        }
        let missing = bad("Need to have either a valid P or a valid E word with M66");
        let (word, analog) = match (b.p, b.e) {
            (Some(p), _) => (p, false),
            (None, Some(e)) => (e, true),
            (None, None) => return Err(missing),
        };
        let index = round_to_int(word, col)?;
        if index < 0 {
            return Err(missing);
        }
        let mode = match l.unwrap_or(0) {
            0 => WaitMode::Immediate,
            1 => WaitMode::Rise,
            2 => WaitMode::Fall,
            3 => WaitMode::High,
            4 => WaitMode::Low,
            _ => return Err(bad("L word (wait type) must be 0..=4 with M66")),
        };
        let timeout = if analog || q <= 0.0 { 0.0 } else { q };
        self.emit(Canon::WaitInput { index, analog, mode, timeout });
        Ok(())
    }

    /// M61 Q: the spindle's tool becomes tool Q (no change is made; `CHANGE_TOOL_NUMBER`
    /// with its place in the table), and #5400-#5413 follow.
    pub(super) fn set_current_tool(&mut self, b: &Block) -> KResult<()> {
        let col = b.first_col;
        let missing = (col, ErrorKind::BadIo("Need non-negative Q-word to specify tool number with M61"));
        let number = round_to_int(b.q.ok_or(missing.clone())?, col)?;
        let number = u32::try_from(number).map_err(|_| missing)?;
        let index = self.tool_index(number, col)?;
        self.tool.current = (number, index);
        self.emit(Canon::ChangeToolNumber { index });
        self.publish_tool_params();
        Ok(())
    }
}
