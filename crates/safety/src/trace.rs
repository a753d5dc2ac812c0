//! Offline evaluation of a recorded trace (CSV), deterministic: the same rules and trace
//! always give the same rows. Used by `motus safety check --rules <file> --trace <csv>`.
//!
//! Format:
//! - Lines starting with `#` and blank lines are ignored. The first other line is the header.
//! - Column `time`: seconds (monotonic, strictly increasing). Each row is one supervisor
//!   evaluation at cycle `round(time / cycle_time)`.
//! - For every axis of the rules: `<axis>.position` (units) and `<axis>.speed` (units/s),
//!   in the algorithm unit of the axis (not raw). An empty cell (both or either) means no
//!   new sample for that axis in this row: the previous one ages.
//! - Optional `<axis>.homed` (`1`/`0`/`true`/`false`, default `1`) and `mode`
//!   (`normal`/`homing`, default `normal`). Any other column is an error.
//! - The integrity input is taken as OK (the trace checks the rules only).

use crate::rules::RuleSet;
use crate::supervisor::{CycleInput, Mode, Sample, Supervisor};
use std::fmt::Write as _;
use std::time::Duration;
use thiserror::Error;

/// A trace that cannot be read.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum TraceError {
    /// No header line.
    #[error("trace has no header")]
    NoHeader,
    /// A column the rules do not know, or a duplicate.
    #[error("header: unknown or duplicate column {0:?}")]
    Column(String),
    /// A required column is missing.
    #[error("header: missing column {0:?}")]
    MissingColumn(String),
    /// A cell that is not what its column needs.
    #[error("line {line}: column {column:?}: bad value {value:?}")]
    Value {
        /// 1-based line number.
        line: usize,
        /// Column name.
        column: String,
        /// Cell text.
        value: String,
    },
    /// Wrong number of cells.
    #[error("line {line}: {got} cells, header has {expected}")]
    Cells {
        /// 1-based line number.
        line: usize,
        /// Cells found.
        got: usize,
        /// Cells expected.
        expected: usize,
    },
    /// Time not increasing.
    #[error("line {line}: time {time} does not increase")]
    Time {
        /// 1-based line number.
        line: usize,
        /// Time found.
        time: f64,
    },
}

/// Result of one trace row.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceRow {
    /// 1-based line number in the CSV.
    pub line: usize,
    /// Time (s).
    pub time: f64,
    /// SafeToRun of this evaluation.
    pub safe_to_run: bool,
    /// Interlock outputs (config order).
    pub interlocks: Vec<bool>,
    /// Diagnosis text when SafeToRun is false.
    pub diagnosis: Option<String>,
}

#[derive(Clone, Copy)]
enum Col {
    Time,
    Pos(usize),
    Speed(usize),
    Homed(usize),
    Mode,
}

