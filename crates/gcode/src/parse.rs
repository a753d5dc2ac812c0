//! Line parser: one program line into its N number, O-word, words, parameter assignments,
//! `EX` external-parameter writes and comments, each with its 1-based column.
//!
//! Like LinuxCNC, spaces and tabs outside comments are ignored everywhere (`X 1 .5` is
//! `X1.5`) and letters are case-insensitive. `(...)` is a comment (a `(` inside it is the
//! error "Nested comment found"), `;` starts a comment running to the end of the line,
//! `(MSG,text)` is a message. A line holding only `%` is a program delimiter.

use crate::error::{ErrorKind, KResult};
use crate::expr::{BinOp, Expr, Func, ParamRef};

/// A word: letter and value expression (evaluated when the block is read).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Word {
    pub(crate) letter: u8,
    pub(crate) value: Expr,
    pub(crate) col: u32,
}

/// `#target=value`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Assign {
    pub(crate) target: ParamRef,
    pub(crate) value: Expr,
    pub(crate) col: u32,
}

/// `EX<array><index>=value`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ExWrite {
    pub(crate) array: u8,
    pub(crate) index: u8,
    pub(crate) value: Expr,
    pub(crate) col: u32,
}

/// O-word keywords.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum OKind {
    Sub,
    EndSub,
    Call,
    Return,
    If,
    ElseIf,
    Else,
    EndIf,
    While,
    EndWhile,
    Do,
    Break,
    Continue,
}

/// An O-word line (`o100 if [#1 GT 2]`, `o<name> call [1] [2]`).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct OWord {
    pub(crate) name: String,
    pub(crate) kind: OKind,
    /// Condition (if/elseif/while) or return value, or call arguments.
    pub(crate) args: Vec<Expr>,
    pub(crate) col: u32,
}

/// The comment executed with a block (LinuxCNC executes only the last one of a line).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Remark {
    Comment(String),
    Message(String),
}

/// One parsed program line.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Line {
    pub(crate) block_delete: bool,
    pub(crate) percent: bool,
    pub(crate) n: Option<u32>,
    pub(crate) oword: Option<OWord>,
    pub(crate) words: Vec<Word>,
    pub(crate) assigns: Vec<Assign>,
    pub(crate) ex: Vec<ExWrite>,
    pub(crate) remark: Option<Remark>,
}

struct Cursor {
    chars: Vec<(u8, u32)>,
    pos: usize,
    end_col: u32,
}

impl Cursor {
    fn peek(&self) -> Option<u8> {
        self.chars.get(self.pos).map(|c| c.0)
    }
    fn peek_at(&self, k: usize) -> Option<u8> {
        self.chars.get(self.pos + k).map(|c| c.0)
    }
    fn col(&self) -> u32 {
        self.chars.get(self.pos).map_or(self.end_col, |c| c.1)
    }
    fn bump(&mut self) {
        self.pos += 1;
    }
    fn eat(&mut self, c: u8) -> bool {
        if self.peek() == Some(c) {
            self.pos += 1;
            true
        } else {
            false
        }
    }
    fn eat_str(&mut self, s: &str) -> bool {
        let ok = s.bytes().enumerate().all(|(k, b)| self.peek_at(k) == Some(b));
        if ok {
            self.pos += s.len();
        }
        ok
    }
    fn alpha_run(&mut self) -> String {
        let mut s = String::new();
        while let Some(c) = self.peek().filter(u8::is_ascii_alphabetic) {
            s.push(char::from(c));
            self.bump();
        }
        s
    }
}

