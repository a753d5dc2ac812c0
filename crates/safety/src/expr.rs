//! Rule expressions: the building blocks of the seed's macros combined with
//! `&&`, `||`, `!` (also `and`, `or`, `not`) and parentheses, parsed from text.
//!
//! Grammar (axis = name or id number; value = number with an optional unit suffix
//! `deg`, `mm`, `cm`, `m`, `um`, converted to the axis's unit; no suffix = axis units):
//!
//! ```text
//! or      := and ( ("||" | "or") and )*
//! and     := unary ( ("&&" | "and") unary )*
//! unary   := ("!" | "not") unary | "(" or ")" | leaf
//! leaf    := "limits(" axis ")"                    predicted reach stays inside the end limits
//!          | "region(" axis "," min "," max ")"    predicted reach avoids the closed region [min, max]
//!          | "collision(" axis "," axis ")"        predicted reaches, grown by the oversizes, stay apart
//!          | "below(" axis "," value ")"           predicted reach stays < value
//!          | "above(" axis "," value ")"           predicted reach stays > value
//!          | "within(" axis "," min "," max ")"    predicted reach stays inside (min, max)
//!          | "position(" axis ")" ("<" | ">") value  current sample only, NOT predictive (seed style)
//! ```
//!
//! Note on `!`: negating a predictive leaf is not conservative (the negation of "cannot
//! reach" is "might reach"); use it only for interlocks, never to build safety rules.

use crate::model::{AxisModel, Unit};
use std::fmt;
use thiserror::Error;

/// A leaf condition on predicted or current positions (axes are indexes into the model list).
#[derive(Debug, Clone, PartialEq)]
pub enum Leaf {
    /// Reach inside the axis's end limits.
    Limits {
        /// Axis index.
        axis: usize,
    },
    /// Reach does not touch the forbidden region `[min, max]`.
    Region {
        /// Axis index.
        axis: usize,
        /// Lower edge of the region (units).
        min: f64,
        /// Upper edge of the region (units).
        max: f64,
    },
    /// Two axes on a common line (same unit) cannot meet, sizes included.
    Collision {
        /// First axis index.
        a: usize,
        /// Second axis index.
        b: usize,
    },
    /// Reach stays strictly below `value`.
    Below {
        /// Axis index.
        axis: usize,
        /// Threshold (units).
        value: f64,
    },
    /// Reach stays strictly above `value`.
    Above {
        /// Axis index.
        axis: usize,
        /// Threshold (units).
        value: f64,
    },
    /// Reach stays strictly inside `(min, max)`.
    Within {
        /// Axis index.
        axis: usize,
        /// Lower bound (units).
        min: f64,
        /// Upper bound (units).
        max: f64,
    },
    /// Current position `< value` (no prediction, as the seed's `giAxis1position < ...`).
    PositionBelow {
        /// Axis index.
        axis: usize,
        /// Threshold (units).
        value: f64,
    },
    /// Current position `> value` (no prediction).
    PositionAbove {
        /// Axis index.
        axis: usize,
        /// Threshold (units).
        value: f64,
    },
}

impl Leaf {
    /// Axis indexes the leaf reads.
    pub fn axes(&self) -> (usize, Option<usize>) {
        match *self {
            Leaf::Collision { a, b } => (a, Some(b)),
            Leaf::Limits { axis }
            | Leaf::Region { axis, .. }
            | Leaf::Below { axis, .. }
            | Leaf::Above { axis, .. }
            | Leaf::Within { axis, .. }
            | Leaf::PositionBelow { axis, .. }
            | Leaf::PositionAbove { axis, .. } => (axis, None),
        }
    }
}

/// A compiled rule expression.
#[derive(Debug, Clone, PartialEq)]
pub enum Expr {
    /// All must hold.
    And(Vec<Expr>),
    /// At least one must hold.
    Or(Vec<Expr>),
    /// Negation.
    Not(Box<Expr>),
    /// A leaf condition.
    Leaf(Leaf),
}

