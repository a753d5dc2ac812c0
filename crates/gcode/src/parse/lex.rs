//! Lexical level of the line parser: the fast path for lines of plain words, and the
//! normalisation (lower case, blanks and comments removed, columns kept) that the
//! general path reads.

use super::{Line, Word};
use crate::error::{ErrorKind, KResult};
use crate::expr::Val;

impl Line {
    /// The fast path: a line of plain words (`G1 X10 Y-2.5`, optional N number; ASCII,
    /// no comment, expression, parameter, O-word or EX word) is read straight from the
    /// text. Returns `false` (leaving partial results for the caller to clear) for any
    /// other line, which the general path then reads — with identical results for the
    /// lines accepted here, since the value of a plain number and the column of a word
    /// (all bytes before it are ASCII) are the same in both paths.
    pub(super) fn parse_plain(&mut self, text: &str) -> bool {
        let b = text.as_bytes();
        let mut i = 0usize;
        let mut first = true;
        loop {
            while matches!(b.get(i), Some(b' ' | b'\t' | b'\r')) {
                i += 1;
            }
            let Some(&c) = b.get(i) else { return true };
            let letter = c.to_ascii_lowercase();
            if !letter.is_ascii_lowercase() || letter == b'o' || letter == b'e' {
                return false;
            }
            let Ok(col) = u32::try_from(i + 1) else { return false };
            i += 1;
            let Some(v) = plain_number(b, &mut i) else { return false };
            if first && letter == b'n' {
                if v < 0.0 || v.fract() != 0.0 || v > f64::from(u32::MAX) {
                    return false;
                }
                // Non-negative integer below 2^32: exact.
                self.n = Some(v as u32);
            } else {
                self.words.push(Word { letter: letter.to_ascii_uppercase(), value: Val::Num(v), col });
            }
            first = false;
        }
    }

    /// Fills `norm` and `cols`; notes block delete and the last comment.
    pub(super) fn normalize(&mut self, text: &str) -> KResult<()> {
        // Sized up front and truncated after: no capacity check per byte.
        let mut norm = std::mem::take(&mut self.norm);
        let mut cols = std::mem::take(&mut self.cols);
        norm.clear();
        cols.clear();
        norm.resize(text.len(), 0);
        cols.resize(text.len(), 0);
        let r = self.normalize_into(text, &mut norm, &mut cols);
        let len = r.as_ref().map_or(0, |&k| k);
        norm.truncate(len);
        cols.truncate(len);
        self.norm = norm;
        self.cols = cols;
        r.map(drop)
    }

    /// Writes the normalised bytes and their columns; returns how many.
    fn normalize_into(&mut self, text: &str, norm: &mut [u8], cols: &mut [u32]) -> KResult<usize> {
        let mut k = 0usize;
        let bytes = text.as_bytes();
        // Continuation bytes of multi-byte characters (only possible in comments) so far:
        // columns count characters.
        let mut skipped = 0usize;
        let col = |i: usize, skipped: usize| u32::try_from(i.saturating_sub(skipped) + 1).unwrap_or(u32::MAX);
        let mut first = true;
        let mut i = 0usize;
        while let Some(&c) = bytes.get(i) {
            match c {
                b' ' | b'\t' => {
                    i += 1;
                    continue;
                }
                b'\r' => {}
                b'/' if first => self.block_delete = true,
                b';' => break,
                b'(' => {
                    let open = col(i, skipped);
                    let mut j = i + 1;
                    loop {
                        match bytes.get(j) {
                            None => return Err((open, ErrorKind::UnclosedComment)),
                            Some(b')') => break,
                            Some(b'(') => return Err((col(j, skipped), ErrorKind::NestedComment)),
                            Some(&b) => {
                                if b & 0xC0 == 0x80 {
                                    skipped += 1;
                                }
                                j += 1;
                            }
                        }
                    }
                    self.comment = Some((i + 1, j));
                    i = j;
                }
                c if c.is_ascii() => {
                    // k <= i < text.len(): always in bounds.
                    if let (Some(n), Some(p)) = (norm.get_mut(k), cols.get_mut(k)) {
                        *n = c.to_ascii_lowercase();
                        *p = col(i, skipped);
                    }
                    k += 1;
                }
                _ => {
                    let ch =
                        text.get(i..).and_then(|t| t.chars().next()).unwrap_or(char::REPLACEMENT_CHARACTER);
                    return Err((col(i, skipped), ErrorKind::BadCharacter(ch)));
                }
            }
            first = false;
            i += 1;
        }
        Ok(k)
    }
}

