//! Expressions (`[..]`, functions, operators), compiled by the parser into postfix
//! instructions ([`Op`]) and evaluated on a value stack (no trees, no allocation).
//!
//! Semantics follow LinuxCNC: trigonometric functions work in degrees, `EQ`/`NE` compare
//! with a tolerance of 0.0001, binary operators of equal precedence evaluate left to right
//! (`2**3**2` is 64), `MOD` gives a result with the sign of the divisor's magnitude (never
//! negative), `ROUND` rounds half away from zero.

use crate::error::ErrorKind;
use crate::params::{param_index, Params};
/// Tolerance of `EQ` / `NE` (LinuxCNC's `TOLERANCE_EQUAL`).
const TOLERANCE_EQUAL: f64 = 0.0001;

/// A unary function.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Func {
    Abs,
    Acos,
    Asin,
    Cos,
    Exp,
    Fix,
    Fup,
    Ln,
    Round,
    Sin,
    Sqrt,
    Tan,
}

impl Func {
    /// The function of a lower-case name.
    pub(crate) fn from_name(name: &[u8]) -> Option<Self> {
        Some(match name {
            b"abs" => Self::Abs,
            b"acos" => Self::Acos,
            b"asin" => Self::Asin,
            b"cos" => Self::Cos,
            b"exp" => Self::Exp,
            b"fix" => Self::Fix,
            b"fup" => Self::Fup,
            b"ln" => Self::Ln,
            b"round" => Self::Round,
            b"sin" => Self::Sin,
            b"sqrt" => Self::Sqrt,
            b"tan" => Self::Tan,
            _ => return None,
        })
    }

    fn apply(self, v: f64) -> Result<f64, ErrorKind> {
        Ok(match self {
            Self::Abs => v.abs(),
            Self::Acos => {
                if !(-1.0..=1.0).contains(&v) {
                    return Err(ErrorKind::FunctionDomain("ACOS"));
                }
                v.acos().to_degrees()
            }
            Self::Asin => {
                if !(-1.0..=1.0).contains(&v) {
                    return Err(ErrorKind::FunctionDomain("ASIN"));
                }
                v.asin().to_degrees()
            }
            Self::Cos => v.to_radians().cos(),
            Self::Exp => v.exp(),
            Self::Fix => v.floor(),
            Self::Fup => v.ceil(),
            Self::Ln => {
                if v <= 0.0 {
                    return Err(ErrorKind::FunctionDomain("LN"));
                }
                v.ln()
            }
            Self::Round => v.round(),
            Self::Sin => v.to_radians().sin(),
            Self::Sqrt => {
                if v < 0.0 {
                    return Err(ErrorKind::FunctionDomain("SQRT"));
                }
                v.sqrt()
            }
            Self::Tan => v.to_radians().tan(),
        })
    }
}

/// A binary operator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum BinOp {
    Pow,
    Mul,
    Div,
    Mod,
    Add,
    Sub,
    Eq,
    Ne,
    Gt,
    Ge,
    Lt,
    Le,
    And,
    Or,
    Xor,
}

impl BinOp {
    /// LinuxCNC's precedence (higher binds tighter).
    pub(crate) fn precedence(self) -> u8 {
        match self {
            Self::Pow => 6,
            Self::Mul | Self::Div | Self::Mod => 5,
            Self::Add | Self::Sub => 4,
            Self::Eq | Self::Ne | Self::Gt | Self::Ge | Self::Lt | Self::Le => 3,
            Self::And | Self::Or | Self::Xor => 2,
        }
    }

    fn apply(self, l: f64, r: f64) -> Result<f64, ErrorKind> {
        let b = |c: bool| if c { 1.0 } else { 0.0 };
        Ok(match self {
            Self::Pow => {
                if l < 0.0 && r.floor() != r {
                    return Err(ErrorKind::FunctionDomain("**"));
                }
                l.powf(r)
            }
            Self::Mul => l * r,
            Self::Div => {
                if r == 0.0 {
                    return Err(ErrorKind::DivideByZero);
                }
                l / r
            }
            Self::Mod => {
                if r == 0.0 {
                    return Err(ErrorKind::DivideByZero);
                }
                let m = l % r;
                if m < 0.0 {
                    m + r.abs()
                } else {
                    m
                }
            }
            Self::Add => l + r,
            Self::Sub => l - r,
            Self::Eq => b((l - r).abs() < TOLERANCE_EQUAL),
            Self::Ne => b((l - r).abs() >= TOLERANCE_EQUAL),
            Self::Gt => b(l > r),
            Self::Ge => b(l >= r),
            Self::Lt => b(l < r),
            Self::Le => b(l <= r),
            Self::And => b(l != 0.0 && r != 0.0),
            Self::Or => b(l != 0.0 || r != 0.0),
            Self::Xor => b((l != 0.0) != (r != 0.0)),
        })
    }
}

/// `x.round()` (half away from zero), without the library call when `x` is already an
/// integer (the usual case for G/M codes and parameter numbers).
#[inline]
pub(crate) fn round(x: f64) -> f64 {
    // Exact test: the saturating cast gives back `x` only for integers (and -0.0 -> 0,
    // which compares equal and is returned unchanged).
    if (x as i64) as f64 == x {
        x
    } else {
        x.round()
    }
}