/// Parses one line (`text` without its line terminator).
pub(crate) fn parse_line(text: &str) -> KResult<Line> {
    let mut line = Line::default();
    if text.trim() == "%" {
        line.percent = true;
        return Ok(line);
    }
    let mut chars = Vec::with_capacity(text.len());
    let mut it = text.chars().zip(1u32..).peekable();
    let mut first = true;
    while let Some((c, col)) = it.next() {
        match c {
            ' ' | '\t' | '\r' => {}
            '/' if first => line.block_delete = true,
            ';' => break,
            '(' => {
                let mut body = String::new();
                let mut closed = false;
                for (c2, col2) in it.by_ref() {
                    match c2 {
                        ')' => {
                            closed = true;
                            break;
                        }
                        '(' => return Err((col2, ErrorKind::NestedComment)),
                        _ => body.push(c2),
                    }
                }
                if !closed {
                    return Err((col, ErrorKind::UnclosedComment));
                }
                line.remark = Some(remark(body));
            }
            c if c.is_ascii() => {
                // ASCII, so the cast is exact.
                chars.push((c.to_ascii_lowercase() as u8, col));
            }
            other => return Err((col, ErrorKind::BadCharacter(other))),
        }
        if c != ' ' && c != '\t' {
            first = false;
        }
    }
    let end_col = chars.last().map_or(1, |c: &(u8, u32)| c.1.saturating_add(1));
    let mut cur = Cursor { chars, pos: 0, end_col };
    if cur.peek() == Some(b'n') {
        let col = cur.col();
        cur.bump();
        let v = read_number(&mut cur, b'n')?;
        if v < 0.0 || v.fract() != 0.0 || v > f64::from(u32::MAX) {
            return Err((col, ErrorKind::BadNumber));
        }
        // Non-negative integer below 2^32: exact.
        line.n = Some(v as u32);
    }
    if cur.peek() == Some(b'o') {
        line.oword = Some(read_oword(&mut cur)?);
        if cur.peek().is_some() {
            return Err((cur.col(), ErrorKind::OWord("unexpected text after O-word".into())));
        }
        return Ok(line);
    }
    while let Some(c) = cur.peek() {
        let col = cur.col();
        if c == b'#' {
            cur.bump();
            let target = read_param_ref(&mut cur)?;
            if !cur.eat(b'=') {
                return Err((cur.col(), ErrorKind::BadExpression("'=' expected")));
            }
            let value = read_real_value(&mut cur, b'=')?;
            line.assigns.push(Assign { target, value, col });
        } else if c == b'e' && cur.peek_at(1) == Some(b'x') {
            cur.pos += 2;
            line.ex.push(read_ex(&mut cur, col)?);
        } else if c.is_ascii_alphabetic() {
            cur.bump();
            let value = read_real_value(&mut cur, c.to_ascii_uppercase())?;
            line.words.push(Word { letter: c.to_ascii_uppercase(), value, col });
        } else {
            return Err((col, ErrorKind::BadCharacter(char::from(c))));
        }
    }
    Ok(line)
}

fn remark(body: String) -> Remark {
    let t = body.trim_start();
    if t.len() >= 4 && t.get(..4).is_some_and(|p| p.eq_ignore_ascii_case("msg,")) {
        Remark::Message(t.get(4..).unwrap_or("").to_owned())
    } else {
        Remark::Comment(body)
    }
}

fn read_ex(cur: &mut Cursor, col: u32) -> KResult<ExWrite> {
    let array = match cur.peek() {
        Some(a @ (b'b' | b'w' | b'l' | b'f')) => a.to_ascii_uppercase(),
        _ => return Err((cur.col(), ErrorKind::BadExternal("array letter B, W, L or F expected"))),
    };
    cur.bump();
    let mut index: u32 = 0;
    let mut digits = 0;
    while let Some(d) = cur.peek().filter(u8::is_ascii_digit) {
        index = index * 10 + u32::from(d - b'0');
        digits += 1;
        cur.bump();
        if index > 99 {
            return Err((col, ErrorKind::BadExternal("index must be 0..=99")));
        }
    }
    if digits == 0 {
        return Err((cur.col(), ErrorKind::BadExternal("index expected")));
    }
    if !cur.eat(b'=') {
        return Err((cur.col(), ErrorKind::BadExternal("'=' expected")));
    }
    let value = read_real_value(cur, b'=')?;
    Ok(ExWrite { array, index: u8::try_from(index).unwrap_or(0), value, col })
}

