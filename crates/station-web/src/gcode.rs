//! The tiny G-code subset the [`crate::fake::FakeBackend`] runs on its gantry: `G0`/`G1`
//! with `X Y Z` (mm, absolute) and `F` (mm/min), `G4`, `G17 G20 G21 G90 G94`, `M0 M2 M3 M5
//! M30`, `N`/`S`/`T`/`P` words, `;` and `( )` comments. Errors carry line:col (1-based).
//! The real station checks programs with the `gcode` crate instead.

use motus_lab::MotionDemand;

use crate::backend::{AxisView, ProgramCheck, ProgramDiagnostic};

/// One motion block of a checked program.
#[derive(Debug, Clone, PartialEq)]
pub struct FakeBlock {
    /// 1-based source line.
    pub line: usize,
    /// The line's text.
    pub text: String,
    /// `(axis id, target in m)`.
    pub targets: Vec<(String, f64)>,
    /// Path speed in m/s.
    pub speed: f64,
}

struct Word {
    letter: char,
    value: f64,
    col: usize,
}

/// Splits one line into words, or an error `(col, message)`.
fn words(line: &str) -> Result<Vec<Word>, (usize, String)> {
    let chars: Vec<char> = line.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while let Some(&c) = chars.get(i) {
        if c.is_whitespace() {
            i += 1;
            continue;
        }
        if c == ';' {
            break;
        }
        if c == '(' {
            match chars.iter().skip(i).position(|&d| d == ')') {
                Some(n) => {
                    i += n + 1;
                    continue;
                }
                None => return Err((i + 1, "unclosed comment".into())),
            }
        }
        if !c.is_ascii_alphabetic() {
            return Err((i + 1, format!("unexpected character {c:?}")));
        }
        let col = i + 1;
        i += 1;
        let start = i;
        while chars.get(i).is_some_and(|d| d.is_ascii_digit() || matches!(d, '.' | '+' | '-')) {
            i += 1;
        }
        let num: String = chars.iter().skip(start).take(i - start).collect();
        let value: f64 = num
            .parse()
            .map_err(|_| (col, format!("word {} needs a number, found {num:?}", c.to_ascii_uppercase())))?;
        out.push(Word { letter: c.to_ascii_uppercase(), value, col });
    }
    Ok(out)
}

