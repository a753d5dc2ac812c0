//! The tool table: LinuxCNC's `.tbl` format (`T1 P1 X0 Y0 Z10.5 D6 ;comment`, one tool a
//! line: number, pocket, offsets X..W, diameter D, front/back angles I/J, orientation Q),
//! read into [`Tool`]s in millimetres and degrees (the caller says the file's units).

use serde::{Deserialize, Serialize};

use crate::canon::Units;

/// One tool of the table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tool {
    /// Tool number (the T word).
    pub number: u32,
    /// Pocket (informational: the changer here is not random).
    pub pocket: u32,
    /// Length offsets X Y Z (mm) and A B C (degrees).
    pub offset: [f64; 6],
    /// Diameter (mm).
    pub diameter: f64,
    /// Lathe tool front and back angles (degrees) and orientation (0-9).
    pub front_angle: f64,
    /// See [`Tool::front_angle`].
    pub back_angle: f64,
    /// See [`Tool::front_angle`].
    pub orientation: u8,
    /// The text after `;`.
    pub comment: String,
}

/// Why a tool table line was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ToolTableError {
    /// A word with a letter the format does not have.
    #[error("tool table line {line}: unknown word '{word}'")]
    UnknownWord {
        /// 1-based line.
        line: usize,
        /// The word.
        word: String,
    },
    /// A word whose value is not a number (or not a whole one where one is needed).
    #[error("tool table line {line}: bad value in '{word}'")]
    BadValue {
        /// 1-based line.
        line: usize,
        /// The word.
        word: String,
    },
    /// A line without its T word.
    #[error("tool table line {line}: no T word")]
    NoToolNumber {
        /// 1-based line.
        line: usize,
    },
    /// The same tool number twice.
    #[error("tool table line {line}: tool {number} listed twice")]
    Duplicate {
        /// 1-based line.
        line: usize,
        /// The tool number.
        number: u32,
    },
}

/// Reads a tool table in LinuxCNC's format; lengths in the file are in `units`.
///
/// # Errors
/// The first line that is not a tool entry, blank or a comment.
pub fn parse_tool_table(text: &str, units: Units) -> Result<Vec<Tool>, ToolTableError> {
    let f = units.mm_per_unit();
    let mut tools: Vec<Tool> = Vec::new();
    for (k, raw) in text.lines().enumerate() {
        let line = k + 1;
        let (body, comment) = match raw.split_once(';') {
            Some((b, c)) => (b, c.trim().to_owned()),
            None => (raw, String::new()),
        };
        if body.trim().is_empty() {
            continue;
        }
        let mut tool = Tool {
            number: 0,
            pocket: 0,
            offset: [0.0; 6],
            diameter: 0.0,
            front_angle: 0.0,
            back_angle: 0.0,
            orientation: 0,
            comment,
        };
        let mut has_t = false;
        for word in body.split_whitespace() {
            let mut chars = word.chars();
            let letter = chars.next().map(|c| c.to_ascii_uppercase()).unwrap_or(' ');
            let bad = || ToolTableError::BadValue { line, word: word.to_owned() };
            let value: f64 = chars.as_str().parse().map_err(|_| bad())?;
            // Finite, also once turned from inches into millimetres.
            if !(value * 25.4).is_finite() {
                return Err(bad());
            }
            let whole = || -> Result<u32, ToolTableError> {
                if value.fract() != 0.0 || !(0.0..=f64::from(u32::MAX)).contains(&value) {
                    return Err(bad());
                }
                // Whole and in range: exact.
                Ok(value as u32)
            };
            match letter {
                'T' => {
                    tool.number = whole()?;
                    has_t = true;
                }
                'P' => tool.pocket = whole()?,
                'X' | 'Y' | 'Z' => {
                    let i = usize::from(letter as u8 - b'X');
                    if let Some(slot) = tool.offset.get_mut(i) {
                        *slot = value * f;
                    }
                }
                'A' | 'B' | 'C' => {
                    let i = 3 + usize::from(letter as u8 - b'A');
                    if let Some(slot) = tool.offset.get_mut(i) {
                        *slot = value;
                    }
                }
                // U V W: no such axes here; accepted and ignored.
                'U' | 'V' | 'W' => {}
                'D' => tool.diameter = value * f,
                'I' => tool.front_angle = value,
                'J' => tool.back_angle = value,
                'Q' => tool.orientation = u8::try_from(whole()?).ok().filter(|q| *q <= 9).ok_or_else(bad)?,
                _ => return Err(ToolTableError::UnknownWord { line, word: word.to_owned() }),
            }
        }
        if !has_t {
            return Err(ToolTableError::NoToolNumber { line });
        }
        if tools.iter().any(|t| t.number == tool.number) {
            return Err(ToolTableError::Duplicate { line, number: tool.number });
        }
        tools.push(tool);
    }
    Ok(tools)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn reads_linuxcnc_lines_in_either_unit() {
        let t =
            parse_tool_table("T1 P1 D6 Z10 ;drill 6\n\n; a comment\nt2 p2 z20.5 d3\n", Units::Mm).unwrap();
        assert_eq!(t.len(), 2);
        assert_eq!(
            (t[0].number, t[0].offset[2], t[0].diameter, t[0].comment.as_str()),
            (1, 10.0, 6.0, "drill 6")
        );
        assert_eq!((t[1].number, t[1].offset[2]), (2, 20.5));
        let inch = parse_tool_table("T3 Z1 D0.5\n", Units::Inch).unwrap();
        assert!((inch[0].offset[2] - 25.4).abs() < 1e-12 && (inch[0].diameter - 12.7).abs() < 1e-12);
    }

    #[test]
    fn names_what_is_wrong() {
        assert_eq!(
            parse_tool_table("T1 K3\n", Units::Mm),
            Err(ToolTableError::UnknownWord { line: 1, word: "K3".into() })
        );
        assert_eq!(
            parse_tool_table("T1.5\n", Units::Mm),
            Err(ToolTableError::BadValue { line: 1, word: "T1.5".into() })
        );
        assert_eq!(parse_tool_table("P1 Z3\n", Units::Mm), Err(ToolTableError::NoToolNumber { line: 1 }));
        assert_eq!(
            parse_tool_table("T1\nT1\n", Units::Mm),
            Err(ToolTableError::Duplicate { line: 2, number: 1 })
        );
        assert!(parse_tool_table("T1 Znan\n", Units::Mm).is_err());
    }
}
