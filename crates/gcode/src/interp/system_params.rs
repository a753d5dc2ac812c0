//! LinuxCNC's read-only parameters, published before each line is read (as LinuxCNC does
//! in its `read`): the current position #5420-#5428 and the predefined named parameters of
//! [`SYSTEM_NAMES`] (`#<_x>`, `#<_feed>`, `#<_motion_mode>`, ...), and the text of
//! `(DEBUG,...)` and `(PRINT,...)` comments with their parameters substituted.

use super::feed::FeedMode;
use super::motion::Motion;
use super::Interpreter;
use crate::canon::{Plane, Pose, Units};
use crate::params::{param_index, SYSTEM_NAMES};

/// The first of the current-position parameters (#5420 = X).
const POSITION_PARAM: usize = 5420;

/// The version of LinuxCNC whose dialect this interpreter follows (`#<_vmajor>`,
/// `#<_vminor>`: programs test it): the `rs274` the oracle tests compare with.
const LINUXCNC_VERSION: (f64, f64) = (2.9, 0.0);

/// What a parameter that is not defined prints as in a `(DEBUG,...)` text (LinuxCNC's).
const UNDEFINED: &str = "######";

/// A flag as LinuxCNC's parameters give it.
fn flag(b: bool) -> f64 {
    if b {
        1.0
    } else {
        0.0
    }
}

impl Interpreter<'_> {
    /// Publishes the read-only parameters for the line about to be read.
    pub(super) fn publish_system_params(&mut self) {
        // Under cutter compensation: where the compensated tool is (as LinuxCNC's current
        // position), not the programmed point.
        let pos = self.comp_tool_position();
        for (k, v) in pos.iter().enumerate() {
            self.params.set(POSITION_PARAM + k, *v);
        }
        for k in pos.len()..9 {
            self.params.set(POSITION_PARAM + k, 0.0);
        }
        // _abs_x ..: where the machine is (offsets and the tool length offset added), in
        // program units.
        let origin = self.origins.get(self.coord).copied().unwrap_or_default();
        let mm = self.units.mm_per_unit();
        let mut abs: [f64; 6] = std::array::from_fn(|k| {
            let tool = self.tool.offset_mm.get(k).copied().unwrap_or(0.0);
            pos.get(k).copied().unwrap_or(0.0)
                + origin.get(k).copied().unwrap_or(0.0)
                + self.g92.get(k).copied().unwrap_or(0.0)
                + if k < 3 { tool / mm } else { tool }
        });
        super::rotation::set_xy(&mut abs, self.absolute_xy(&pos));
        let motion_mode = match self.motion {
            None => 800.0,
            Some(Motion::Rapid) => 0.0,
            Some(Motion::Feed) => 10.0,
            Some(Motion::Cw) => 20.0,
            Some(Motion::Ccw) => 30.0,
            Some(Motion::Cycle(c)) => f64::from(c.code()),
        };
        let plane = match self.plane {
            Plane::Xy => 170.0,
            Plane::Xz => 180.0,
            Plane::Yz => 190.0,
        };
        let coord_system = [540.0, 550.0, 560.0, 570.0, 580.0, 590.0, 591.0, 592.0, 593.0]
            .get(self.coord)
            .copied()
            .unwrap_or(540.0);
        let metric = self.units == Units::Mm;
        // _x .. _w and _abs_x .. _abs_w (no U V W here), then the rest in the order of
        // SYSTEM_NAMES (the array's length is checked against it when this compiles).
        let nine = |p: Pose| -> [f64; 9] { std::array::from_fn(|k| p.get(k).copied().unwrap_or(0.0)) };
        let rest: [f64; SYSTEM_NAMES.len() - 18] = [
            self.feed,
            self.rpm,
            f64::from(self.cur_line),
            motion_mode,
            plane,
            coord_system,
            flag(metric),
            flag(!metric),
            flag(self.absolute),
            flag(!self.absolute),
            flag(self.arc_absolute),
            flag(self.feed_mode == FeedMode::InverseTime),
            flag(self.feed_mode == FeedMode::PerMinute),
            flag(self.feed_mode == FeedMode::PerRevolution),
            // Cutter compensation: 400 (G40), 410 (left), 420 (right).
            self.comp.ccomp(),
            // Radius mode (G8).
            0.0,
            1.0,
            flag(self.css_max_rpm.is_none()),
            flag(self.css_max_rpm.is_some()),
            // Overrides at 100 %, no adaptive feed, feed hold allowed.
            1.0,
            1.0,
            0.0,
            1.0,
            flag(self.spindle != 0),
            flag(self.spindle > 0),
            flag(self.mist),
            flag(self.flood),
            LINUXCNC_VERSION.0,
            LINUXCNC_VERSION.1,
            self.calls.len() as f64,
            0.0,
            0.0,
            f64::from(self.tool.current.0),
            f64::from(self.tool.selected.0),
            flag(self.tool.active),
        ];
        let values = nine(pos).into_iter().chain(nine(abs)).chain(rest);
        for (slot, v) in self.params.system.iter_mut().zip(values) {
            *slot = v;
        }
    }

    /// `text` with each `#n` and `#<name>` replaced by the parameter's value as LinuxCNC's
    /// `(DEBUG,...)` prints it (six decimals; `######` when it is not defined).
    pub(super) fn substitute_params(&self, text: &str) -> String {
        let mut out = String::with_capacity(text.len() + 16);
        let mut rest = text;
        while let Some(at) = rest.find('#') {
            out.push_str(rest.get(..at).unwrap_or(""));
            let after = rest.get(at + 1..).unwrap_or("");
            if let Some(named) = after.strip_prefix('<') {
                let Some(end) = named.find('>') else {
                    out.push('#');
                    rest = after;
                    continue;
                };
                let name: String = named
                    .get(..end)
                    .unwrap_or("")
                    .chars()
                    .filter(|c| !c.is_whitespace())
                    .map(|c| c.to_ascii_lowercase())
                    .collect();
                push_value(&mut out, self.params.get_named(&name));
                rest = named.get(end + 1..).unwrap_or("");
            } else {
                let digits = after.bytes().take_while(u8::is_ascii_digit).count();
                if digits == 0 {
                    out.push('#');
                    rest = after;
                    continue;
                }
                let number: f64 = after.get(..digits).and_then(|d| d.parse().ok()).unwrap_or(0.0);
                push_value(&mut out, param_index(number).ok().map(|i| self.params.get(i)));
                rest = after.get(digits..).unwrap_or("");
            }
        }
        out.push_str(rest);
        out
    }
}

fn push_value(out: &mut String, v: Option<f64>) {
    match v {
        Some(v) => out.push_str(&format!("{v:.6}")),
        None => out.push_str(UNDEFINED),
    }
}
