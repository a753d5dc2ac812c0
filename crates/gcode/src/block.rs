//! Reading a parsed line into a block: evaluated word values, grouped by modal group,
//! with LinuxCNC's checks (one G per modal group, one M per M group, no repeated words).

use crate::error::{ErrorKind, KResult};
use crate::params::Params;
use crate::parse::Line;

/// G codes, as ten times their number (G92.1 = 921).
pub(crate) mod g {
    pub(crate) const G0: u16 = 0;
    pub(crate) const G1: u16 = 10;
    pub(crate) const G2: u16 = 20;
    pub(crate) const G3: u16 = 30;
    pub(crate) const G4: u16 = 40;
    pub(crate) const G10: u16 = 100;
    pub(crate) const G17: u16 = 170;
    pub(crate) const G18: u16 = 180;
    pub(crate) const G19: u16 = 190;
    pub(crate) const G20: u16 = 200;
    pub(crate) const G21: u16 = 210;
    pub(crate) const G28: u16 = 280;
    pub(crate) const G28_1: u16 = 281;
    pub(crate) const G30: u16 = 300;
    pub(crate) const G30_1: u16 = 301;
    pub(crate) const G40: u16 = 400;
    pub(crate) const G41: u16 = 410;
    pub(crate) const G41_1: u16 = 411;
    pub(crate) const G42: u16 = 420;
    pub(crate) const G42_1: u16 = 421;
    pub(crate) const G52: u16 = 520;
    pub(crate) const G43: u16 = 430;
    pub(crate) const G43_1: u16 = 431;
    pub(crate) const G49: u16 = 490;
    pub(crate) const G53: u16 = 530;
    pub(crate) const G61: u16 = 610;
    pub(crate) const G61_1: u16 = 611;
    pub(crate) const G64: u16 = 640;
    pub(crate) const G73: u16 = 730;
    pub(crate) const G80: u16 = 800;
    pub(crate) const G81: u16 = 810;
    pub(crate) const G82: u16 = 820;
    pub(crate) const G83: u16 = 830;
    pub(crate) const G85: u16 = 850;
    pub(crate) const G89: u16 = 890;
    pub(crate) const G98: u16 = 980;
    pub(crate) const G99: u16 = 990;
    pub(crate) const G90: u16 = 900;
    pub(crate) const G90_1: u16 = 901;
    pub(crate) const G91: u16 = 910;
    pub(crate) const G91_1: u16 = 911;
    pub(crate) const G92: u16 = 920;
    pub(crate) const G92_1: u16 = 921;
    pub(crate) const G92_2: u16 = 922;
    pub(crate) const G92_3: u16 = 923;
    pub(crate) const G93: u16 = 930;
    pub(crate) const G94: u16 = 940;
    pub(crate) const G95: u16 = 950;
    pub(crate) const G96: u16 = 960;
    pub(crate) const G97: u16 = 970;
}

/// The modal group of a supported G code (LinuxCNC's numbering).
fn g_group(code: u16) -> Option<usize> {
    Some(match code {
        g::G4 | g::G10 | g::G53 | g::G92 | g::G92_1 | g::G92_2 | g::G92_3 => 0,
        g::G28 | g::G28_1 | g::G30 | g::G30_1 | g::G52 => 0,
        g::G0 | g::G1 | g::G2 | g::G3 | g::G80 => 1,
        g::G73 | g::G81 | g::G82 | g::G83 | g::G85 | g::G89 => 1,
        g::G17 | g::G18 | g::G19 => 2,
        g::G90 | g::G91 => 3,
        g::G90_1 | g::G91_1 => 4,
        g::G93 | g::G94 | g::G95 => 5,
        g::G20 | g::G21 => 6,
        g::G40 | g::G41 | g::G41_1 | g::G42 | g::G42_1 => 7,
        g::G43 | g::G43_1 | g::G49 => 8,
        g::G98 | g::G99 => 10,
        540 | 550 | 560 | 570 | 580 | 590 | 591 | 592 | 593 => 12,
        g::G61 | g::G61_1 | g::G64 => 13,
        g::G96 | g::G97 => 14,
        _ => return None,
    })
}

/// M group: 4 = stopping, 6 = tool change, 7 = spindle, 8 = coolant; `None` = the seed's
/// M-functions.
fn m_group(m: u16) -> Option<usize> {
    match m {
        0 | 1 | 2 | 30 => Some(4),
        6 => Some(6),
        3..=5 => Some(7),
        7..=9 => Some(8),
        _ => None,
    }
}

/// One block, values evaluated.
#[derive(Debug, Clone, Default)]
pub(crate) struct Block {
    /// Per modal group 0..=14: the code and its column.
    pub(crate) g: [Option<(u16, u32)>; 15],
    /// Standard M codes per group (4, 7, 8).
    pub(crate) m_stop: Option<u16>,
    /// M6.
    pub(crate) m_tool: Option<u16>,
    pub(crate) m_spindle: Option<u16>,
    pub(crate) m_coolant: Option<u16>,
    /// The seed's M-functions in order of appearance, with columns.
    pub(crate) m_user: Vec<(u16, u32)>,
    /// X Y Z A B C.
    pub(crate) axes: [Option<f64>; 6],
    /// I J K.
    pub(crate) ijk: [Option<f64>; 3],
    pub(crate) f: Option<f64>,
    pub(crate) s: Option<f64>,
    pub(crate) p: Option<f64>,
    pub(crate) r: Option<f64>,
    pub(crate) l: Option<f64>,
    pub(crate) q: Option<f64>,
    pub(crate) t: Option<f64>,
    pub(crate) h: Option<f64>,
    pub(crate) d: Option<f64>,
    /// The E word (M66-M68's analog channel in the LinuxCNC dialect) and its column.
    pub(crate) e: Option<f64>,
    pub(crate) e_col: u32,
    /// Polar radius `@` and angle `^` (degrees).
    pub(crate) polar: [Option<f64>; 2],
    /// Column of the first axis word (for error positions).
    pub(crate) axis_col: Option<u32>,
    /// Column of the motion word or of the first word.
    pub(crate) first_col: u32,
}

