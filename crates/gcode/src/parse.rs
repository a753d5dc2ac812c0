//! Line parser: one program line into its N number, O-word, words, parameter assignments,
//! `EX` external-parameter writes and comment, each with its 1-based column.
//!
//! Like LinuxCNC, spaces and tabs outside comments are ignored everywhere (`X 1 .5` is
//! `X1.5`) and letters are case-insensitive. `(...)` is a comment (a `(` inside it is the
//! error "Nested comment found"), `;` starts a comment running to the end of the line,
//! `(MSG,text)` is a message. A line holding only `%` is a program delimiter.
//!
//! The line is first normalised into reused buffers (lower case, without spaces, tabs and
//! comments, with each byte's column), then read word by word: plain numbers directly,
//! other values compiled to postfix instructions (see `value.rs`). Once the buffers have
//! grown, parsing a line allocates nothing (O-word names and error messages aside).

use crate::error::{ErrorKind, KResult};
use crate::expr::{self, BinOp, Op, Val};
use crate::params::Params;
use crate::value::Cursor;

mod lex;

/// A word: letter and value (evaluated when the block is read).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Word {
    pub(crate) letter: u8,
    pub(crate) value: Val,
    pub(crate) col: u32,
}

/// The parameter written by `#target=value`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Target {
    /// `#<value>=`: the value gives the number.
    Numbered(Val),
    /// `#<name>=`: byte range of the name in the normalised line.
    Named(u32, u32),
}

/// `#target=value`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Assign {
    pub(crate) target: Target,
    pub(crate) value: Val,
    pub(crate) col: u32,
}

/// `EX<array><index>=value`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ExWrite {
    pub(crate) array: u8,
    pub(crate) index: u8,
    pub(crate) value: Val,
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
    /// `o100 repeat [n]`: the lines up to `o100 endrepeat`, n times.
    Repeat,
    EndRepeat,
    /// An O-word alone (`O1234`, a program number heading the file): nothing to do.
    Heading,
}

/// An O-word line (`o100 if [#1 GT 2]`, `o<name> call [1] [2]`).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct OWord {
    pub(crate) name: String,
    pub(crate) kind: OKind,
    /// Condition (if/elseif/while) or return value, or call arguments.
    pub(crate) args: Vec<Val>,
    pub(crate) col: u32,
}