fn read_oword(cur: &mut Cursor) -> KResult<OWord> {
    let col = cur.col();
    cur.bump();
    let name = if cur.eat(b'<') {
        let mut n = String::from("<");
        loop {
            match cur.peek() {
                Some(b'>') => {
                    cur.bump();
                    break;
                }
                Some(c) => {
                    n.push(char::from(c));
                    cur.bump();
                }
                None => return Err((cur.col(), ErrorKind::OWord("unclosed O-word name".into()))),
            }
        }
        n.push('>');
        n
    } else {
        let mut n = String::new();
        while let Some(d) = cur.peek().filter(u8::is_ascii_digit) {
            n.push(char::from(d));
            cur.bump();
        }
        if n.is_empty() {
            return Err((cur.col(), ErrorKind::OWord("O-word number or <name> expected".into())));
        }
        // o0100 and o100 are the same.
        let t = n.trim_start_matches('0');
        if t.is_empty() {
            "0".to_owned()
        } else {
            t.to_owned()
        }
    };
    let kcol = cur.col();
    let kw = cur.alpha_run();
    let kind = match kw.as_str() {
        "sub" => OKind::Sub,
        "endsub" => OKind::EndSub,
        "call" => OKind::Call,
        "return" => OKind::Return,
        "if" => OKind::If,
        "elseif" => OKind::ElseIf,
        "else" => OKind::Else,
        "endif" => OKind::EndIf,
        "while" => OKind::While,
        "endwhile" => OKind::EndWhile,
        "do" => OKind::Do,
        "break" => OKind::Break,
        "continue" => OKind::Continue,
        _ => return Err((kcol, ErrorKind::OWord(format!("unknown O-word keyword '{kw}'")))),
    };
    let mut args = Vec::new();
    match kind {
        OKind::If | OKind::ElseIf | OKind::While => {
            if cur.peek() != Some(b'[') {
                return Err((cur.col(), ErrorKind::OWord(format!("[condition] expected after {kw}"))));
            }
            args.push(read_real_value(cur, b'o')?);
        }
        OKind::Call | OKind::Return | OKind::EndSub => {
            while cur.peek().is_some() {
                args.push(read_real_value(cur, b'o')?);
            }
            if kind != OKind::Call && args.len() > 1 {
                return Err((kcol, ErrorKind::OWord("one return value at most".into())));
            }
        }
        _ => {}
    }
    Ok(OWord { name, kind, args, col })
}

/// After `#`: `<name>` or a value giving the number.
fn read_param_ref(cur: &mut Cursor) -> KResult<ParamRef> {
    if cur.eat(b'<') {
        let mut n = String::new();
        loop {
            match cur.peek() {
                Some(b'>') => {
                    cur.bump();
                    break;
                }
                Some(c) => {
                    n.push(char::from(c));
                    cur.bump();
                }
                None => return Err((cur.col(), ErrorKind::BadExpression("unclosed #<name>"))),
            }
        }
        if n.is_empty() {
            return Err((cur.col(), ErrorKind::BadExpression("empty parameter name")));
        }
        return Ok(ParamRef::Named(n));
    }
    Ok(ParamRef::Numbered(Box::new(read_real_value(cur, b'#')?)))
}

fn read_number(cur: &mut Cursor, after: u8) -> KResult<f64> {
    let start = cur.pos;
    let col = cur.col();
    let mut neg = false;
    if let Some(c @ (b'+' | b'-')) = cur.peek() {
        neg = c == b'-';
        cur.bump();
    }
    // Exact fast path (Clinger): an integer mantissa below 2^53 divided by an exact power
    // of ten is correctly rounded, the same result as `str::parse`.
    let mut mantissa: u64 = 0;
    let mut digits = 0u32;
    let mut frac = 0u32;
    let mut dot = false;
    let mut slow = false;
    while let Some(c) = cur.peek() {
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
        cur.bump();
    }
    if digits == 0 {
        cur.pos = start;
        if cur.peek().is_none() {
            return Err((col, ErrorKind::MissingValue(char::from(after))));
        }
        return Err((col, ErrorKind::BadNumber));
    }
    const POW10: [f64; 23] = [
        1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17,
        1e18, 1e19, 1e20, 1e21, 1e22,
    ];
    let v = match POW10.get(frac as usize) {
        // mantissa < 2^53: exact in f64.
        Some(p) if !slow => mantissa as f64 / p,
        _ => {
            let s: String =
                cur.chars.get(start..cur.pos).unwrap_or(&[]).iter().map(|c| char::from(c.0)).collect();
            return s.parse::<f64>().map_err(|_| (col, ErrorKind::BadNumber));
        }
    };
    Ok(if neg { -v } else { v })
}

