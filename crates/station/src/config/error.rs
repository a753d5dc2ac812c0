//! Configuration errors that point at a file, a line, a column and a key.

use std::fmt;
use std::path::{Path, PathBuf};

/// One problem in a cell file.
///
/// Displays as `file:line:column: message`; the message names the key (e.g.
/// `cell.toml:42:7: axis "x": limits.min (10) must be below limits.max (5)`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigError {
    /// The cell file (as given to the loader).
    pub file: PathBuf,
    /// 1-based line of the offending value (0 when the file could not be read).
    pub line: usize,
    /// 1-based column (in characters) of the offending value.
    pub column: usize,
    /// Path of the key in the document, e.g. `axis[2].limits.min` (empty for syntax errors
    /// outside any key).
    pub key: String,
    /// What is wrong, naming the section and the key.
    pub message: String,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}: {}", self.file.display(), self.line, self.column, self.message)
    }
}

/// Every problem found in a cell file (at least one), in file order.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub struct ConfigErrors(pub Vec<ConfigError>);

impl ConfigErrors {
    /// The problems.
    pub fn errors(&self) -> &[ConfigError] {
        &self.0
    }
}

impl fmt::Display for ConfigErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut first = true;
        for e in &self.0 {
            if !first {
                writeln!(f)?;
            }
            first = false;
            write!(f, "{e}")?;
        }
        Ok(())
    }
}

/// Maps byte offsets of one source text to 1-based lines and columns.
#[derive(Debug, Clone)]
pub(crate) struct Locator<'a> {
    file: &'a Path,
    text: &'a str,
}

impl<'a> Locator<'a> {
    /// A locator for `text` read from `file`.
    pub(crate) fn new(file: &'a Path, text: &'a str) -> Self {
        Locator { file, text }
    }

    /// 1-based (line, column) of a byte offset (clamped to the text; columns count chars).
    pub(crate) fn line_col(&self, offset: usize) -> (usize, usize) {
        let mut offset = offset.min(self.text.len());
        while !self.text.is_char_boundary(offset) {
            offset = offset.saturating_sub(1);
        }
        let before = self.text.get(..offset).unwrap_or("");
        let line = before.matches('\n').count() + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let column = before.get(line_start..).map_or(0, |s| s.chars().count()) + 1;
        (line, column)
    }

    /// An error at a byte offset.
    pub(crate) fn error(
        &self,
        offset: usize,
        key: impl Into<String>,
        message: impl Into<String>,
    ) -> ConfigError {
        let (line, column) = self.line_col(offset);
        ConfigError { file: self.file.to_path_buf(), line, column, key: key.into(), message: message.into() }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn line_and_column_count_from_one() {
        // "ab\ncdé\nx": a=0 b=1 \n=2 c=3 d=4 é=5..6 \n=7 x=8 (é is 2 bytes in UTF-8).
        let text = "ab\ncdé\nx";
        let loc = Locator::new(Path::new("c.toml"), text);
        assert_eq!(loc.line_col(0), (1, 1));
        assert_eq!(loc.line_col(1), (1, 2));
        assert_eq!(loc.line_col(3), (2, 1));
        assert_eq!(loc.line_col(5), (2, 3));
        assert_eq!(loc.line_col(8), (3, 1));
        // Inside the two-byte 'é' (offset 6) snaps back to its start (column 3).
        assert_eq!(loc.line_col(6), (2, 3));
        assert_eq!(loc.line_col(1000), (3, 2));
    }

    #[test]
    fn display_is_file_line_column_message() {
        let loc = Locator::new(Path::new("cell.toml"), "a\nb = 1\n");
        let e = loc.error(6, "b", "b: bad");
        assert_eq!(e.to_string(), "cell.toml:2:5: b: bad");
        let all = ConfigErrors(vec![e.clone(), e]);
        assert_eq!(all.to_string(), "cell.toml:2:5: b: bad\ncell.toml:2:5: b: bad");
    }
}