/// Checks `text` against the axes `views` (gantry `x y z`); returns the diagnostics and
/// per-axis demands, and the motion blocks to run.
#[must_use]
pub fn check_gcode(text: &str, views: &[AxisView]) -> (ProgramCheck, Vec<FakeBlock>) {
    let mut errors = Vec::new();
    let mut blocks = Vec::new();
    let mut feed: Option<f64> = None;
    let mut rapid = true;
    let mut scale = 0.001; // mm -> m
    let mut peak: Vec<(String, f64)> = Vec::new();
    for (n, raw) in text.lines().enumerate() {
        let line = n + 1;
        let ws = match words(raw) {
            Ok(ws) => ws,
            Err((col, message)) => {
                errors.push(ProgramDiagnostic { line, col, message });
                continue;
            }
        };
        let mut targets = Vec::new();
        let mut end = false;
        for w in &ws {
            let err = |m: String| ProgramDiagnostic { line, col: w.col, message: m };
            match w.letter {
                'G' | 'M' => {
                    // Codes are whole numbers here (G4, G21...); a fraction is unsupported.
                    let code = if w.value.fract() == 0.0 && w.value.abs() < 1000.0 {
                        Some(w.value as i64)
                    } else {
                        None
                    };
                    match (w.letter, code) {
                        ('G', Some(0)) => rapid = true,
                        ('G', Some(1)) => rapid = false,
                        ('G', Some(20)) => scale = 0.0254,
                        ('G', Some(21)) => scale = 0.001,
                        ('G', Some(4 | 17 | 90 | 94)) | ('M', Some(0 | 3 | 5)) => {}
                        ('M', Some(2 | 30)) => end = true,
                        (l, _) => errors.push(err(format!("unsupported {l}{}", w.value))),
                    }
                }
                'F' => {
                    if w.value <= 0.0 {
                        errors.push(err("feed F must be positive".into()));
                    } else {
                        feed = Some(w.value);
                    }
                }
                'X' | 'Y' | 'Z' => {
                    let id = w.letter.to_ascii_lowercase().to_string();
                    let target = w.value * scale;
                    match views.iter().find(|a| a.id == id) {
                        Some(a) if target < a.limits.min || target > a.limits.max => {
                            errors.push(err(format!(
                                "{} {} is outside [{}, {}] m",
                                w.letter, w.value, a.limits.min, a.limits.max
                            )))
                        }
                        Some(_) => targets.push((id, target)),
                        None => errors.push(err(format!("no axis {id}"))),
                    }
                }
                'N' | 'S' | 'T' | 'P' => {}
                other => errors.push(err(format!("unknown word {other}"))),
            }
        }
        if !targets.is_empty() {
            let speed = if rapid {
                targets
                    .iter()
                    .filter_map(|(id, _)| views.iter().find(|a| a.id == *id).map(|a| a.limits.max_speed))
                    .fold(f64::INFINITY, f64::min)
            } else {
                match feed {
                    Some(f) => f * scale / 60.0,
                    None => {
                        errors.push(ProgramDiagnostic {
                            line,
                            col: 1,
                            message: "G1 without a feed F".into(),
                        });
                        0.0
                    }
                }
            };
            for (id, _) in &targets {
                match peak.iter_mut().find(|(i, _)| i == id) {
                    Some((_, s)) => *s = s.max(speed),
                    None => peak.push((id.clone(), speed)),
                }
            }
            blocks.push(FakeBlock { line, text: raw.trim().to_string(), targets, speed });
        }
        if end {
            break;
        }
    }
    let demands = peak
        .into_iter()
        .map(|(id, speed)| {
            let acceleration = views.iter().find(|a| a.id == id).map_or(0.0, |a| a.acceleration);
            (id, MotionDemand { speed, acceleration })
        })
        .collect();
    (ProgramCheck { errors, demands }, blocks)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use crate::backend::MachineBackend;
    use crate::fake::FakeBackend;

    #[test]
    fn checks_words_limits_and_demands() {
        let views = FakeBackend::new().axes();
        let text = "G21 G90\nG1 X100 Y50 F600 ; 10 mm/s\nG0 Z20\nG1 X600\nQ5\nG1 X1..2\nM30\nG1 X1";
        let (check, blocks) = check_gcode(text, &views);
        // Expected by hand: line 4 X600 mm = 0.6 m > 0.5 m at col 4; line 5 unknown Q at
        // col 1; line 6 bad number at col 4 ("X1..2"); nothing after M30 is read.
        let found: Vec<(usize, usize)> = check.errors.iter().map(|e| (e.line, e.col)).collect();
        assert_eq!(found, vec![(4, 4), (5, 1), (6, 4)], "{:?}", check.errors);
        assert_eq!(blocks.len(), 2);
        assert_eq!(blocks[0].targets, vec![("x".into(), 0.1), ("y".into(), 0.05)]);
        // F600 mm/min = 0.01 m/s.
        assert!((blocks[0].speed - 0.01).abs() < 1e-12);
        // G0 Z: rapid at z's max speed 0.05 m/s.
        assert!((blocks[1].speed - 0.05).abs() < 1e-12);
        let x = check.demands.iter().find(|(i, _)| i == "x").unwrap().1;
        assert!((x.speed - 0.01).abs() < 1e-12);
    }

    #[test]
    fn comments_are_skipped_and_unclosed_reported() {
        let views = FakeBackend::new().axes();
        let (check, blocks) = check_gcode("(start) G0 X10 ; go\nG0 (oops X1", &views);
        assert_eq!(blocks.len(), 1);
        assert_eq!(check.errors.len(), 1);
        assert_eq!((check.errors[0].line, check.errors[0].col), (2, 4));
    }
}
