//! The cell file: one TOML file describing links, devices, axes, groups, the supervisor,
//! cyclic tasks and programs.
//!
//! [`load`] reads and validates a file; every problem is reported at once as a
//! [`ConfigError`] naming the file, line, column and key, e.g.
//! `cell.toml:42:7: axis "x": limits.min (10) must be below limits.max (5)`.
//! Unknown keys are errors (`deny_unknown_fields`). Relative paths (data dir, rules,
//! programs) are resolved against the cell file's folder. See `examples/demo-cell.toml`.

mod error;
mod model;
mod raw;
mod validate;

use std::path::Path;

pub use error::{ConfigError, ConfigErrors};
pub use model::{
    AxisConfig, Camera, Cell, Device, DeviceKind, Group, GroupKind, Limits, Link, LinkKind, Program, Station,
    StudentLimits, Supervisor, TaskClassConfig, TaskConfig, TaskKind, ToolConfig, Unit, DEFAULT_LISTEN,
    DEFAULT_OVERRUN_LIMIT, DEFAULT_PROGRAM_CHECK_TIME,
};

use error::Locator;
use raw::RawCell;
use validate::Validator;

/// Reads and validates a cell file.
pub fn load(path: &Path) -> Result<Cell, ConfigErrors> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        ConfigErrors(vec![ConfigError {
            file: path.to_path_buf(),
            line: 0,
            column: 0,
            key: String::new(),
            message: format!("cannot read the cell file: {e}"),
        }])
    })?;
    parse_str(path, &text)
}

/// Validates cell-file text that was read from `file` (used for messages and to resolve
/// relative paths). Referenced rules and program files must exist.
pub fn parse_str(file: &Path, text: &str) -> Result<Cell, ConfigErrors> {
    parse_with(file, text, &|p: &Path| p.exists())
}

/// [`parse_str`] with a custom "does this file exist" check.
pub(crate) fn parse_with(
    file: &Path,
    text: &str,
    exists: &dyn Fn(&Path) -> bool,
) -> Result<Cell, ConfigErrors> {
    let loc = Locator::new(file, text);
    let de = toml::Deserializer::new(text);
    let raw: RawCell = match serde_path_to_error::deserialize(de) {
        Ok(raw) => raw,
        Err(e) => {
            let key = clean_key_path(&e.path().to_string());
            let inner = e.into_inner();
            let offset = inner.span().map_or(0, |s| s.start);
            let what = inner.message().trim_end().to_string();
            let message = if key.is_empty() { what } else { format!("{key}: {what}") };
            return Err(ConfigErrors(vec![loc.error(offset, key, message)]));
        }
    };
    let base = file.parent().map(Path::to_path_buf).unwrap_or_default();
    Validator::new(loc, base, exists).run(file, raw).map_err(ConfigErrors)
}

/// Drops the `toml::Spanned` wrapper's internal segments from a serde path.
fn clean_key_path(path: &str) -> String {
    if path == "." || path == "?" {
        return String::new();
    }
    path.split('.').filter(|seg| !seg.starts_with("$__serde_spanned_private")).collect::<Vec<_>>().join(".")
}

#[cfg(test)]
mod tests;
