//! Parameters: numbered `#1..#5602` (global, except `#1..#30` inside a subroutine call),
//! named locals `#<name>` (per call frame) and named globals `#<_name>`.

use std::collections::HashMap;

use crate::error::ErrorKind;

/// Highest numbered parameter (LinuxCNC's `RS274NGC_MAX_PARAMETERS - 1`).
pub const MAX_PARAMETER: usize = 5602;

/// A subroutine frame's local parameters.
#[derive(Debug, Clone, Default)]
pub(crate) struct Frame {
    /// `#1..#30` of this call.
    pub(crate) locals: [f64; 30],
    /// Named locals (`#<name>` without a leading underscore).
    pub(crate) named: HashMap<String, f64>,
}

/// LinuxCNC's predefined read-only named parameters this interpreter keeps, in the order of
/// [`Params::system`] (their values are published before each line is read:
/// `interp/system_params.rs`).
#[rustfmt::skip]
pub(crate) const SYSTEM_NAMES: [&str; 53] = [
    "_x", "_y", "_z", "_a", "_b", "_c", "_u", "_v", "_w",
    "_abs_x", "_abs_y", "_abs_z", "_abs_a", "_abs_b", "_abs_c", "_abs_u", "_abs_v", "_abs_w",
    "_feed", "_rpm", "_line", "_motion_mode", "_plane", "_coord_system",
    "_metric", "_imperial", "_absolute", "_incremental", "_ijk_absolute_mode",
    "_inverse_time", "_units_per_minute", "_units_per_rev", "_ccomp",
    "_lathe_diameter_mode", "_lathe_radius_mode", "_spindle_rpm_mode", "_spindle_css_mode",
    "_speed_override", "_feed_override", "_adaptive_feed", "_feed_hold",
    "_spindle_on", "_spindle_cw", "_mist", "_flood",
    "_vmajor", "_vminor", "_call_level", "_task", "_remap_level",
    "_current_tool", "_selected_tool", "_tool_offset",
];

/// Where `name` (lower case) is in [`SYSTEM_NAMES`].
pub(crate) fn system_index(name: &str) -> Option<usize> {
    SYSTEM_NAMES.iter().position(|n| *n == name)
}

/// Numbered parameters a program cannot assign (LinuxCNC: tool data, current position).
pub(crate) fn is_read_only(idx: usize) -> bool {
    (5400..=5413).contains(&idx) || (5420..=5428).contains(&idx)
}

/// All parameters: numbered (global, except `#1..#30` inside a call), named locals, globals.
#[derive(Debug, Clone)]
pub(crate) struct Params {
    numbered: Vec<f64>,
    globals: HashMap<String, f64>,
    /// The values of [`SYSTEM_NAMES`].
    pub(crate) system: [f64; SYSTEM_NAMES.len()],
    /// `frames[0]` is the main program's frame (its `#1..#30` live in `numbered`).
    pub(crate) frames: Vec<Frame>,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            numbered: vec![0.0; MAX_PARAMETER + 1],
            globals: HashMap::new(),
            system: [0.0; SYSTEM_NAMES.len()],
            frames: vec![Frame::default()],
        }
    }
}

/// Converts a value to a parameter index (must be within 0.0001 of an integer in 1..=5602).
pub(crate) fn param_index(v: f64) -> Result<usize, ErrorKind> {
    let r = crate::expr::round(v);
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
            if let Some(i) = system_index(name) {
                return self.system.get(i).copied();
            }
            self.globals.get(name).copied()
        } else {
            self.frames.last().and_then(|f| f.named.get(name).copied())
        }
    }

    /// Writes a named parameter.
    pub(crate) fn set_named(&mut self, name: &str, v: f64) {
        let map = if name.starts_with('_') {
            &mut self.globals
        } else if let Some(f) = self.frames.last_mut() {
            &mut f.named
        } else {
            return;
        };
        match map.get_mut(name) {
            Some(slot) => *slot = v,
            None => {
                map.insert(name.to_owned(), v);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

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

    #[test]
    fn named_locals_and_globals() {
        let mut p = Params::default();
        p.set_named("_g", 1.0);
        p.set_named("l", 2.0);
        p.frames.push(Frame::default());
        assert_eq!(p.get_named("_g"), Some(1.0));
        assert_eq!(p.get_named("l"), None);
        p.set_named("_g", 3.0);
        p.frames.pop();
        assert_eq!((p.get_named("_g"), p.get_named("l")), (Some(3.0), Some(2.0)));
        assert_eq!(param_index(5602.00005), Ok(5602));
        assert!(param_index(0.0).is_err() && param_index(1.5).is_err());
    }
}
