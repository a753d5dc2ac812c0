//! Expressions (`[..]`, functions, operators) and parameters (`#n`, `#<local>`, `#<_global>`).
//!
//! Semantics follow LinuxCNC: trigonometric functions work in degrees, `EQ`/`NE` compare
//! with a tolerance of 0.0001, binary operators of equal precedence evaluate left to right
//! (`2**3**2` is 64), `MOD` gives a result with the sign of the divisor's magnitude (never
//! negative), `ROUND` rounds half away from zero.

use std::collections::HashMap;

use crate::error::{ErrorKind, KResult};

/// Highest numbered parameter (LinuxCNC's `RS274NGC_MAX_PARAMETERS - 1`).
pub const MAX_PARAMETER: usize = 5602;
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
    pub(crate) fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "abs" => Self::Abs,
            "acos" => Self::Acos,
            "asin" => Self::Asin,
            "cos" => Self::Cos,
            "exp" => Self::Exp,
            "fix" => Self::Fix,
            "fup" => Self::Fup,
            "ln" => Self::Ln,
            "round" => Self::Round,
            "sin" => Self::Sin,
            "sqrt" => Self::Sqrt,
            "tan" => Self::Tan,
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

/// A reference to a parameter.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum ParamRef {
    /// `#<value>`: numbered (the value must be an integer 1..=5602).
    Numbered(Box<Expr>),
    /// `#<name>` (lower case, spaces removed).
    Named(String),
}

/// An expression tree.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Expr {
    Num(f64),
    Param(ParamRef),
    Neg(Box<Expr>),
    Func(Func, Box<Expr>),
    Atan(Box<Expr>, Box<Expr>),
    Exists(String),
    Bin(BinOp, Box<Expr>, Box<Expr>),
}

/// A subroutine frame's local parameters.
#[derive(Debug, Clone, Default)]
pub(crate) struct Frame {
    /// `#1..#30` of this call.
    pub(crate) locals: [f64; 30],
    /// Named locals (`#<name>` without a leading underscore).
    pub(crate) named: HashMap<String, f64>,
}

/// All parameters: numbered (global, except `#1..#30` inside a call), named locals, globals.
#[derive(Debug, Clone)]
pub(crate) struct Params {
    numbered: Vec<f64>,
    globals: HashMap<String, f64>,
    /// `frames[0]` is the main program's frame (its `#1..#30` live in `numbered`).
    pub(crate) frames: Vec<Frame>,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            numbered: vec![0.0; MAX_PARAMETER + 1],
            globals: HashMap::new(),
            frames: vec![Frame::default()],
        }
    }
}

/// Converts a value to a parameter index (must be within 0.0001 of an integer in 1..=5602).
pub(crate) fn param_index(v: f64) -> Result<usize, ErrorKind> {
    let r = v.round();
    if (v - r).abs() > 0.0001 || !(1.0..=MAX_PARAMETER as f64).contains(&r) {
        return Err(ErrorKind::ParameterOutOfRange(v));
    }
    // `r` is an integer in 1..=5602 here.
    Ok(r as usize)
}

impl Params {
    fn in_call(&self) -> bool {
        self.frames.len() > 1
    }

    /// Reads numbered parameter `idx` (1..=5602).
    pub(crate) fn get(&self, idx: usize) -> f64 {
        if self.in_call() && (1..=30).contains(&idx) {
            if let Some(f) = self.frames.last() {
                return f.locals.get(idx - 1).copied().unwrap_or(0.0);
            }
        }
        self.numbered.get(idx).copied().unwrap_or(0.0)
    }

    /// Writes numbered parameter `idx` (1..=5602).
    pub(crate) fn set(&mut self, idx: usize, v: f64) {
        let in_call = self.in_call();
        if in_call && (1..=30).contains(&idx) {
            if let Some(slot) = self.frames.last_mut().and_then(|f| f.locals.get_mut(idx - 1)) {
                *slot = v;
            }
            return;
        }
        if let Some(slot) = self.numbered.get_mut(idx) {
            *slot = v;
        }
    }

    /// Reads a named parameter.
    pub(crate) fn get_named(&self, name: &str) -> Option<f64> {
        if name.starts_with('_') {
            self.globals.get(name).copied()
        } else {
            self.frames.last().and_then(|f| f.named.get(name).copied())
        }
    }

    /// Writes a named parameter.
    pub(crate) fn set_named(&mut self, name: &str, v: f64) {
        if name.starts_with('_') {
            self.globals.insert(name.to_owned(), v);
        } else if let Some(f) = self.frames.last_mut() {
            f.named.insert(name.to_owned(), v);
        }
    }

    /// Evaluates an expression; errors carry no position (the caller adds it).
    pub(crate) fn eval(&self, e: &Expr) -> Result<f64, ErrorKind> {
        self.eval_depth(e, 0)
    }

    fn eval_depth(&self, e: &Expr, depth: u32) -> Result<f64, ErrorKind> {
        if depth > 200 {
            return Err(ErrorKind::BadExpression("nested too deeply"));
        }
        let d = depth + 1;
        match e {
            Expr::Num(v) => Ok(*v),
            Expr::Param(ParamRef::Numbered(ix)) => {
                let i = param_index(self.eval_depth(ix, d)?)?;
                Ok(self.get(i))
            }
            Expr::Param(ParamRef::Named(n)) => {
                self.get_named(n).ok_or_else(|| ErrorKind::UndefinedNamedParameter(n.clone()))
            }
            Expr::Neg(x) => Ok(-self.eval_depth(x, d)?),
            Expr::Func(f, x) => f.apply(self.eval_depth(x, d)?),
            Expr::Atan(a, b) => {
                let (a, b) = (self.eval_depth(a, d)?, self.eval_depth(b, d)?);
                Ok(a.atan2(b).to_degrees())
            }
            Expr::Exists(n) => Ok(if self.get_named(n).is_some() { 1.0 } else { 0.0 }),
            Expr::Bin(op, l, r) => {
                let l = self.eval_depth(l, d)?;
                let r = self.eval_depth(r, d)?;
                op.apply(l, r)
            }
        }
    }
}

/// Evaluates `e` and attaches `col` to an error.
pub(crate) fn eval_at(p: &Params, e: &Expr, col: u32) -> KResult<f64> {
    p.eval(e).map_err(|k| (col, k))
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
    fn locals_shadow_in_calls() {
        let mut p = Params::default();
        p.set(1, 5.0);
        p.frames.push(Frame::default());
        assert_eq!(p.get(1), 0.0);
        p.set(1, 7.0);
        p.set(31, 9.0);
        p.frames.pop();
        assert_eq!(p.get(1), 5.0);
        assert_eq!(p.get(31), 9.0);
    }
}
