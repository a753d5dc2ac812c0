//! The storage interface and its two implementations.
//!
//! [`Store`] is deliberately small: plain record reads and writes, plus the one operation
//! that must be atomic (booking a slot only if it overlaps nothing). All rules live above it.
//! [`SqliteStore`] is the default (a file beside the station's configuration, see
//! [`default_db_path`]); [`MemoryStore`] serves tests and throw-away simulations.

mod memory;
mod sqlite;

pub use memory::MemoryStore;
pub use sqlite::{default_db_path, SqliteStore, SCHEMA_VERSION};

use crate::alarm::{Alarm, AlarmQuery};
use crate::audit::{AuditEntry, AuditQuery, AuditRecord};
use crate::program::{ProgramKind, ProgramMeta};
use crate::reservation::{NewReservation, Reservation};
use crate::session::SessionRecord;
use crate::time::UnixMs;
use crate::users::User;

/// A storage failure. Rule violations are not store errors (see each facade's error type).
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The SQLite database reported an error during `op`.
    #[error("database error during {op}: {source}")]
    Sqlite {
        /// What was being done ("insert user", "migrate to v1"...).
        op: &'static str,
        /// The library's error.
        #[source]
        source: rusqlite::Error,
    },
    /// A record with this key already exists.
    #[error("{what} {key:?} already exists")]
    Conflict {
        /// Kind of record ("user", "session"...).
        what: &'static str,
        /// Its key.
        key: String,
    },
    /// No record with this key.
    #[error("{what} {key:?} not found")]
    NotFound {
        /// Kind of record.
        what: &'static str,
        /// Its key.
        key: String,
    },
    /// A stored value could not be decoded (e.g. an unknown role name).
    #[error("corrupt {what} in storage: {detail}")]
    Corrupt {
        /// Which value.
        what: &'static str,
        /// What was wrong.
        detail: String,
    },
    /// The database was written by a newer version of this crate.
    #[error("database schema version {found} is newer than the supported {supported}")]
    SchemaTooNew {
        /// `PRAGMA user_version` found.
        found: i64,
        /// Highest version this build knows.
        supported: i64,
    },
    /// A memory store's lock was poisoned by a panicking thread.
    #[error("store lock poisoned")]
    Poisoned,
}

/// Result of [`Store::insert_reservation_if_free`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BookOutcome {
    /// Stored under this id.
    Booked(i64),
    /// Not stored: it overlaps this existing reservation of the same station.
    Overlaps(Reservation),
}

/// Which reservations [`Store::list_reservations`] returns (all filters combine with AND).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ReservationFilter {
    /// Only this station.
    pub station: Option<String>,
    /// Only this user's.
    pub user: Option<String>,
    /// Only those whose `[start, end)` intersects this `[from, until)` window.
    pub window: Option<(UnixMs, UnixMs)>,
    /// Only those that ended at or before this instant and are not yet cleaned up.
    pub pending_cleanup_at: Option<UnixMs>,
}

impl ReservationFilter {
    /// True if `r` passes the filter (shared by the memory store and tests).
    #[must_use]
    pub fn matches(&self, r: &Reservation) -> bool {
        self.station.as_ref().map_or(true, |s| *s == r.station)
            && self.user.as_ref().map_or(true, |u| *u == r.user)
            && self.window.map_or(true, |(from, until)| r.start < until && from < r.end)
            && self.pending_cleanup_at.map_or(true, |t| r.end <= t && !r.cleaned)
    }
}

/// Persistence for everything the laboratory layer keeps. Implementations are shared between
/// threads (`&self` methods); each call is atomic on its own.
pub trait Store: Send + Sync {
    /// Adds a user. [`StoreError::Conflict`] if the name exists.
    fn insert_user(&self, user: &User) -> Result<(), StoreError>;
    /// Replaces a user's role, hash and `updated` time. [`StoreError::NotFound`] if absent.
    fn update_user(&self, user: &User) -> Result<(), StoreError>;
    /// A user by name.
    fn get_user(&self, name: &str) -> Result<Option<User>, StoreError>;
    /// Deletes a user and their sessions; false if there was none.
    fn delete_user(&self, name: &str) -> Result<bool, StoreError>;
    /// Every user, ordered by name.
    fn list_users(&self) -> Result<Vec<User>, StoreError>;