/// A value: number, `[expression]`, `#parameter`, `function[..]` or a signed one of those.
fn read_real_value(cur: &mut Cursor, after: u8) -> KResult<Expr> {
    read_value_depth(cur, after, 0)
}

fn read_value_depth(cur: &mut Cursor, after: u8, depth: u32) -> KResult<Expr> {
    if depth > 64 {
        return Err((cur.col(), ErrorKind::BadExpression("nested too deeply")));
    }
    let col = cur.col();
    match cur.peek() {
        None => Err((col, ErrorKind::MissingValue(char::from(after.to_ascii_uppercase())))),
        Some(b'[') => {
            cur.bump();
            let e = read_expression(cur, depth + 1)?;
            Ok(e)
        }
        Some(b'#') => {
            cur.bump();
            if depth > 32 {
                return Err((col, ErrorKind::BadExpression("nested too deeply")));
            }
            Ok(Expr::Param(read_param_ref_depth(cur, depth + 1)?))
        }
        Some(b'-' | b'+') if !matches!(cur.peek_at(1), Some(b'0'..=b'9' | b'.')) => {
            let neg = cur.peek() == Some(b'-');
            cur.bump();
            let v = read_value_depth(cur, after, depth + 1)?;
            Ok(if neg { Expr::Neg(Box::new(v)) } else { v })
        }
        Some(c) if c.is_ascii_alphabetic() => {
            let name = cur.alpha_run();
            if name == "exists" {
                if !(cur.eat(b'[') && cur.eat(b'#') && cur.eat(b'<')) {
                    return Err((col, ErrorKind::BadExpression("EXISTS[#<name>] expected")));
                }
                let mut n = String::new();
                while let Some(c) = cur.peek().filter(|&c| c != b'>') {
                    n.push(char::from(c));
                    cur.bump();
                }
                if !(cur.eat(b'>') && cur.eat(b']')) {
                    return Err((col, ErrorKind::BadExpression("EXISTS[#<name>] expected")));
                }
                return Ok(Expr::Exists(n));
            }
            if name == "atan" {
                if !cur.eat(b'[') {
                    return Err((cur.col(), ErrorKind::BadExpression("'[' expected after ATAN")));
                }
                let a = read_expression(cur, depth + 1)?;
                if !(cur.eat(b'/') && cur.eat(b'[')) {
                    return Err((cur.col(), ErrorKind::BadExpression("ATAN[a]/[b] expected")));
                }
                let b = read_expression(cur, depth + 1)?;
                return Ok(Expr::Atan(Box::new(a), Box::new(b)));
            }
            let f = Func::from_name(&name).ok_or((col, ErrorKind::UnknownOperation(name)))?;
            if !cur.eat(b'[') {
                return Err((cur.col(), ErrorKind::BadExpression("'[' expected after function")));
            }
            let a = read_expression(cur, depth + 1)?;
            Ok(Expr::Func(f, Box::new(a)))
        }
        Some(_) => Ok(Expr::Num(read_number(cur, after)?)),
    }
}

fn read_param_ref_depth(cur: &mut Cursor, depth: u32) -> KResult<ParamRef> {
    if cur.peek() == Some(b'<') {
        return read_param_ref(cur);
    }
    Ok(ParamRef::Numbered(Box::new(read_value_depth(cur, b'#', depth)?)))
}

