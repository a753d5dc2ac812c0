//! Feed and spindle-speed modes, with LinuxCNC's semantics: G94 (units per minute), G93
//! (inverse time: each feed move takes 1/F minutes; the rate sent before it is its length
//! times F, at least 0.1) and G95 (units per spindle revolution); G96 (constant surface
//! speed, D the rpm limit) and G97 (rpm). Every feed move gets its rate in millimetres per
//! minute for the planner.

use super::Interpreter;
use crate::block::{g, Block};
use crate::canon::Canon;
use crate::error::{ErrorKind, KResult};

/// The feed mode in force.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(super) enum FeedMode {
    /// G94.
    #[default]
    PerMinute,
    /// G93.
    InverseTime,
    /// G95.
    PerRevolution,
}

/// LinuxCNC's lowest inverse-time rate (units per minute).
const MIN_INVERSE_TIME_RATE: f64 = 0.1;

/// LinuxCNC's rpm limit of G96 without a D word ("no limit").
const CSS_NO_LIMIT: f64 = 1e30;

impl Interpreter<'_> {
    /// G93, G94 or G95.
    pub(super) fn set_feed_mode(&mut self, code: u16) {
        match code {
            g::G93 => {
                self.feed_mode = FeedMode::InverseTime;
                self.emit(Canon::SetFeedMode { per_revolution: false });
            }
            _ => {
                let per_revolution = code == g::G95;
                self.feed_mode = if per_revolution { FeedMode::PerRevolution } else { FeedMode::PerMinute };
                self.emit(Canon::SetFeedMode { per_revolution });
                self.emit(Canon::SetFeedRate { rate: 0.0 });
                self.feed = 0.0;
            }
        }
    }

    /// The F word: the feed rate, or under G93 the inverse time of this block's move.
    pub(super) fn feed_word(&mut self, f: f64) {
        if self.feed_mode == FeedMode::InverseTime {
            self.inverse_f = f;
        } else {
            self.feed = f;
            self.emit(Canon::SetFeedRate { rate: f });
        }
    }

    /// G96 (with its D word) or G97.
    pub(super) fn set_spindle_mode(&mut self, code: u16, b: &Block) {
        let max_rpm = if code == g::G96 { b.d.unwrap_or(CSS_NO_LIMIT) } else { 0.0 };
        self.css_max_rpm = (code == g::G96).then_some(max_rpm);
        self.emit(Canon::SetSpindleMode { max_rpm });
    }

    /// The rate of a feed move of `length` (program units) for motion `g` (1, 2 or 3, for the
    /// messages), in millimetres per minute; under G93 also sends the move's rate first.
    pub(super) fn move_feed(&mut self, length: f64, b: &Block, g: u8, col: u32) -> KResult<f64> {
        let mm = self.units.mm_per_unit();
        match self.feed_mode {
            FeedMode::PerMinute => {
                if self.feed == 0.0 {
                    return Err((col, ErrorKind::ZeroFeed(g)));
                }
                Ok(self.feed * mm)
            }
            FeedMode::InverseTime => {
                if b.f.is_none() {
                    return Err((col, ErrorKind::InverseTimeWithoutF(g)));
                }
                let rate = (length * self.inverse_f).max(MIN_INVERSE_TIME_RATE);
                self.emit(Canon::SetFeedRate { rate });
                Ok(rate * mm)
            }
            FeedMode::PerRevolution => {
                if self.feed == 0.0 {
                    return Err((col, ErrorKind::ZeroFeed(g)));
                }
                // Under G96 the speed varies with the radius: plan with its limit.
                let rpm = match self.css_max_rpm {
                    Some(limit) if limit < CSS_NO_LIMIT => limit,
                    Some(_) => return Err((col, ErrorKind::PerRevolutionUnderCssWithoutLimit)),
                    None => self.rpm,
                };
                if rpm == 0.0 {
                    return Err((col, ErrorKind::ZeroSpindlePerRevolution));
                }
                Ok(self.feed * mm * rpm)
            }
        }
    }
}