    /// Adds a session. [`StoreError::Conflict`] on a duplicate token hash.
    fn insert_session(&self, session: &SessionRecord) -> Result<(), StoreError>;
    /// A session by the SHA-256 (hex) of its token.
    fn get_session(&self, token_hash: &str) -> Result<Option<SessionRecord>, StoreError>;
    /// Sets a session's `last_seen`.
    fn touch_session(&self, token_hash: &str, last_seen: UnixMs) -> Result<(), StoreError>;
    /// Deletes one session; false if there was none.
    fn delete_session(&self, token_hash: &str) -> Result<bool, StoreError>;
    /// Deletes every session of `user`; returns how many.
    fn delete_user_sessions(&self, user: &str) -> Result<usize, StoreError>;
    /// Deletes sessions created at or before `created_by` or last seen at or before `seen_by`;
    /// returns how many.
    fn delete_stale_sessions(&self, created_by: UnixMs, seen_by: UnixMs) -> Result<usize, StoreError>;
    /// Sessions (of one user, or all), oldest first.
    fn list_sessions(&self, user: Option<&str>) -> Result<Vec<SessionRecord>, StoreError>;

    /// Atomically stores `r` unless it overlaps (`a.start < b.end && b.start < a.end`) another
    /// reservation of the same station.
    fn insert_reservation_if_free(&self, r: &NewReservation) -> Result<BookOutcome, StoreError>;
    /// A reservation by id.
    fn get_reservation(&self, id: i64) -> Result<Option<Reservation>, StoreError>;
    /// Replaces `end`, `ended_by` and `cleaned` of reservation `r.id`.
    fn update_reservation(&self, r: &Reservation) -> Result<(), StoreError>;
    /// Deletes a reservation; false if there was none.
    fn delete_reservation(&self, id: i64) -> Result<bool, StoreError>;
    /// Reservations passing `filter`, ordered by start then id.
    fn list_reservations(&self, filter: &ReservationFilter) -> Result<Vec<Reservation>, StoreError>;

    /// Appends an audit entry; returns its id (increasing).
    fn append_audit(&self, entry: &AuditEntry) -> Result<i64, StoreError>;
    /// Audit entries passing `query`, newest first, at most `query.limit`.
    fn query_audit(&self, query: &AuditQuery) -> Result<Vec<AuditRecord>, StoreError>;

    /// Stores a new alarm (its `id` is ignored); returns the id given.
    fn insert_alarm(&self, alarm: &Alarm) -> Result<i64, StoreError>;
    /// Replaces the acknowledgement and clearing fields of alarm `alarm.id`.
    fn update_alarm(&self, alarm: &Alarm) -> Result<(), StoreError>;
    /// An alarm by id.
    fn get_alarm(&self, id: i64) -> Result<Option<Alarm>, StoreError>;
    /// Alarms passing `query`, newest first.
    fn list_alarms(&self, query: &AlarmQuery) -> Result<Vec<Alarm>, StoreError>;

    /// Inserts or replaces the metadata of a program or trace (key: station, owner, kind, name).
    fn upsert_program(&self, program: &ProgramMeta) -> Result<(), StoreError>;
    /// Programs and traces, optionally of one station and/or owner, ordered by key.
    fn list_programs(
        &self,
        station: Option<&str>,
        owner: Option<&str>,
    ) -> Result<Vec<ProgramMeta>, StoreError>;
    /// Deletes one program's metadata; false if there was none.
    fn delete_program(
        &self,
        station: &str,
        owner: &str,
        kind: ProgramKind,
        name: &str,
    ) -> Result<bool, StoreError>;
}