fn read_op(cur: &mut Cursor) -> KResult<Option<BinOp>> {
    let col = cur.col();
    let op = match cur.peek() {
        Some(b']') => {
            cur.bump();
            return Ok(None);
        }
        None => return Err((col, ErrorKind::BadExpression("unclosed '['"))),
        Some(b'*') => {
            if cur.eat_str("**") {
                return Ok(Some(BinOp::Pow));
            }
            BinOp::Mul
        }
        Some(b'/') => BinOp::Div,
        Some(b'+') => BinOp::Add,
        Some(b'-') => BinOp::Sub,
        Some(_) => {
            let table = [
                ("mod", BinOp::Mod),
                ("eq", BinOp::Eq),
                ("ne", BinOp::Ne),
                ("gt", BinOp::Gt),
                ("ge", BinOp::Ge),
                ("lt", BinOp::Lt),
                ("le", BinOp::Le),
                ("and", BinOp::And),
                ("or", BinOp::Or),
                ("xor", BinOp::Xor),
            ];
            for (s, op) in table {
                if cur.eat_str(s) {
                    return Ok(Some(op));
                }
            }
            return Err((
                col,
                ErrorKind::UnknownOperation(char::from(cur.peek().unwrap_or(b'?')).to_string()),
            ));
        }
    };
    cur.bump();
    Ok(Some(op))
}

/// After `[`: values and operators up to the matching `]`, with LinuxCNC's precedence
/// (left to right within one level).
fn read_expression(cur: &mut Cursor, depth: u32) -> KResult<Expr> {
    let mut values = vec![read_value_depth(cur, b'[', depth)?];
    let mut ops: Vec<BinOp> = Vec::new();
    loop {
        let next = read_op(cur)?;
        // Reduce while the stacked operator binds at least as tightly as the next one.
        while let Some(&top) = ops.last() {
            if next.is_some_and(|n| n.precedence() > top.precedence()) {
                break;
            }
            ops.pop();
            let r = values.pop();
            let l = values.pop();
            match (l, r) {
                (Some(l), Some(r)) => values.push(Expr::Bin(top, Box::new(l), Box::new(r))),
                _ => return Err((cur.col(), ErrorKind::BadExpression("operand missing"))),
            }
        }
        match next {
            None => break,
            Some(op) => {
                ops.push(op);
                values.push(read_value_depth(cur, b'[', depth)?);
            }
        }
    }
    values.pop().ok_or((cur.col(), ErrorKind::BadExpression("empty expression")))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use crate::expr::Params;

    fn val(s: &str) -> f64 {
        let l = parse_line(&format!("X{s}")).unwrap();
        Params::default().eval(&l.words[0].value).unwrap()
    }

    #[test]
    fn precedence_and_functions() {
        // Values worked out by hand with LinuxCNC's precedence table.
        assert_eq!(val("[1 + 2 * 3]"), 7.0);
        assert_eq!(val("[2 ** 3 ** 2]"), 64.0);
        assert_eq!(val("[10 - 4 - 3]"), 3.0);
        assert_eq!(val("[1 + 1 EQ 2]"), 1.0);
        assert_eq!(val("[1 LT 2 AND 3 GT 4]"), 0.0);
        assert_eq!(val("[7 MOD 4]"), 3.0);
        assert!((val("[sin[30]]") - 0.5).abs() < 1e-15);
        assert!((val("atan[1]/[1]") - 45.0).abs() < 1e-12);
        assert_eq!(val("[fix[-1.5]]"), -2.0);
        assert_eq!(val("[fup[1.2]]"), 2.0);
        assert_eq!(val("[round[2.5]]"), 3.0);
        assert_eq!(val("-1.5"), -1.5);
        assert_eq!(val(".5"), 0.5);
    }

    #[test]
    fn comments_and_columns() {
        assert_eq!(parse_line("G1 (a (b))").unwrap_err(), (7, ErrorKind::NestedComment));
        let l = parse_line("n10 g1 x 1 (msg,hi) ; rest").unwrap();
        assert_eq!(l.n, Some(10));
        assert_eq!(l.words[1].col, 8);
        assert_eq!(l.remark, Some(Remark::Message("hi".into())));
    }

    #[test]
    fn ex_and_owords() {
        let l = parse_line("EXW60=3600 exf61=[1/2]").unwrap();
        assert_eq!(l.ex.len(), 2);
        assert_eq!((l.ex[0].array, l.ex[0].index), (b'W', 60));
        let o = parse_line("o<foo> call [1] [2]").unwrap().oword.unwrap();
        assert_eq!((o.name.as_str(), o.kind, o.args.len()), ("<foo>", OKind::Call, 2));
    }
}