/// Evaluates every row of `csv` with the supervisor for `rules`.
pub fn evaluate(rules: &RuleSet, csv: &str) -> Result<Vec<TraceRow>, TraceError> {
    let mut lines = csv
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (_, header) = lines.next().ok_or(TraceError::NoHeader)?;
    let axes = rules.axes();
    let mut cols = Vec::new();
    let mut seen: Vec<&str> = Vec::new();
    for name in header.split(',').map(str::trim) {
        if seen.contains(&name) {
            return Err(TraceError::Column(name.to_string()));
        }
        seen.push(name);
        let col = match name.rsplit_once('.') {
            None if name == "time" => Col::Time,
            None if name == "mode" => Col::Mode,
            Some((axis, field)) => {
                let i = rules.axis_index(axis).ok_or_else(|| TraceError::Column(name.to_string()))?;
                match field {
                    "position" => Col::Pos(i),
                    "speed" => Col::Speed(i),
                    "homed" => Col::Homed(i),
                    _ => return Err(TraceError::Column(name.to_string())),
                }
            }
            None => return Err(TraceError::Column(name.to_string())),
        };
        cols.push(col);
    }
    let need = std::iter::once("time".to_string())
        .chain(axes.iter().flat_map(|a| [format!("{}.position", a.name), format!("{}.speed", a.name)]));
    for n in need {
        if !seen.contains(&n.as_str()) {
            return Err(TraceError::MissingColumn(n));
        }
    }
    let timing = &rules.config().supervisor;
    let mut sup = Supervisor::new(rules.clone());
    let mut samples: Vec<Option<Sample>> = vec![None; axes.len()];
    let mut out = Vec::new();
    let mut last_time = f64::NEG_INFINITY;
    for (line, text) in lines {
        let cells: Vec<&str> = text.split(',').map(str::trim).collect();
        if cells.len() != cols.len() {
            return Err(TraceError::Cells { line, got: cells.len(), expected: cols.len() });
        }
        let bad = |c: usize, v: &str| TraceError::Value {
            line,
            column: seen.get(c).copied().unwrap_or("?").to_string(),
            value: v.to_string(),
        };
        let mut time = f64::NAN;
        let mut mode = Mode::Normal;
        let mut pos: Vec<Option<f64>> = vec![None; axes.len()];
        let mut speed: Vec<Option<f64>> = vec![None; axes.len()];
        let mut homed = vec![true; axes.len()];
        for (c, (col, v)) in cols.iter().zip(&cells).enumerate() {
            let num = || -> Result<Option<f64>, TraceError> {
                if v.is_empty() {
                    Ok(None)
                } else {
                    v.parse::<f64>().map(Some).map_err(|_| bad(c, v))
                }
            };
            match *col {
                Col::Time => time = num()?.ok_or_else(|| bad(c, v))?,
                Col::Pos(i) => set(&mut pos, i, num()?),
                Col::Speed(i) => set(&mut speed, i, num()?),
                Col::Homed(i) => {
                    let h = match *v {
                        "1" | "true" | "" => true,
                        "0" | "false" => false,
                        _ => return Err(bad(c, v)),
                    };
                    if let Some(x) = homed.get_mut(i) {
                        *x = h;
                    }
                }
                Col::Mode => {
                    mode = match *v {
                        "normal" | "" => Mode::Normal,
                        "homing" => Mode::Homing,
                        _ => return Err(bad(c, v)),
                    }
                }
            }
        }
        if !(time.is_finite() && time > last_time && time >= 0.0) {
            return Err(TraceError::Time { line, time });
        }
        last_time = time;
        let cycle = (time / timing.cycle_time).round() as u64;
        for (i, slot) in samples.iter_mut().enumerate() {
            let h = homed.get(i).copied().unwrap_or(true);
            match (pos.get(i).copied().flatten(), speed.get(i).copied().flatten()) {
                (Some(p), Some(v)) => *slot = Some(Sample { position: p, speed: v, cycle, homed: h }),
                _ => {
                    if let Some(s) = slot.as_mut() {
                        s.homed = h;
                    }
                }
            }
        }
        let d = sup.evaluate(&CycleInput {
            now: Duration::from_secs_f64(time),
            cycle,
            mode,
            samples: &samples,
            params_ok: true,
        });
        out.push(TraceRow {
            line,
            time,
            safe_to_run: d.safe_to_run(),
            interlocks: d.interlocks().iter().map(|(_, v)| *v).collect(),
            diagnosis: d.diagnosis().map(ToString::to_string),
        });
    }
    Ok(out)
}

fn set(v: &mut [Option<f64>], i: usize, x: Option<f64>) {
    if let Some(s) = v.get_mut(i) {
        *s = x;
    }
}

/// Formats rows as CSV: `time,safe_to_run,<interlocks...>,diagnosis` (diagnosis quoted,
/// `"` doubled); deterministic.
pub fn format_rows(rules: &RuleSet, rows: &[TraceRow]) -> String {
    let mut s = String::from("time,safe_to_run");
    for r in rules.interlocks() {
        s.push(',');
        s.push_str(&r.name);
    }
    s.push_str(",diagnosis\n");
    for r in rows {
        let _ = write!(s, "{},{}", r.time, u8::from(r.safe_to_run));
        for v in &r.interlocks {
            let _ = write!(s, ",{}", u8::from(*v));
        }
        let d = r.diagnosis.as_deref().unwrap_or("").replace('"', "\"\"");
        let _ = writeln!(s, ",\"{d}\"");
    }
    s
}