/// The comment executed with a block (LinuxCNC executes only the last one of a line).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Remark<'a> {
    Comment(&'a str),
    Message(&'a str),
    /// `(DEBUG,text)`: a message with the parameters in `text` substituted.
    Debug(&'a str),
    /// `(PRINT,text)`: printed with the parameters in `text` substituted.
    Print(&'a str),
}

/// One parsed program line (its buffers are reused from line to line).
#[derive(Debug, Clone, Default)]
pub(crate) struct Line {
    pub(crate) block_delete: bool,
    pub(crate) percent: bool,
    pub(crate) n: Option<u32>,
    pub(crate) oword: Option<OWord>,
    pub(crate) words: Vec<Word>,
    pub(crate) assigns: Vec<Assign>,
    pub(crate) ex: Vec<ExWrite>,
    /// Byte range, in the source text, of the body of the line's last `(...)` comment.
    comment: Option<(usize, usize)>,
    /// The normalised line (ASCII, lower case, no spaces, tabs or comments).
    norm: Vec<u8>,
    /// 1-based source column (in characters) of each byte of `norm`.
    cols: Vec<u32>,
    /// Compiled values (ranges of it are referenced by [`Val::Code`]).
    ops: Vec<Op>,
    /// Scratch operator stack of the expression compiler.
    opstack: Vec<BinOp>,
}

/// Parses one line (`text` without its line terminator) into a new [`Line`].
pub(crate) fn parse_line(text: &str) -> KResult<Line> {
    let mut line = Line::default();
    line.parse(text)?;
    Ok(line)
}

impl Line {
    /// Does the line hold anything besides its N number (words, comment, O-word...)?
    pub(crate) fn has_content(&self) -> bool {
        self.oword.is_some()
            || !self.words.is_empty()
            || !self.assigns.is_empty()
            || !self.ex.is_empty()
            || self.comment.is_some()
    }

    /// The comment or message of the line (`text` is the line it was parsed from).
    #[inline]
    pub(crate) fn remark<'t>(&self, text: &'t str) -> Option<Remark<'t>> {
        let body = self.comment.and_then(|(a, b)| text.get(a..b))?;
        let t = body.trim_start();
        let keyword = |k: &str| t.get(..k.len()).is_some_and(|p| p.eq_ignore_ascii_case(k));
        Some(if keyword("msg,") {
            Remark::Message(t.get(4..).unwrap_or(""))
        } else if keyword("debug,") {
            Remark::Debug(t.get(6..).unwrap_or(""))
        } else if keyword("print,") {
            Remark::Print(t.get(6..).unwrap_or(""))
        } else {
            Remark::Comment(body)
        })
    }

    /// The parameter name of a [`Target::Named`].
    pub(crate) fn name(&self, start: u32, end: u32) -> &str {
        expr::name(&self.norm, start, end)
    }

    /// Evaluates a value of this line; errors are placed at `col`.
    #[inline]
    pub(crate) fn eval(&self, params: &Params, stack: &mut Vec<f64>, v: Val, col: u32) -> KResult<f64> {
        match v {
            Val::Num(x) => Ok(x),
            Val::Code(a, b) => {
                let ops = self.ops.get(a as usize..b as usize).unwrap_or(&[]);
                expr::run(params, stack, ops, &self.norm).map_err(|k| (col, k))
            }
        }
    }

    /// Parses `text` (without its line terminator) into this line, reusing its buffers.
    pub(crate) fn parse(&mut self, text: &str) -> KResult<()> {
        self.block_delete = false;
        self.percent = false;
        self.n = None;
        self.oword = None;
        self.words.clear();
        self.assigns.clear();
        self.ex.clear();
        self.comment = None;
        self.ops.clear();
        if self.parse_plain(text) {
            return Ok(());
        }
        self.parse_general(text)
    }

    /// The general path of [`Line::parse`] (`ops` must be empty).
    fn parse_general(&mut self, text: &str) -> KResult<()> {
        self.n = None;
        self.words.clear();
        if text.trim() == "%" {
            self.percent = true;
            return Ok(());
        }
        self.normalize(text)?;
        let mut cur = Cursor::new(&self.norm, &self.cols, &mut self.ops, &mut self.opstack);
        if cur.peek() == Some(b'n') {
            let col = cur.col();
            cur.bump();
            let v = cur.number(b'n')?;
            if v < 0.0 || v.fract() != 0.0 || v > f64::from(u32::MAX) {
                return Err((col, ErrorKind::BadNumber));
            }
            // Non-negative integer below 2^32: exact.
            self.n = Some(v as u32);
        }
        if cur.peek() == Some(b'o') {
            self.oword = Some(read_oword(&mut cur)?);
            if cur.peek().is_some() {
                return Err((cur.col(), ErrorKind::OWord("unexpected text after O-word".into())));
            }
            return Ok(());
        }
        while let Some(c) = cur.peek() {
            let col = cur.col();
            if c == b'#' {
                cur.bump();
                let target = match cur.param_target()? {
                    Ok(v) => Target::Numbered(v),
                    Err((a, b)) => Target::Named(a, b),
                };
                if !cur.eat(b'=') {
                    return Err((cur.col(), ErrorKind::BadExpression("'=' expected")));
                }
                let value = cur.value(b'=')?;
                self.assigns.push(Assign { target, value, col });
            } else if c == b'e' && cur.peek_at(1) == Some(b'x') {
                cur.pos += 2;
                self.ex.push(read_ex(&mut cur, col)?);
            } else if c.is_ascii_alphabetic() || c == b'@' || c == b'^' {
                // `@` and `^` are the polar radius and angle words.
                cur.bump();
                let letter = c.to_ascii_uppercase();
                let value = cur.value(letter)?;
                self.words.push(Word { letter, value, col });
            } else {
                return Err((col, ErrorKind::BadCharacter(char::from(c))));
            }
        }
        Ok(())
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
    let value = cur.value(b'=')?;
    Ok(ExWrite { array, index: u8::try_from(index).unwrap_or(0), value, col })
}

fn okind(kw: &[u8]) -> Option<OKind> {
    Some(match kw {
        b"sub" => OKind::Sub,
        b"endsub" => OKind::EndSub,
        b"call" => OKind::Call,
        b"return" => OKind::Return,
        b"if" => OKind::If,
        b"elseif" => OKind::ElseIf,
        b"else" => OKind::Else,
        b"endif" => OKind::EndIf,
        b"while" => OKind::While,
        b"endwhile" => OKind::EndWhile,
        b"do" => OKind::Do,
        b"break" => OKind::Break,
        b"continue" => OKind::Continue,
        b"repeat" => OKind::Repeat,
        b"endrepeat" => OKind::EndRepeat,
        b"" => OKind::Heading,
        _ => return None,
    })
}

fn read_oword(cur: &mut Cursor) -> KResult<OWord> {
    let col = cur.col();
    cur.bump();
    let text = |cur: &Cursor, (a, b): (usize, usize)| {
        String::from_utf8_lossy(cur.s.get(a..b).unwrap_or(&[])).into_owned()
    };
    let name = if cur.eat(b'<') {
        let Some(range) = cur.until(b'>') else {
            cur.pos = cur.s.len();
            return Err((cur.col(), ErrorKind::OWord("unclosed O-word name".into())));
        };
        cur.bump();
        format!("<{}>", text(cur, range))
    } else {
        let start = cur.pos;
        while cur.peek().is_some_and(|d| d.is_ascii_digit()) {
            cur.bump();
        }
        if cur.pos == start {
            return Err((cur.col(), ErrorKind::OWord("O-word number or <name> expected".into())));
        }
        // o0100 and o100 are the same.
        let n = text(cur, (start, cur.pos));
        let t = n.trim_start_matches('0');
        if t.is_empty() {
            "0".to_owned()
        } else {
            t.to_owned()
        }
    };
    let kcol = cur.col();
    let kw = cur.alpha_run();
    let kind = okind(cur.s.get(kw.0..kw.1).unwrap_or(&[]))
        .ok_or_else(|| (kcol, ErrorKind::OWord(format!("unknown O-word keyword '{}'", text(cur, kw)))))?;
    let mut args = Vec::new();
    match kind {
        OKind::If | OKind::ElseIf | OKind::While | OKind::Repeat => {
            if cur.peek() != Some(b'[') {
                let msg = format!("[condition] expected after {}", text(cur, kw));
                return Err((cur.col(), ErrorKind::OWord(msg)));
            }
            args.push(cur.value(b'o')?);
        }
        OKind::Call | OKind::Return | OKind::EndSub => {
            while cur.peek().is_some() {
                args.push(cur.value(b'o')?);
            }
            if kind != OKind::Call && args.len() > 1 {
                return Err((kcol, ErrorKind::OWord("one return value at most".into())));
            }
        }
        _ => {}
    }
    Ok(OWord { name, kind, args, col })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    fn val(s: &str) -> f64 {
        let l = parse_line(&format!("X{s}")).unwrap();
        l.eval(&Params::default(), &mut Vec::new(), l.words[0].value, 1).unwrap()
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
        let text = "n10 g1 x 1 (msg,hi) ; rest";
        let l = parse_line(text).unwrap();
        assert_eq!(l.n, Some(10));
        assert_eq!(l.words[1].col, 8);
        assert_eq!(l.remark(text), Some(Remark::Message("hi")));
        // Columns count characters: the 2-byte 'é' in the comment is one column (by hand:
        // '(' 1, 'é' 2, ')' 3, ' ' 4, 'G' 5, '1' 6, ' ' 7, then '€' or 'X' at 8; a missing
        // value is reported just after the last character, 9).
        assert_eq!(parse_line("(é) G1 €").unwrap_err(), (8, ErrorKind::BadCharacter('€')));
        assert_eq!(parse_line("(é) G1 X").unwrap_err(), (9, ErrorKind::MissingValue('X')));
        // A plain number is read directly; a bracketed lone number too.
        let l = parse_line("X[5] Y-.5 Z#1").unwrap();
        assert_eq!(l.words[0].value, Val::Num(5.0));
        assert_eq!(l.words[1].value, Val::Num(-0.5));
        assert!(matches!(l.words[2].value, Val::Code(0, 1)));
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
