//! The simulator's persistent state: what a real module keeps in EEPROM (the parameter
//! block), plus where the simulated machine physically stands. Written atomically
//! (temporary file + rename) so a killed simulator never leaves a torn file.

use motus_ps1a_protocol::Parameters;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Persistent state of one module slot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModuleState {
    /// EEPROM parameter block.
    pub parameters: Parameters,
    /// True once a parameter set has been stored (command 1).
    pub programmed: bool,
    /// Machine position in encoder units (the mechanics stay where they are).
    pub machine_position: f64,
}

/// The state file: one entry per module slot, in the order of `--addr`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StateFile {
    /// Format version.
    pub version: u32,
    /// Slots.
    pub modules: Vec<ModuleState>,
}

/// Reading or writing the state file failed.
#[derive(Debug, thiserror::Error)]
pub enum StateFileError {
    /// IO failure.
    #[error("state file {path}: {source}")]
    Io {
        /// File path.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The content is not a valid state file.
    #[error("state file {path} is invalid: {source}")]
    Format {
        /// File path.
        path: String,
        /// Parse error.
        source: serde_json::Error,
    },
}

impl StateFile {
    /// Current format version.
    pub const VERSION: u32 = 1;

    /// Loads `path`; a missing file is an empty state (factory-new modules).
    pub fn load(path: &Path) -> Result<StateFile, StateFileError> {
        match std::fs::read(path) {
            Ok(bytes) => serde_json::from_slice(&bytes)
                .map_err(|source| StateFileError::Format { path: path.display().to_string(), source }),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(StateFile::default()),
            Err(source) => Err(StateFileError::Io { path: path.display().to_string(), source }),
        }
    }

    /// Writes `path` atomically.
    pub fn save(&self, path: &Path) -> Result<(), StateFileError> {
        let io = |source| StateFileError::Io { path: path.display().to_string(), source };
        let json = serde_json::to_vec_pretty(self)
            .map_err(|source| StateFileError::Format { path: path.display().to_string(), source })?;
        let tmp = path.with_extension("tmp");
        std::fs::write(&tmp, json).map_err(io)?;
        std::fs::rename(&tmp, path).map_err(io)
    }
}