/// A rule expression that could not be parsed or does not fit the axis models.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ExprError {
    /// Syntax error at a byte offset.
    #[error("at offset {at}: {msg}")]
    Syntax {
        /// Byte offset in the expression text.
        at: usize,
        /// What was expected.
        msg: String,
    },
    /// The axis name or number is not in the model.
    #[error("unknown axis {0:?}")]
    UnknownAxis(String),
    /// Units that cannot be combined.
    #[error("unit mismatch: {0}")]
    UnitMismatch(String),
    /// A region/window with `min >= max` or a non-finite number.
    #[error("impossible bounds: {0}")]
    Bounds(String),
}

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Ident(String),
    Num(f64, Option<String>),
    LParen,
    RParen,
    Comma,
    And,
    Or,
    Not,
    Lt,
    Gt,
}

fn tokenize(s: &str) -> Result<Vec<(usize, Tok)>, ExprError> {
    let mut out = Vec::new();
    let b = s.as_bytes();
    let mut i = 0;
    while let Some(&c) = b.get(i) {
        let start = i;
        let two = b.get(i..i + 2);
        match c {
            b' ' | b'\t' | b'\n' | b'\r' => {
                i += 1;
                continue;
            }
            b'(' => out.push((start, Tok::LParen)),
            b')' => out.push((start, Tok::RParen)),
            b',' => out.push((start, Tok::Comma)),
            b'<' => out.push((start, Tok::Lt)),
            b'>' => out.push((start, Tok::Gt)),
            b'!' => out.push((start, Tok::Not)),
            b'&' | b'|' if two == Some(b"&&") || two == Some(b"||") => {
                out.push((start, if c == b'&' { Tok::And } else { Tok::Or }));
                i += 2;
                continue;
            }
            b'-' | b'+' | b'.' | b'0'..=b'9' => {
                let mut j = i + 1;
                while b.get(j).is_some_and(|d| d.is_ascii_digit() || *d == b'.' || *d == b'_') {
                    j += 1;
                }
                // exponent
                if b.get(j).is_some_and(|d| *d == b'e' || *d == b'E')
                    && b.get(j + 1).is_some_and(|d| d.is_ascii_digit() || *d == b'-' || *d == b'+')
                {
                    j += 2;
                    while b.get(j).is_some_and(u8::is_ascii_digit) {
                        j += 1;
                    }
                }
                let text: String = s.get(i..j).unwrap_or("").chars().filter(|c| *c != '_').collect();
                let v: f64 = text
                    .parse()
                    .map_err(|_| ExprError::Syntax { at: start, msg: format!("bad number {text:?}") })?;
                let mut k = j;
                while b.get(k).is_some_and(u8::is_ascii_alphabetic) {
                    k += 1;
                }
                let suffix = (k > j).then(|| s.get(j..k).unwrap_or("").to_string());
                out.push((start, Tok::Num(v, suffix)));
                i = k;
                continue;
            }
            c if c.is_ascii_alphabetic() || c == b'_' => {
                let mut j = i + 1;
                while b.get(j).is_some_and(|d| d.is_ascii_alphanumeric() || *d == b'_') {
                    j += 1;
                }
                let word = s.get(i..j).unwrap_or("");
                out.push((
                    start,
                    match word {
                        "and" => Tok::And,
                        "or" => Tok::Or,
                        "not" => Tok::Not,
                        w => Tok::Ident(w.to_string()),
                    },
                ));
                i = j;
                continue;
            }
            _ => {
                return Err(ExprError::Syntax {
                    at: start,
                    msg: format!("unexpected character {:?}", char::from(c)),
                })
            }
        }
        i += 1;
    }
    Ok(out)
}

struct Parser<'a> {
    toks: Vec<(usize, Tok)>,
    pos: usize,
    end: usize,
    axes: &'a [AxisModel],
}

fn suffix_scale(suffix: &str) -> Option<(bool, f64)> {
    // (angular, size in deg or mm)
    Some(match suffix {
        "deg" => (true, 1.0),
        "um" => (false, 0.001),
        "mm" => (false, 1.0),
        "cm" => (false, 10.0),
        "m" => (false, 1000.0),
        _ => return None,
    })
}

fn unit_scale(u: Unit) -> f64 {
    match u {
        Unit::TenthDegree | Unit::TenthMillimetre => 0.1,
        Unit::Degree | Unit::Millimetre => 1.0,
        Unit::HundredthMillimetre => 0.01,
        Unit::Micrometre => 0.001,
    }
}