impl Block {
    /// Axis words, polar ones included.
    pub(crate) fn has_axes(&self) -> bool {
        self.axes.iter().any(Option::is_some) || self.has_polar()
    }

    /// A polar radius or angle word.
    pub(crate) fn has_polar(&self) -> bool {
        self.polar.iter().any(Option::is_some)
    }
}

fn integer(v: f64, col: u32) -> KResult<i64> {
    let r = crate::expr::round(v);
    if (v - r).abs() > 0.0001 {
        return Err((col, ErrorKind::NonInteger(v)));
    }
    // Rounded, and checked to fit below.
    if r.abs() > 1e15 {
        return Err((col, ErrorKind::NonInteger(v)));
    }
    Ok(r as i64)
}

/// Evaluates every word of `line` with the parameters as they are before the line.
/// `b` must be empty ([`Block::default`]); it is filled in place.
pub(crate) fn read_block(b: &mut Block, line: &Line, params: &Params, stack: &mut Vec<f64>) -> KResult<()> {
    b.first_col = line.words.first().map_or(1, |w| w.col);
    for w in &line.words {
        let v = line.eval(params, stack, w.value, w.col)?;
        let col = w.col;
        let set = |slot: &mut Option<f64>, letter: u8| -> KResult<()> {
            if slot.is_some() {
                return Err((col, ErrorKind::DuplicateWord(char::from(letter))));
            }
            *slot = Some(v);
            Ok(())
        };
        match w.letter {
            b'G' => {
                let code10 = crate::expr::round(v * 10.0);
                if (v * 10.0 - code10).abs() > 0.0001 || !(0.0..=9999.0).contains(&code10) {
                    return Err((col, ErrorKind::UnsupportedG(v)));
                }
                // In 0..=9999, so exact.
                let code = code10 as u16;
                let grp = g_group(code).ok_or((col, ErrorKind::UnsupportedG(v)))?;
                let slot = b.g.get_mut(grp).ok_or((col, ErrorKind::UnsupportedG(v)))?;
                // As LinuxCNC's read_g: G80 beside another motion code (a CAM safety line's
                // `G0 G80`) gives way to it, in either order.
                match *slot {
                    Some(_) if code == g::G80 => {}
                    Some((prev, _)) if prev != g::G80 => return Err((col, ErrorKind::GModalConflict)),
                    _ => *slot = Some((code, col)),
                }
            }
            b'M' => {
                let m = integer(v, col)?;
                let m =
                    u16::try_from(m).ok().filter(|&m| m <= 1023).ok_or((col, ErrorKind::UnsupportedM(v)))?;
                let slot = match m_group(m) {
                    Some(4) => &mut b.m_stop,
                    Some(6) => &mut b.m_tool,
                    Some(7) => &mut b.m_spindle,
                    Some(_) => &mut b.m_coolant,
                    None => {
                        b.m_user.push((m, col));
                        continue;
                    }
                };
                if slot.is_some() {
                    return Err((col, ErrorKind::MModalConflict));
                }
                *slot = Some(m);
            }
            b'X' | b'Y' | b'Z' | b'A' | b'B' | b'C' => {
                let k = match w.letter {
                    b'X' => 0,
                    b'Y' => 1,
                    b'Z' => 2,
                    b'A' => 3,
                    b'B' => 4,
                    _ => 5,
                };
                if let Some(slot) = b.axes.get_mut(k) {
                    set(slot, w.letter)?;
                }
                b.axis_col.get_or_insert(col);
            }
            b'I' | b'J' | b'K' => {
                let k = usize::from(w.letter - b'I');
                if let Some(slot) = b.ijk.get_mut(k) {
                    set(slot, w.letter)?;
                }
            }
            b'F' => set(&mut b.f, b'F')?,
            b'S' => set(&mut b.s, b'S')?,
            b'P' => set(&mut b.p, b'P')?,
            b'R' => set(&mut b.r, b'R')?,
            b'L' => set(&mut b.l, b'L')?,
            b'Q' => set(&mut b.q, b'Q')?,
            b'T' => set(&mut b.t, b'T')?,
            b'H' => set(&mut b.h, b'H')?,
            b'D' => set(&mut b.d, b'D')?,
            b'E' => {
                set(&mut b.e, b'E')?;
                b.e_col = col;
            }
            b'@' | b'^' => {
                let k = usize::from(w.letter == b'^');
                if let Some(slot) = b.polar.get_mut(k) {
                    set(slot, w.letter)?;
                }
                b.axis_col.get_or_insert(col);
            }
            other => return Err((col, ErrorKind::UnsupportedLetter(char::from(other)))),
        }
    }
    Ok(())
}
