//! Reading values from a normalised line (lower case, no spaces or comments): plain
//! numbers directly (the fast path), everything else (`[..]`, `#n`, `#<name>`, functions,
//! unary signs) compiled to postfix [`Op`]s with LinuxCNC's operator precedence.

use crate::error::{ErrorKind, KResult};
use crate::expr::{BinOp, Func, Op, Val};
use crate::params::param_index;

/// Exact powers of ten (all below 2^53 times a power of two, so exact in f64).
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18,
    1e19, 1e20, 1e21, 1e22,
];

/// `mantissa / 10^frac`, correctly rounded, for `mantissa < 2^53` (exact in f64) and
/// `frac <= 22` (exact powers of ten); `None` for a larger `frac`.
#[inline]
pub(crate) fn scale(mantissa: u64, frac: u32) -> Option<f64> {
    if frac == 0 {
        return Some(mantissa as f64);
    }
    POW10.get(frac as usize).map(|p| mantissa as f64 / p)
}

/// Deepest nesting of values (`[`, `#`, unary signs) in one word.
const MAX_DEPTH: u32 = 64;

/// A position in a normalised line, and where compiled instructions go.
pub(crate) struct Cursor<'a> {
    /// The normalised bytes.
    pub(crate) s: &'a [u8],
    /// 1-based source column of each byte of `s`.
    cols: &'a [u32],
    /// Index of the next byte.
    pub(crate) pos: usize,
    /// Column just after the last byte (for "missing value" errors).
    end_col: u32,
    ops: &'a mut Vec<Op>,
    /// Pending operators of the expressions being read (shared by nesting levels).
    opstack: &'a mut Vec<BinOp>,
}

impl<'a> Cursor<'a> {
    /// A cursor at the start of `s` (whose byte columns are `cols`), compiling into `ops`.
    pub(crate) fn new(
        s: &'a [u8],
        cols: &'a [u32],
        ops: &'a mut Vec<Op>,
        opstack: &'a mut Vec<BinOp>,
    ) -> Self {
        let end_col = cols.last().map_or(1, |c| c.saturating_add(1));
        opstack.clear();
        Self { s, cols, pos: 0, end_col, ops, opstack }
    }

    pub(crate) fn peek(&self) -> Option<u8> {
        self.s.get(self.pos).copied()
    }

    pub(crate) fn peek_at(&self, k: usize) -> Option<u8> {
        self.s.get(self.pos + k).copied()
    }

    /// Column of the next byte (or just after the end).
    pub(crate) fn col(&self) -> u32 {
        self.cols.get(self.pos).copied().unwrap_or(self.end_col)
    }

    pub(crate) fn bump(&mut self) {
        self.pos += 1;
    }

    pub(crate) fn eat(&mut self, c: u8) -> bool {
        if self.peek() == Some(c) {
            self.pos += 1;
            true
        } else {
            false
        }
    }

    fn eat_str(&mut self, s: &[u8]) -> bool {
        let ok = self.s.get(self.pos..).is_some_and(|rest| rest.starts_with(s));
        if ok {
            self.pos += s.len();
        }
        ok
    }

    /// Reads letters; returns their byte range.
    pub(crate) fn alpha_run(&mut self) -> (usize, usize) {
        let start = self.pos;
        while self.peek().is_some_and(|c| c.is_ascii_alphabetic()) {
            self.bump();
        }
        (start, self.pos)
    }

    /// Reads bytes up to `stop` (not consumed); `None` if the line ends first.
    pub(crate) fn until(&mut self, stop: u8) -> Option<(usize, usize)> {
        let start = self.pos;
        let len = self.s.get(start..)?.iter().position(|&c| c == stop)?;
        self.pos = start + len;
        Some((start, self.pos))
    }

