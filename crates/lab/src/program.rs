//! Metadata of users' uploaded programs and recorded traces (the files are the station's).
//!
//! A program or trace not marked *exported* is removed at the end of its owner's slot
//! (see [`crate::reservation::Reservations::due_cleanups`]).

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::store::{Store, StoreError};
use crate::time::UnixMs;

/// What kind of user file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProgramKind {
    /// An uploaded motion program (task, cam profile...).
    Program,
    /// A recorded trace.
    Trace,
}

impl ProgramKind {
    /// Storage name (`program`, `trace`).
    #[must_use]
    pub fn as_str(self) -> &'static str {
        match self {
            ProgramKind::Program => "program",
            ProgramKind::Trace => "trace",
        }
    }

    /// Parses a storage name.
    #[must_use]
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "program" => Some(ProgramKind::Program),
            "trace" => Some(ProgramKind::Trace),
            _ => None,
        }
    }
}

/// Metadata of one user file. Key: (station, owner, kind, name).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ProgramMeta {
    /// Station it belongs to.
    pub station: String,
    /// User who uploaded or recorded it.
    pub owner: String,
    /// Program or trace.
    pub kind: ProgramKind,
    /// File name as the station knows it.
    pub name: String,
    /// Exported (kept): survives the end of the slot.
    pub exported: bool,
    /// Size in bytes.
    pub size_bytes: u64,
    /// When it was stored.
    pub created: UnixMs,
}

/// Program/trace metadata over a [`Store`].
pub struct Programs {
    store: Arc<dyn Store>,
}

impl Programs {
    /// Programs in `store`.
    #[must_use]
    pub fn new(store: Arc<dyn Store>) -> Self {
        Programs { store }
    }

    /// Records (or replaces) a program's metadata.
    ///
    /// # Errors
    /// A storage failure.
    pub fn register(&self, meta: &ProgramMeta) -> Result<(), StoreError> {
        self.store.upsert_program(meta)
    }

    /// Sets or clears the exported flag; false if there is no such program.
    ///
    /// # Errors
    /// A storage failure.
    pub fn set_exported(
        &self,
        station: &str,
        owner: &str,
        kind: ProgramKind,
        name: &str,
        exported: bool,
    ) -> Result<bool, StoreError> {
        let found = self
            .store
            .list_programs(Some(station), Some(owner))?
            .into_iter()
            .find(|p| p.kind == kind && p.name == name);
        match found {
            Some(mut p) => {
                p.exported = exported;
                self.store.upsert_program(&p)?;
                Ok(true)
            }
            None => Ok(false),
        }
    }

    /// Programs and traces of a station and/or owner.
    ///
    /// # Errors
    /// A storage failure.
    pub fn list(&self, station: Option<&str>, owner: Option<&str>) -> Result<Vec<ProgramMeta>, StoreError> {
        self.store.list_programs(station, owner)
    }

    /// Removes a program's metadata (after the station deleted the file).
    ///
    /// # Errors
    /// A storage failure.
    pub fn remove(
        &self,
        station: &str,
        owner: &str,
        kind: ProgramKind,
        name: &str,
    ) -> Result<bool, StoreError> {
        self.store.delete_program(station, owner, kind, name)
    }
}
