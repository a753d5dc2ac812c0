//! Progress lines on a terminal; silence when stderr is not a terminal.

use std::io::{IsTerminal, Write};

/// Prints a progress line that overwrites itself, only on a terminal.
pub struct Progress {
    on: bool,
    shown: bool,
}

impl Progress {
    /// A progress display on stderr if it is a terminal.
    pub fn new() -> Self {
        Progress { on: std::io::stderr().is_terminal(), shown: false }
    }

    /// Shows `line`.
    pub fn update(&mut self, line: &str) {
        if self.on {
            let mut e = std::io::stderr();
            let _ = write!(e, "\r\x1b[2K{line}");
            let _ = e.flush();
            self.shown = true;
        }
    }

    /// Ends the line.
    pub fn finish(&mut self) {
        if self.on && self.shown {
            eprintln!();
            self.shown = false;
        }
    }
}