impl Parser<'_> {
    fn peek(&self) -> Option<&Tok> {
        self.toks.get(self.pos).map(|(_, t)| t)
    }
    fn at(&self) -> usize {
        self.toks.get(self.pos).map_or(self.end, |(a, _)| *a)
    }
    fn err<T>(&self, msg: impl Into<String>) -> Result<T, ExprError> {
        Err(ExprError::Syntax { at: self.at(), msg: msg.into() })
    }
    fn next(&mut self) -> Option<Tok> {
        let t = self.toks.get(self.pos).map(|(_, t)| t.clone());
        self.pos += 1;
        t
    }
    fn expect(&mut self, t: &Tok, what: &str) -> Result<(), ExprError> {
        if self.peek() == Some(t) {
            self.pos += 1;
            Ok(())
        } else {
            self.err(format!("expected {what}"))
        }
    }

    fn or(&mut self) -> Result<Expr, ExprError> {
        let mut v = vec![self.and()?];
        while self.peek() == Some(&Tok::Or) {
            self.pos += 1;
            v.push(self.and()?);
        }
        Ok(if v.len() == 1 { v.pop().map_or(Expr::Or(Vec::new()), |e| e) } else { Expr::Or(v) })
    }
    fn and(&mut self) -> Result<Expr, ExprError> {
        let mut v = vec![self.unary()?];
        while self.peek() == Some(&Tok::And) {
            self.pos += 1;
            v.push(self.unary()?);
        }
        Ok(if v.len() == 1 { v.pop().map_or(Expr::And(Vec::new()), |e| e) } else { Expr::And(v) })
    }
    fn unary(&mut self) -> Result<Expr, ExprError> {
        match self.peek() {
            Some(Tok::Not) => {
                self.pos += 1;
                Ok(Expr::Not(Box::new(self.unary()?)))
            }
            Some(Tok::LParen) => {
                self.pos += 1;
                let e = self.or()?;
                self.expect(&Tok::RParen, "')'")?;
                Ok(e)
            }
            Some(Tok::Ident(_)) => self.leaf(),
            _ => self.err("expected a condition, '(' or '!'"),
        }
    }
    fn axis(&mut self) -> Result<usize, ExprError> {
        let name = match self.next() {
            Some(Tok::Ident(n)) => n,
            Some(Tok::Num(v, None)) if v.fract() == 0.0 && v >= 0.0 => format!("{v}"),
            _ => {
                self.pos = self.pos.saturating_sub(1);
                return self.err("expected an axis name or number");
            }
        };
        self.axes
            .iter()
            .position(|a| a.name == name || a.id.to_string() == name)
            .ok_or(ExprError::UnknownAxis(name))
    }
    fn value(&mut self, axis: usize) -> Result<f64, ExprError> {
        let (v, suffix) = match self.next() {
            Some(Tok::Num(v, s)) => (v, s),
            _ => {
                self.pos = self.pos.saturating_sub(1);
                return self.err("expected a number");
            }
        };
        if !v.is_finite() {
            return Err(ExprError::Bounds(format!("{v} is not finite")));
        }
        let Some(suffix) = suffix else { return Ok(v) };
        let model = self.axes.get(axis).ok_or(ExprError::UnknownAxis(format!("#{axis}")))?;
        let unit = Unit::parse(&model.unit).map_err(|e| ExprError::UnitMismatch(e.to_string()))?;
        let (angular, size) = suffix_scale(&suffix)
            .ok_or_else(|| ExprError::UnitMismatch(format!("unknown unit suffix {suffix:?}")))?;
        if angular != unit.is_angular() {
            return Err(ExprError::UnitMismatch(format!(
                "value {v}{suffix} on axis {:?} measured in {}",
                model.name, model.unit
            )));
        }
        Ok(v * size / unit_scale(unit))
    }
    fn comma(&mut self) -> Result<(), ExprError> {
        self.expect(&Tok::Comma, "','")
    }
    fn leaf(&mut self) -> Result<Expr, ExprError> {
        let start = self.at();
        let Some(Tok::Ident(name)) = self.next() else {
            return self.err("expected a condition");
        };
        self.expect(&Tok::LParen, "'(' after condition name")?;
        let axis = self.axis()?;
        let leaf = match name.as_str() {
            "limits" => Leaf::Limits { axis },
            "region" | "within" => {
                self.comma()?;
                let min = self.value(axis)?;
                self.comma()?;
                let max = self.value(axis)?;
                if min >= max {
                    return Err(ExprError::Bounds(format!(
                        "{name}({}, {min}, {max}): min must be < max",
                        self.axes.get(axis).map_or("?", |a| a.name.as_str())
                    )));
                }
                if name == "region" {
                    Leaf::Region { axis, min, max }
                } else {
                    Leaf::Within { axis, min, max }
                }
            }
            "collision" => {
                self.comma()?;
                let b = self.axis()?;
                let (ma, mb) = (self.axes.get(axis), self.axes.get(b));
                if let (Some(ma), Some(mb)) = (ma, mb) {
                    if axis == b {
                        return Err(ExprError::Bounds(format!(
                            "collision of axis {:?} with itself",
                            ma.name
                        )));
                    }
                    if ma.unit != mb.unit {
                        return Err(ExprError::UnitMismatch(format!(
                            "collision({}, {}): {} vs {} (axes must share a line and a unit)",
                            ma.name, mb.name, ma.unit, mb.unit
                        )));
                    }
                }
                Leaf::Collision { a: axis, b }
            }
            "below" | "above" => {
                self.comma()?;
                let value = self.value(axis)?;
                if name == "below" {
                    Leaf::Below { axis, value }
                } else {
                    Leaf::Above { axis, value }
                }
            }
            "position" => {
                self.expect(&Tok::RParen, "')'")?;
                let op = self.next();
                let value = self.value(axis)?;
                return match op {
                    Some(Tok::Lt) => Ok(Expr::Leaf(Leaf::PositionBelow { axis, value })),
                    Some(Tok::Gt) => Ok(Expr::Leaf(Leaf::PositionAbove { axis, value })),
                    _ => Err(ExprError::Syntax {
                        at: start,
                        msg: "position(axis) must be followed by < or >".into(),
                    }),
                };
            }
            other => {
                return Err(ExprError::Syntax { at: start, msg: format!("unknown condition {other:?}") })
            }
        };
        self.expect(&Tok::RParen, "')'")?;
        Ok(Expr::Leaf(leaf))
    }
}

