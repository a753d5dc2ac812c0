//! O-word control flow: the pre-scan linking the lines of one O name, subroutine calls
//! and returns, if/elseif/else, while, do-while, repeat, break and continue, and a
//! program-number heading (`O1234` alone).

use std::collections::HashMap;

use super::Interpreter;
use crate::error::{ErrorKind, KResult};
use crate::expr::Val;
use crate::params::{Frame, Params};
use crate::parse::{parse_line, Line, OKind, OWord};

/// A line's parse result (error = column and kind).
pub(super) type ParsedLine = Result<Line, (u32, ErrorKind)>;

/// What the pre-scan learnt about a line starting with an O-word.
#[derive(Debug, Default)]
pub(super) struct OLine {
    /// The keyword (`None` if the line does not parse).
    kind: Option<OKind>,
    /// The previous and next line with the same O name.
    prev: Option<usize>,
    next: Option<usize>,
    /// The parsed line (taken out while it executes).
    pub(super) parsed: Option<Box<ParsedLine>>,
}

/// A subroutine call in progress.
pub(super) struct CallFrame {
    return_pc: usize,
}

/// Does `text` start (after block delete, N number and blanks) with an O-word?
pub(super) fn is_oword_line(text: &str) -> bool {
    // Quick answer for the usual line: its first byte is ASCII and none of those that
    // the trimming below skips (whitespace, '/', N, digits) nor 'o'.
    if let Some(&b) = text.as_bytes().first() {
        if b.is_ascii() && !matches!(b, 9..=13 | b' ' | b'/' | b'n' | b'N' | b'0'..=b'9' | b'o' | b'O') {
            return false;
        }
    }
    let t = text.trim_start().trim_start_matches('/').trim_start();
    let t =
        t.trim_start_matches(|c: char| c == 'n' || c == 'N' || c.is_ascii_digit() || c == ' ' || c == '\t');
    t.starts_with(['o', 'O'])
}

/// Pre-scan: parses the O-word lines, links lines of the same O name, finds subroutines.
pub(super) fn index_owords(lines: &[&str]) -> (HashMap<usize, OLine>, HashMap<String, usize>) {
    let mut olines: HashMap<usize, OLine> = HashMap::new();
    let mut subs = HashMap::new();
    let mut last: HashMap<String, usize> = HashMap::new();
    for (i, text) in lines.iter().enumerate() {
        if !is_oword_line(text) {
            continue;
        }
        let parsed = parse_line(text);
        let mut entry = OLine::default();
        if let Ok(Line { oword: Some(o), .. }) = &parsed {
            entry.kind = Some(o.kind);
            if let Some(&j) = last.get(&o.name) {
                if let Some(prev) = olines.get_mut(&j) {
                    prev.next = Some(i);
                }
                entry.prev = Some(j);
            }
            last.insert(o.name.clone(), i);
            if o.kind == OKind::Sub {
                subs.entry(o.name.clone()).or_insert(i);
            }
        }
        entry.parsed = Some(Box::new(parsed));
        olines.insert(i, entry);
    }
    (olines, subs)
}

/// Evaluates an if/elseif/while condition.
fn cond(params: &Params, stack: &mut Vec<f64>, line: &Line, o: &OWord) -> KResult<bool> {
    let e = o.args.first().ok_or((o.col, ErrorKind::OWord("condition missing".into())))?;
    Ok(line.eval(params, stack, *e, o.col)? != 0.0)
}

/// The bracketed argument of an O-word (`repeat [n]`).
fn cond_arg(o: &OWord) -> KResult<Val> {
    o.args.first().copied().ok_or((o.col, ErrorKind::OWord("[count] missing".into())))
}

fn oerr(col: u32, msg: &str) -> (u32, ErrorKind) {
    (col, ErrorKind::OWord(msg.to_owned()))
}