/// A plain signed decimal number at `b[*i..]` (blanks allowed between its characters, as
/// in the normalised line), read exactly like [`Cursor::number`]; `None` if there is none
/// or it needs the slow path.
fn plain_number(b: &[u8], i: &mut usize) -> Option<f64> {
    let blank = |c: Option<&u8>| matches!(c, Some(b' ' | b'\t' | b'\r'));
    while blank(b.get(*i)) {
        *i += 1;
    }
    let mut neg = false;
    if let Some(&c @ (b'+' | b'-')) = b.get(*i) {
        neg = c == b'-';
        *i += 1;
    }
    let mut mantissa: u64 = 0;
    let mut digits = 0u32;
    let mut frac = 0u32;
    let mut dot = false;
    while let Some(&c) = b.get(*i) {
        if c.is_ascii_digit() {
            digits += 1;
            frac += u32::from(dot);
            mantissa = mantissa * 10 + u64::from(c - b'0');
            if mantissa >= 1 << 53 {
                return None;
            }
        } else if c == b'.' && !dot {
            dot = true;
        } else if !blank(Some(&c)) {
            break;
        }
        *i += 1;
    }
    if digits == 0 {
        return None;
    }
    let v = crate::value::scale(mantissa, frac)?;
    Some(if neg { -v } else { v })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use proptest::prelude::*;

    /// When the fast path accepts `text`, the general path must give the same N number
    /// and words (and nothing else).
    fn same_as_general(text: &str) -> bool {
        let mut fast = Line::default();
        if !fast.parse_plain(text) {
            return false;
        }
        let mut general = Line::default();
        general.parse_general(text).unwrap();
        assert_eq!((fast.n, &fast.words), (general.n, &general.words), "{text:?}");
        assert!(!general.has_content() || !general.words.is_empty(), "{text:?}");
        assert!(general.assigns.is_empty() && general.ex.is_empty() && general.oword.is_none());
        assert!(!general.block_delete && !general.percent);
        true
    }

    #[test]
    fn plain_lines_take_the_fast_path() {
        for t in
            ["G1 X10 Y-2.5", "g1x1y2", "X 1 .5", "N10 G0 X1", "n10 n20", "\tG1\rX3\r", "", "  ", "x-.5 y+2."]
        {
            assert!(same_as_general(t), "{t:?}");
        }
        // Blanks inside a number are ignored (LinuxCNC): X 1 .5 is X1.5, at column 1.
        let l = super::super::parse_line("X 1 .5").unwrap();
        assert_eq!(l.words, vec![Word { letter: b'X', value: Val::Num(1.5), col: 1 }]);
        for t in [
            "N-1 G1",
            "n1.5",
            "G1 X1..5",
            "X.",
            "X9007199254740993",
            "X1.00000000000000000000000001",
            "G1 X1 (c)",
            "G1 X1 ; c",
            "O100 sub",
            "EXW1=2",
            "G1 X1é",
            "/G1 X1",
            "%",
            "G1 X[1]",
            "G1 X#1",
            "G1 X",
            "G1 X-[1]",
        ] {
            assert!(!same_as_general(t), "{t:?} must take the general path");
        }
    }

    proptest! {
        #[test]
        fn fast_path_agrees_with_general_path(t in "[GgXxNnZzOoEe0-9. +\\-\t\r]{0,24}") {
            same_as_general(&t);
        }
    }
}