/// Parses an expression against the axis models.
pub fn parse(text: &str, axes: &[AxisModel]) -> Result<Expr, ExprError> {
    let toks = tokenize(text)?;
    let mut p = Parser { toks, pos: 0, end: text.len(), axes };
    let e = p.or()?;
    if p.pos < p.toks.len() {
        return p.err("unexpected text after the expression");
    }
    Ok(e)
}

/// Displays an expression in canonical form with axis names (used for fingerprints).
pub struct Canonical<'a> {
    /// Expression.
    pub expr: &'a Expr,
    /// Axis models the indexes refer to.
    pub axes: &'a [AxisModel],
}

impl fmt::Display for Canonical<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = |i: usize| self.axes.get(i).map_or("?", |a| a.name.as_str());
        let join = |f: &mut fmt::Formatter<'_>, v: &[Expr], op: &str| -> fmt::Result {
            f.write_str("(")?;
            for (i, e) in v.iter().enumerate() {
                if i > 0 {
                    write!(f, " {op} ")?;
                }
                write!(f, "{}", Canonical { expr: e, axes: self.axes })?;
            }
            f.write_str(")")
        };
        match self.expr {
            Expr::And(v) => join(f, v, "&&"),
            Expr::Or(v) => join(f, v, "||"),
            Expr::Not(e) => write!(f, "!{}", Canonical { expr: e, axes: self.axes }),
            Expr::Leaf(l) => match *l {
                Leaf::Limits { axis } => write!(f, "limits({})", n(axis)),
                Leaf::Region { axis, min, max } => write!(f, "region({}, {min:?}, {max:?})", n(axis)),
                Leaf::Within { axis, min, max } => write!(f, "within({}, {min:?}, {max:?})", n(axis)),
                Leaf::Collision { a, b } => write!(f, "collision({}, {})", n(a), n(b)),
                Leaf::Below { axis, value } => write!(f, "below({}, {value:?})", n(axis)),
                Leaf::Above { axis, value } => write!(f, "above({}, {value:?})", n(axis)),
                Leaf::PositionBelow { axis, value } => write!(f, "position({}) < {value:?}", n(axis)),
                Leaf::PositionAbove { axis, value } => write!(f, "position({}) > {value:?}", n(axis)),
            },
        }
    }
}