/// One instruction of a compiled value, in postfix order.
///
/// Names are byte ranges of the line's normalised text (lower case, without spaces).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Op {
    /// Push a number.
    Num(f64),
    /// Pop a parameter number, push that parameter's value.
    Param,
    /// Push parameter `#n` (a literal, valid number: `#12`).
    ParamAt(usize),
    /// Push the named parameter `#<name>`.
    Named(u32, u32),
    /// Push 1 if the named parameter exists, else 0 (`EXISTS[#<name>]`).
    Exists(u32, u32),
    /// Negate the top value.
    Neg,
    /// Apply a function to the top value.
    Func(Func),
    /// Pop b, pop a, push `ATAN[a]/[b]` in degrees.
    Atan,
    /// Pop r, pop l, push `l op r`.
    Bin(BinOp),
}

/// A word's value: a number read directly (the common case) or a compiled expression
/// (a range of the line's [`Op`]s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Val {
    /// A plain number.
    Num(f64),
    /// Instructions `start..end` of the line.
    Code(u32, u32),
}

/// The name `text[start..end]` (ASCII, so always valid UTF-8).
pub(crate) fn name(text: &[u8], start: u32, end: u32) -> &str {
    text.get(start as usize..end as usize).and_then(|n| std::str::from_utf8(n).ok()).unwrap_or("")
}

fn pop(stack: &mut Vec<f64>) -> Result<f64, ErrorKind> {
    stack.pop().ok_or(ErrorKind::BadExpression("operand missing"))
}

/// Runs `ops` (a complete value) on `stack` (cleared first) and returns the result.
/// Evaluation order is LinuxCNC's: left operand, right operand, then the operator.
pub(crate) fn run(params: &Params, stack: &mut Vec<f64>, ops: &[Op], text: &[u8]) -> Result<f64, ErrorKind> {
    stack.clear();
    for op in ops {
        let v = match *op {
            Op::Num(v) => v,
            Op::Param => params.get(param_index(pop(stack)?)?),
            Op::ParamAt(i) => params.get(i),
            Op::Named(a, b) => {
                let n = name(text, a, b);
                params.get_named(n).ok_or_else(|| ErrorKind::UndefinedNamedParameter(n.to_owned()))?
            }
            Op::Exists(a, b) => {
                if params.get_named(name(text, a, b)).is_some() {
                    1.0
                } else {
                    0.0
                }
            }
            Op::Neg => -pop(stack)?,
            Op::Func(f) => f.apply(pop(stack)?)?,
            Op::Atan => {
                let b = pop(stack)?;
                let a = pop(stack)?;
                a.atan2(b).to_degrees()
            }
            Op::Bin(o) => {
                let r = pop(stack)?;
                let l = pop(stack)?;
                o.apply(l, r)?
            }
        };
        stack.push(v);
    }
    pop(stack)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn mod_is_never_negative() {
        // LinuxCNC: fmod(-7, 3) = -1, then + |3| = 2.
        assert_eq!(BinOp::Mod.apply(-7.0, 3.0).unwrap(), 2.0);
        assert_eq!(BinOp::Mod.apply(7.0, 3.0).unwrap(), 1.0);
    }

    #[test]
    fn eq_has_tolerance() {
        assert_eq!(BinOp::Eq.apply(1.0, 1.00005).unwrap(), 1.0);
        assert_eq!(BinOp::Eq.apply(1.0, 1.0002).unwrap(), 0.0);
    }

    #[test]
    fn round_matches_std() {
        for x in [0.0, -0.0, 2.5, -2.5, 0.49999999999999994, 1e300, -7.0, 4503599627370497.0, f64::INFINITY] {
            assert_eq!(round(x).to_bits(), x.round().to_bits(), "{x}");
        }
        assert!(round(f64::NAN).is_nan());
    }

    #[test]
    fn postfix_runs_left_to_right() {
        // 10 - 4 - 3 = 3 as [10 4 - 3 -]; #2 = 5 read through Param.
        let mut p = Params::default();
        p.set(2, 5.0);
        let mut st = Vec::new();
        let ops = [Op::Num(10.0), Op::Num(4.0), Op::Bin(BinOp::Sub), Op::Num(3.0), Op::Bin(BinOp::Sub)];
        assert_eq!(run(&p, &mut st, &ops, b"").unwrap(), 3.0);
        let ops = [Op::Num(2.0), Op::Param, Op::Neg];
        assert_eq!(run(&p, &mut st, &ops, b"").unwrap(), -5.0);
        let ops = [Op::Named(0, 3)];
        assert_eq!(
            run(&p, &mut st, &ops, b"abc").unwrap_err(),
            ErrorKind::UndefinedNamedParameter("abc".into())
        );
        assert_eq!(run(&p, &mut st, &[Op::Exists(0, 3)], b"abc").unwrap(), 0.0);
        assert_eq!(
            run(&p, &mut st, &[Op::Num(0.0), Op::Param], b"").unwrap_err(),
            ErrorKind::ParameterOutOfRange(0.0)
        );
    }
}