    fn text(&self, (a, b): (usize, usize)) -> &'a [u8] {
        self.s.get(a..b).unwrap_or(&[])
    }

    fn push(&mut self, op: Op) {
        self.ops.push(op);
    }

    /// Number of instructions compiled so far.
    fn op_count(&self) -> u32 {
        u32::try_from(self.ops.len()).unwrap_or(u32::MAX)
    }

    /// An unsigned or signed decimal number (`after` names the word, for errors).
    #[inline(always)]
    pub(crate) fn number(&mut self, after: u8) -> KResult<f64> {
        let start = self.pos;
        let col = self.col();
        let mut neg = false;
        if let Some(c @ (b'+' | b'-')) = self.peek() {
            neg = c == b'-';
            self.bump();
        }
        // Exact fast path (Clinger): an integer mantissa below 2^53 divided by an exact
        // power of ten is correctly rounded, the same result as `str::parse`.
        let mut mantissa: u64 = 0;
        let mut digits = 0u32;
        let mut frac = 0u32;
        let mut dot = false;
        let mut slow = false;
        while let Some(c) = self.peek() {
            if c.is_ascii_digit() {
                digits += 1;
                if dot {
                    frac += 1;
                }
                match mantissa.checked_mul(10).and_then(|m| m.checked_add(u64::from(c - b'0'))) {
                    Some(m) if m < (1 << 53) => mantissa = m,
                    _ => slow = true,
                }
            } else if c == b'.' && !dot {
                dot = true;
            } else {
                break;
            }
            self.bump();
        }
        if digits == 0 {
            self.pos = start;
            if self.peek().is_none() {
                return Err((col, ErrorKind::MissingValue(char::from(after))));
            }
            return Err((col, ErrorKind::BadNumber));
        }
        match scale(mantissa, frac) {
            Some(v) if !slow => Ok(if neg { -v } else { v }),
            _ => std::str::from_utf8(self.text((start, self.pos)))
                .ok()
                .and_then(|t| t.parse::<f64>().ok())
                .ok_or((col, ErrorKind::BadNumber)),
        }
    }

    /// A value: number, `[expression]`, `#parameter`, `function[..]` or a signed one of those.
    #[inline(always)]
    pub(crate) fn value(&mut self, after: u8) -> KResult<Val> {
        match self.peek() {
            Some(b'0'..=b'9' | b'.') => return Ok(Val::Num(self.number(after)?)),
            Some(b'-' | b'+') if matches!(self.peek_at(1), Some(b'0'..=b'9' | b'.')) => {
                return Ok(Val::Num(self.number(after)?));
            }
            _ => {}
        }
        let start = self.op_count();
        self.value_depth(after, 0)?;
        self.finish(start)
    }

    /// The value compiled since instruction `start` (a lone number is kept as a number).
    fn finish(&mut self, start: u32) -> KResult<Val> {
        let end = self.op_count();
        if end == start.saturating_add(1) {
            if let Some(&Op::Num(v)) = self.ops.last() {
                self.ops.pop();
                return Ok(Val::Num(v));
            }
        }
        Ok(Val::Code(start, end))
    }

    /// After `#` at line level: `<name>` (its byte range) or a value giving the number.
    pub(crate) fn param_target(&mut self) -> KResult<Result<Val, (u32, u32)>> {
        if self.peek() == Some(b'<') {
            return self.param_name().map(Err);
        }
        self.value(b'#').map(Ok)
    }

    /// `<name>`: the byte range of the name.
    fn param_name(&mut self) -> KResult<(u32, u32)> {
        self.bump();
        let Some((a, b)) = self.until(b'>') else {
            self.pos = self.s.len();
            return Err((self.col(), ErrorKind::BadExpression("unclosed #<name>")));
        };
        self.bump();
        if a == b {
            return Err((self.col(), ErrorKind::BadExpression("empty parameter name")));
        }
        Ok((u32::try_from(a).unwrap_or(u32::MAX), u32::try_from(b).unwrap_or(u32::MAX)))
    }

    fn value_depth(&mut self, after: u8, depth: u32) -> KResult<()> {
        if depth > MAX_DEPTH {
            return Err((self.col(), ErrorKind::BadExpression("nested too deeply")));
        }
        let col = self.col();
        match self.peek() {
            None => Err((col, ErrorKind::MissingValue(char::from(after.to_ascii_uppercase())))),
            Some(b'[') => {
                self.bump();
                self.expression(depth + 1)
            }
            Some(b'#') => {
                self.bump();
                if depth > MAX_DEPTH / 2 {
                    return Err((col, ErrorKind::BadExpression("nested too deeply")));
                }
                if self.peek() == Some(b'<') {
                    let (a, b) = self.param_name()?;
                    self.push(Op::Named(a, b));
                } else {
                    let start = self.ops.len();
                    self.value_depth(b'#', depth + 1)?;
                    // `#<literal>`: check the number now (same result as at run time).
                    if let Some(&[Op::Num(v)]) = self.ops.get(start..) {
                        if let Ok(i) = param_index(v) {
                            self.ops.truncate(start);
                            self.push(Op::ParamAt(i));
                            return Ok(());
                        }
                    }
                    self.push(Op::Param);
                }
                Ok(())
            }
            Some(c @ (b'-' | b'+')) if !matches!(self.peek_at(1), Some(b'0'..=b'9' | b'.')) => {
                self.bump();
                self.value_depth(after, depth + 1)?;
                if c == b'-' {
                    self.push(Op::Neg);
                }
                Ok(())
            }
            Some(c) if c.is_ascii_alphabetic() => self.function(col, depth),
            Some(_) => {
                let v = self.number(after)?;
                self.push(Op::Num(v));
                Ok(())
            }
        }
    }

    /// `EXISTS[#<name>]`, `ATAN[a]/[b]` or `function[a]`.
    fn function(&mut self, col: u32, depth: u32) -> KResult<()> {
        let name = self.alpha_run();
        match self.text(name) {
            b"exists" => {
                if !(self.eat(b'[') && self.eat(b'#') && self.eat(b'<')) {
                    return Err((col, ErrorKind::BadExpression("EXISTS[#<name>] expected")));
                }
                let (a, b) = self.until(b'>').unwrap_or((self.pos, self.s.len()));
                self.pos = b;
                if !(self.eat(b'>') && self.eat(b']')) {
                    return Err((col, ErrorKind::BadExpression("EXISTS[#<name>] expected")));
                }
                let r = |x: usize| u32::try_from(x).unwrap_or(u32::MAX);
                self.push(Op::Exists(r(a), r(b)));
            }
            b"atan" => {
                if !self.eat(b'[') {
                    return Err((self.col(), ErrorKind::BadExpression("'[' expected after ATAN")));
                }
                self.expression(depth + 1)?;
                if !(self.eat(b'/') && self.eat(b'[')) {
                    return Err((self.col(), ErrorKind::BadExpression("ATAN[a]/[b] expected")));
                }
                self.expression(depth + 1)?;
                self.push(Op::Atan);
            }
            n => {
                let f = Func::from_name(n).ok_or_else(|| {
                    (col, ErrorKind::UnknownOperation(String::from_utf8_lossy(n).into_owned()))
                })?;
                if !self.eat(b'[') {
                    return Err((self.col(), ErrorKind::BadExpression("'[' expected after function")));
                }
                self.expression(depth + 1)?;
                self.push(Op::Func(f));
            }
        }
        Ok(())
    }

    /// A binary operator, or `None` at the closing `]`.
    fn operator(&mut self) -> KResult<Option<BinOp>> {
        let col = self.col();
        let op = match self.peek() {
            Some(b']') => {
                self.bump();
                return Ok(None);
            }
            None => return Err((col, ErrorKind::BadExpression("unclosed '['"))),
            Some(b'*') => {
                if self.eat_str(b"**") {
                    return Ok(Some(BinOp::Pow));
                }
                BinOp::Mul
            }
            Some(b'/') => BinOp::Div,
            Some(b'+') => BinOp::Add,
            Some(b'-') => BinOp::Sub,
            Some(other) => {
                const WORDS: [(&[u8], BinOp); 10] = [
                    (b"mod", BinOp::Mod),
                    (b"eq", BinOp::Eq),
                    (b"ne", BinOp::Ne),
                    (b"gt", BinOp::Gt),
                    (b"ge", BinOp::Ge),
                    (b"lt", BinOp::Lt),
                    (b"le", BinOp::Le),
                    (b"and", BinOp::And),
                    (b"or", BinOp::Or),
                    (b"xor", BinOp::Xor),
                ];
                for (s, op) in WORDS {
                    if self.eat_str(s) {
                        return Ok(Some(op));
                    }
                }
                return Err((col, ErrorKind::UnknownOperation(char::from(other).to_string())));
            }
        };
        self.bump();
        Ok(Some(op))
    }

    /// After `[`: values and operators up to the matching `]`, with LinuxCNC's precedence
    /// (left to right within one level). Operators are emitted as they are reduced, which
    /// gives the postfix order of the equivalent tree.
    fn expression(&mut self, depth: u32) -> KResult<()> {
        let base = self.opstack.len();
        self.value_depth(b'[', depth)?;
        loop {
            let next = self.operator()?;
            // Reduce while the stacked operator binds at least as tightly as the next one.
            while self.opstack.len() > base {
                let Some(&top) = self.opstack.last() else { break };
                if next.is_some_and(|n| n.precedence() > top.precedence()) {
                    break;
                }
                self.opstack.pop();
                self.push(Op::Bin(top));
            }
            match next {
                None => return Ok(()),
                Some(op) => {
                    self.opstack.push(op);
                    self.value_depth(b'[', depth)?;
                }
            }
        }
    }
}