impl Interpreter<'_> {
    fn okind(&self, i: usize) -> Option<OKind> {
        self.olines.get(&i).and_then(|o| o.kind)
    }

    /// The next line of the same O name whose keyword is in `stop`.
    fn chain_next(&self, mut i: usize, stop: &[OKind]) -> Option<usize> {
        loop {
            i = self.olines.get(&i)?.next?;
            if self.okind(i).is_some_and(|k| stop.contains(&k)) {
                return Some(i);
            }
        }
    }

    /// The previous line of the same O name whose keyword is in `stop`.
    fn chain_prev(&self, mut i: usize, stop: &[OKind]) -> Option<usize> {
        loop {
            i = self.olines.get(&i)?.prev?;
            if self.okind(i).is_some_and(|k| stop.contains(&k)) {
                return Some(i);
            }
        }
    }

    /// Is the `while` at `i` the tail of a do-while loop?
    fn is_do_tail(&self, i: usize) -> Option<usize> {
        self.chain_prev(i, &[OKind::Do, OKind::While, OKind::EndWhile, OKind::Sub, OKind::If])
            .filter(|&j| self.okind(j) == Some(OKind::Do))
    }

    fn value(&mut self, line: &Line, v: Val, col: u32) -> KResult<f64> {
        line.eval(&self.params, &mut self.stack, v, col)
    }

    /// Executes the O-word `o` of `line` (at index `here`).
    pub(super) fn execute_oword(&mut self, here: usize, line: &Line, o: &OWord) -> KResult<()> {
        let col = o.col;
        match o.kind {
            OKind::Sub => {
                let end =
                    self.chain_next(here, &[OKind::EndSub]).ok_or_else(|| oerr(col, "sub without endsub"))?;
                self.pc = end + 1;
            }
            OKind::EndSub | OKind::Return => {
                if let Some(&e) = o.args.first() {
                    let v = self.value(line, e, col)?;
                    self.params.set_named("_value", v);
                }
                let frame =
                    self.calls.pop().ok_or_else(|| oerr(col, "endsub/return outside a subroutine call"))?;
                self.params.frames.pop();
                self.pc = frame.return_pc;
            }
            OKind::Call => {
                let sub = *self.subs.get(&o.name).ok_or((col, ErrorKind::UnknownSub(o.name.clone())))?;
                if self.calls.len() >= self.config.max_call_depth {
                    return Err((col, ErrorKind::CallDepth(self.config.max_call_depth)));
                }
                let mut frame = Frame::default();
                for (k, &a) in o.args.iter().enumerate() {
                    let v = self.value(line, a, col)?;
                    match frame.locals.get_mut(k) {
                        Some(slot) => *slot = v,
                        None => return Err(oerr(col, "more than 30 call arguments")),
                    }
                }
                self.params.frames.push(frame);
                self.calls.push(CallFrame { return_pc: here + 1 });
                self.pc = sub + 1;
            }
            OKind::If => {
                if !cond(&self.params, &mut self.stack, line, o)? {
                    let mut j = here;
                    loop {
                        j = self
                            .chain_next(j, &[OKind::ElseIf, OKind::Else, OKind::EndIf])
                            .ok_or_else(|| oerr(col, "if without endif"))?;
                        if self.okind(j) != Some(OKind::ElseIf) {
                            break;
                        }
                        let taken = match self.olines.get(&j).and_then(|p| p.parsed.as_deref()) {
                            Some(Ok(l)) => match &l.oword {
                                Some(eo) => cond(&self.params, &mut self.stack, l, eo)?,
                                None => false,
                            },
                            _ => false,
                        };
                        if taken {
                            break;
                        }
                    }
                    self.pc = j + 1;
                }
            }
            OKind::ElseIf | OKind::Else => {
                let end =
                    self.chain_next(here, &[OKind::EndIf]).ok_or_else(|| oerr(col, "else without endif"))?;
                self.pc = end + 1;
            }
            OKind::EndIf | OKind::Do | OKind::Heading => {}
            OKind::Repeat => {
                let n = line.eval(&self.params, &mut self.stack, cond_arg(o)?, col)?;
                let n = crate::expr::round(n);
                if n >= 1.0 {
                    // At least once; the step budget bounds a huge count.
                    self.repeats.insert((here, self.calls.len()), n.min(u64::MAX as f64) as u64 - 1);
                } else {
                    let end = self
                        .chain_next(here, &[OKind::EndRepeat])
                        .ok_or_else(|| oerr(col, "repeat without endrepeat"))?;
                    self.pc = end + 1;
                }
            }
            OKind::EndRepeat => {
                let head = self
                    .chain_prev(here, &[OKind::Repeat])
                    .ok_or_else(|| oerr(col, "endrepeat without repeat"))?;
                let key = (head, self.calls.len());
                match self.repeats.get_mut(&key) {
                    Some(left) if *left > 0 => {
                        *left -= 1;
                        self.pc = head + 1;
                    }
                    _ => {
                        self.repeats.remove(&key);
                    }
                }
            }
            OKind::While => {
                if let Some(d) = self.is_do_tail(here) {
                    if cond(&self.params, &mut self.stack, line, o)? {
                        self.pc = d + 1;
                    }
                } else if !cond(&self.params, &mut self.stack, line, o)? {
                    let end = self
                        .chain_next(here, &[OKind::EndWhile])
                        .ok_or_else(|| oerr(col, "while without endwhile"))?;
                    self.pc = end + 1;
                }
            }
            OKind::EndWhile => {
                let head = self
                    .chain_prev(here, &[OKind::While])
                    .ok_or_else(|| oerr(col, "endwhile without while"))?;
                self.pc = head;
            }
            OKind::Break => {
                let end = self
                    .chain_next(here, &[OKind::EndWhile, OKind::While])
                    .ok_or_else(|| oerr(col, "break outside a loop"))?;
                self.pc = end + 1;
            }
            OKind::Continue => {
                let back = self
                    .chain_prev(here, &[OKind::While, OKind::Do])
                    .ok_or_else(|| oerr(col, "continue outside a loop"))?;
                if self.okind(back) == Some(OKind::Do) {
                    let tail = self
                        .chain_next(here, &[OKind::While])
                        .ok_or_else(|| oerr(col, "do without while"))?;
                    self.pc = tail;
                } else {
                    self.pc = back;
                }
            }
        }
        Ok(())
    }
}
