//! The SQLite [`Store`]: one database file beside the station configuration, WAL journal,
//! schema versioned by `PRAGMA user_version` and migrated forward on open.

use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use rusqlite::types::ToSql;
use rusqlite::{params, Connection, OptionalExtension, Row, TransactionBehavior};

use super::{BookOutcome, ReservationFilter, Store, StoreError};
use crate::alarm::{Ack, Alarm, AlarmQuery, Severity};
use crate::audit::{AuditEntry, AuditOutcome, AuditQuery, AuditRecord};
use crate::program::{ProgramKind, ProgramMeta};
use crate::reservation::{NewReservation, Reservation};
use crate::role::Role;
use crate::session::SessionRecord;
use crate::time::UnixMs;
use crate::users::User;

/// Migrations; `MIGRATIONS[i]` brings the schema from version `i` to `i + 1`.
const MIGRATIONS: &[&str] = &[r"
CREATE TABLE users (
    name          TEXT PRIMARY KEY NOT NULL,
    role          TEXT NOT NULL CHECK (role IN ('viewer', 'student', 'admin')),
    password_hash TEXT NOT NULL,
    created       INTEGER NOT NULL,
    updated       INTEGER NOT NULL
) STRICT;
CREATE TABLE sessions (
    token_hash TEXT PRIMARY KEY NOT NULL,
    user_name  TEXT NOT NULL REFERENCES users(name) ON DELETE CASCADE,
    csrf_token TEXT NOT NULL,
    created    INTEGER NOT NULL,
    last_seen  INTEGER NOT NULL,
    source     TEXT
) STRICT;
CREATE INDEX sessions_by_user ON sessions(user_name);
CREATE TABLE reservations (
    id        INTEGER PRIMARY KEY AUTOINCREMENT,
    station   TEXT NOT NULL,
    user_name TEXT NOT NULL,
    start_ms  INTEGER NOT NULL,
    end_ms    INTEGER NOT NULL,
    created   INTEGER NOT NULL,
    ended_by  TEXT,
    cleaned   INTEGER NOT NULL DEFAULT 0,
    CHECK (start_ms <= end_ms)
) STRICT;
CREATE INDEX reservations_by_station ON reservations(station, start_ms);
CREATE INDEX reservations_pending ON reservations(cleaned, end_ms);
CREATE TABLE audit (
    id        INTEGER PRIMARY KEY AUTOINCREMENT,
    time      INTEGER NOT NULL,
    user_name TEXT NOT NULL,
    action    TEXT NOT NULL,
    target    TEXT NOT NULL,
    result    TEXT NOT NULL CHECK (result IN ('ok', 'denied', 'error')),
    message   TEXT NOT NULL
) STRICT;
CREATE INDEX audit_by_time ON audit(time);
CREATE INDEX audit_by_user ON audit(user_name, time);
CREATE TABLE alarms (
    id         INTEGER PRIMARY KEY AUTOINCREMENT,
    code       TEXT NOT NULL,
    source     TEXT NOT NULL,
    message    TEXT NOT NULL,
    severity   TEXT NOT NULL,
    raised_at  INTEGER NOT NULL,
    ack_by     TEXT,
    ack_at     INTEGER,
    cleared_at INTEGER
) STRICT;
CREATE INDEX alarms_by_time ON alarms(raised_at);
CREATE TABLE programs (
    station    TEXT NOT NULL,
    owner      TEXT NOT NULL,
    kind       TEXT NOT NULL CHECK (kind IN ('program', 'trace')),
    name       TEXT NOT NULL,
    exported   INTEGER NOT NULL,
    size_bytes INTEGER NOT NULL,
    created    INTEGER NOT NULL,
    PRIMARY KEY (station, owner, kind, name)
) STRICT;
"];

/// The schema version this build creates and reads.
pub const SCHEMA_VERSION: i64 = MIGRATIONS.len() as i64;

/// The database path for a station configuration file: beside it, named after it
/// (`/etc/motus/station.toml` -> `/etc/motus/station.lab.sqlite`).
#[must_use]
pub fn default_db_path(config_path: &Path) -> PathBuf {
    let stem = config_path.file_stem().map_or_else(|| "motus".into(), |s| s.to_string_lossy().into_owned());
    config_path.with_file_name(format!("{stem}.lab.sqlite"))
}

/// The SQLite store. One connection behind a lock (the laboratory's load is light).
pub struct SqliteStore {
    conn: Mutex<Connection>,
}

fn db(op: &'static str) -> impl FnOnce(rusqlite::Error) -> StoreError {
    move |source| StoreError::Sqlite { op, source }
}

fn corrupt(what: &'static str, detail: impl ToString) -> StoreError {
    StoreError::Corrupt { what, detail: detail.to_string() }
}

fn limit_i64(limit: usize) -> i64 {
    i64::try_from(limit).unwrap_or(i64::MAX)
}

impl SqliteStore {
    /// Opens (creating if needed, with owner-only permissions on Unix) the database at `path`
    /// and migrates it to [`SCHEMA_VERSION`].
    ///
    /// # Errors
    /// [`StoreError::SchemaTooNew`] for a database from a newer build, or a database error.
    pub fn open(path: &Path) -> Result<Self, StoreError> {
        #[cfg(unix)]
        if !path.exists() {
            use std::os::unix::fs::OpenOptionsExt as _;
            // The database holds password hashes: readable by its owner only.
            let created = std::fs::OpenOptions::new().write(true).create_new(true).mode(0o600).open(path);
            if let Err(e) = created {
                tracing::debug!(path = %path.display(), error = %e, "pre-creating the database file failed");
            }
        }
        let conn = Connection::open(path).map_err(db("open database"))?;
        Self::init(conn, true)
    }

    /// A private in-memory database (tests).
    ///
    /// # Errors
    /// A database error.
    pub fn open_in_memory() -> Result<Self, StoreError> {
        let conn = Connection::open_in_memory().map_err(db("open in-memory database"))?;
        Self::init(conn, false)
    }

    fn init(mut conn: Connection, wal: bool) -> Result<Self, StoreError> {
        conn.busy_timeout(std::time::Duration::from_secs(5)).map_err(db("set busy timeout"))?;
        conn.pragma_update(None, "foreign_keys", "ON").map_err(db("enable foreign keys"))?;
        if wal {
            let mode: String = conn
                .pragma_update_and_check(None, "journal_mode", "WAL", |r| r.get(0))
                .map_err(db("enable WAL"))?;
            if !mode.eq_ignore_ascii_case("wal") {
                tracing::warn!(mode, "SQLite did not switch to WAL");
            }
            conn.pragma_update(None, "synchronous", "NORMAL").map_err(db("set synchronous"))?;
        }
        migrate(&mut conn)?;
        Ok(SqliteStore { conn: Mutex::new(conn) })
    }

    /// The schema version of the open database.
    ///
    /// # Errors
    /// A database error.
    pub fn schema_version(&self) -> Result<i64, StoreError> {
        self.lock()?.pragma_query_value(None, "user_version", |r| r.get(0)).map_err(db("read user_version"))
    }

    fn lock(&self) -> Result<MutexGuard<'_, Connection>, StoreError> {
        self.conn.lock().map_err(|_| StoreError::Poisoned)
    }
}

fn migrate(conn: &mut Connection) -> Result<(), StoreError> {
    let found: i64 =
        conn.pragma_query_value(None, "user_version", |r| r.get(0)).map_err(db("read user_version"))?;
    if found > SCHEMA_VERSION {
        return Err(StoreError::SchemaTooNew { found, supported: SCHEMA_VERSION });
    }
    for (i, sql) in MIGRATIONS.iter().enumerate().skip(usize::try_from(found).unwrap_or(0)) {
        let to = i64::try_from(i + 1).unwrap_or(i64::MAX);
        let tx = conn.transaction().map_err(db("begin migration"))?;
        tx.execute_batch(sql).map_err(db("migrate schema"))?;
        tx.pragma_update(None, "user_version", to).map_err(db("write user_version"))?;
        tx.commit().map_err(db("commit migration"))?;
        tracing::info!(version = to, "database schema migrated");
    }
    Ok(())
}

const USER_COLS: &str = "name, role, password_hash, created, updated";
const SESSION_COLS: &str = "token_hash, user_name, csrf_token, created, last_seen, source";
const RES_COLS: &str = "id, station, user_name, start_ms, end_ms, created, ended_by, cleaned";
const ALARM_COLS: &str = "id, code, source, message, severity, raised_at, ack_by, ack_at, cleared_at";
const PROGRAM_COLS: &str = "station, owner, kind, name, exported, size_bytes, created";

/// Raw columns read inside rusqlite callbacks, decoded afterwards with typed errors.
type RawUser = (String, String, String, i64, i64);

fn raw_user(r: &Row<'_>) -> rusqlite::Result<RawUser> {
    Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?))
}

fn user_from(raw: RawUser) -> Result<User, StoreError> {
    let (name, role, password_hash, created, updated) = raw;
    let role: Role = role.parse().map_err(|e| corrupt("user role", e))?;
    Ok(User { name, role, password_hash, created: UnixMs(created), updated: UnixMs(updated) })
}

fn session_from(r: &Row<'_>) -> rusqlite::Result<SessionRecord> {
    Ok(SessionRecord {
        token_hash: r.get(0)?,
        user: r.get(1)?,
        csrf_token: r.get(2)?,
        created: UnixMs(r.get(3)?),
        last_seen: UnixMs(r.get(4)?),
        source: r.get(5)?,
    })
}

fn reservation_from(r: &Row<'_>) -> rusqlite::Result<Reservation> {
    Ok(Reservation {
        id: r.get(0)?,
        station: r.get(1)?,
        user: r.get(2)?,
        start: UnixMs(r.get(3)?),
        end: UnixMs(r.get(4)?),
        created: UnixMs(r.get(5)?),
        ended_by: r.get(6)?,
        cleaned: r.get(7)?,
    })
}

type RawAudit = (i64, i64, String, String, String, String, String);

fn audit_from(raw: RawAudit) -> Result<AuditRecord, StoreError> {
    let (id, time, user, action, target, result, message) = raw;
    let outcome =
        AuditOutcome::from_parts(&result, &message).ok_or_else(|| corrupt("audit result", &result))?;
    Ok(AuditRecord { id, entry: AuditEntry { time: UnixMs(time), user, action, target, outcome } })
}

type RawAlarm = (i64, String, String, String, String, i64, Option<String>, Option<i64>, Option<i64>);

fn raw_alarm(r: &Row<'_>) -> rusqlite::Result<RawAlarm> {
    Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?, r.get(5)?, r.get(6)?, r.get(7)?, r.get(8)?))
}

fn alarm_from(raw: RawAlarm) -> Result<Alarm, StoreError> {
    let (id, code, source, message, severity, raised_at, ack_by, ack_at, cleared_at) = raw;
    let severity = Severity::parse(&severity).ok_or_else(|| corrupt("alarm severity", &severity))?;
    let acknowledged = match (ack_by, ack_at) {
        (Some(by), Some(at)) => Some(Ack { by, at: UnixMs(at) }),
        (None, None) => None,
        _ => return Err(corrupt("alarm acknowledgement", format!("alarm {id}: half an acknowledgement"))),
    };
    Ok(Alarm {
        id,
        code,
        source,
        message,
        severity,
        raised_at: UnixMs(raised_at),
        acknowledged,
        cleared_at: cleared_at.map(UnixMs),
    })
}

type RawProgram = (String, String, String, String, bool, i64, i64);

fn raw_program(r: &Row<'_>) -> rusqlite::Result<RawProgram> {
    Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?, r.get(5)?, r.get(6)?))
}

fn program_from(raw: RawProgram) -> Result<ProgramMeta, StoreError> {
    let (station, owner, kind, name, exported, size, created) = raw;
    Ok(ProgramMeta {
        station,
        owner,
        kind: ProgramKind::parse(&kind).ok_or_else(|| corrupt("program kind", &kind))?,
        name,
        exported,
        size_bytes: u64::try_from(size).map_err(|e| corrupt("program size", e))?,
        created: UnixMs(created),
    })
}

/// Runs `sql` with boxed parameters and collects rows mapped by `f`.
fn query_rows<T>(
    conn: &Connection,
    op: &'static str,
    sql: &str,
    params: &[Box<dyn ToSql>],
    f: impl FnMut(&Row<'_>) -> rusqlite::Result<T>,
) -> Result<Vec<T>, StoreError> {
    let mut stmt = conn.prepare_cached(sql).map_err(db(op))?;
    let refs: Vec<&dyn ToSql> = params.iter().map(AsRef::as_ref).collect();
    let rows = stmt.query_map(refs.as_slice(), f).map_err(db(op))?;
    rows.collect::<Result<Vec<T>, _>>().map_err(db(op))
}

fn reservation_where(filter: &ReservationFilter) -> (String, Vec<Box<dyn ToSql>>) {
    let mut clauses: Vec<&str> = Vec::new();
    let mut params: Vec<Box<dyn ToSql>> = Vec::new();
    if let Some(s) = &filter.station {
        clauses.push("station = ?");
        params.push(Box::new(s.clone()));
    }
    if let Some(u) = &filter.user {
        clauses.push("user_name = ?");
        params.push(Box::new(u.clone()));
    }
    if let Some((from, until)) = filter.window {
        clauses.push("start_ms < ? AND ? < end_ms");
        params.push(Box::new(until.0));
        params.push(Box::new(from.0));
    }
    if let Some(t) = filter.pending_cleanup_at {
        clauses.push("end_ms <= ? AND cleaned = 0");
        params.push(Box::new(t.0));
    }
    let sql = if clauses.is_empty() { String::new() } else { format!(" WHERE {}", clauses.join(" AND ")) };
    (sql, params)
}

impl Store for SqliteStore {
    fn insert_user(&self, u: &User) -> Result<(), StoreError> {
        let conn = self.lock()?;
        let r = conn.execute(
            &format!("INSERT INTO users ({USER_COLS}) VALUES (?1, ?2, ?3, ?4, ?5)"),
            params![u.name, u.role.as_str(), u.password_hash, u.created.0, u.updated.0],
        );
        match r {
            Ok(_) => Ok(()),
            Err(rusqlite::Error::SqliteFailure(e, _))
                if e.code == rusqlite::ErrorCode::ConstraintViolation =>
            {
                Err(StoreError::Conflict { what: "user", key: u.name.clone() })
            }
            Err(e) => Err(db("insert user")(e)),
        }
    }

    fn update_user(&self, u: &User) -> Result<(), StoreError> {
        let n = self
            .lock()?
            .execute(
                "UPDATE users SET role = ?2, password_hash = ?3, updated = ?4 WHERE name = ?1",
                params![u.name, u.role.as_str(), u.password_hash, u.updated.0],
            )
            .map_err(db("update user"))?;
        if n == 0 {
            return Err(StoreError::NotFound { what: "user", key: u.name.clone() });
        }
        Ok(())
    }

    fn get_user(&self, name: &str) -> Result<Option<User>, StoreError> {
        let raw = self
            .lock()?
            .prepare_cached(&format!("SELECT {USER_COLS} FROM users WHERE name = ?1"))
            .and_then(|mut s| s.query_row([name], raw_user).optional())
            .map_err(db("get user"))?;
        raw.map(user_from).transpose()
    }

    fn delete_user(&self, name: &str) -> Result<bool, StoreError> {
        // Sessions go with it (ON DELETE CASCADE).
        let n =
            self.lock()?.execute("DELETE FROM users WHERE name = ?1", [name]).map_err(db("delete user"))?;
        Ok(n > 0)
    }

    fn list_users(&self) -> Result<Vec<User>, StoreError> {
        let conn = self.lock()?;
        let raw = query_rows(
            &conn,
            "list users",
            &format!("SELECT {USER_COLS} FROM users ORDER BY name"),
            &[],
            raw_user,
        )?;
        raw.into_iter().map(user_from).collect()
    }

    fn insert_session(&self, s: &SessionRecord) -> Result<(), StoreError> {
        let conn = self.lock()?;
        let r = conn.execute(
            &format!("INSERT INTO sessions ({SESSION_COLS}) VALUES (?1, ?2, ?3, ?4, ?5, ?6)"),
            params![s.token_hash, s.user, s.csrf_token, s.created.0, s.last_seen.0, s.source],
        );
        match r {
            Ok(_) => Ok(()),
            Err(rusqlite::Error::SqliteFailure(e, msg))
                if e.extended_code == rusqlite::ffi::SQLITE_CONSTRAINT_FOREIGNKEY =>
            {
                tracing::debug!(?msg, "session for a missing user");
                Err(StoreError::NotFound { what: "user", key: s.user.clone() })
            }
            Err(rusqlite::Error::SqliteFailure(e, _))
                if e.code == rusqlite::ErrorCode::ConstraintViolation =>
            {
                Err(StoreError::Conflict { what: "session", key: s.token_hash.clone() })
            }
            Err(e) => Err(db("insert session")(e)),
        }
    }

    fn get_session(&self, token_hash: &str) -> Result<Option<SessionRecord>, StoreError> {
        self.lock()?
            .prepare_cached(&format!("SELECT {SESSION_COLS} FROM sessions WHERE token_hash = ?1"))
            .and_then(|mut s| s.query_row([token_hash], session_from).optional())
            .map_err(db("get session"))
    }

    fn touch_session(&self, token_hash: &str, last_seen: UnixMs) -> Result<(), StoreError> {
        self.lock()?
            .prepare_cached("UPDATE sessions SET last_seen = ?2 WHERE token_hash = ?1")
            .and_then(|mut s| s.execute(params![token_hash, last_seen.0]))
            .map_err(db("touch session"))?;
        Ok(())
    }

    fn delete_session(&self, token_hash: &str) -> Result<bool, StoreError> {
        let n = self
            .lock()?
            .execute("DELETE FROM sessions WHERE token_hash = ?1", [token_hash])
            .map_err(db("delete session"))?;
        Ok(n > 0)
    }

    fn delete_user_sessions(&self, user: &str) -> Result<usize, StoreError> {
        self.lock()?
            .execute("DELETE FROM sessions WHERE user_name = ?1", [user])
            .map_err(db("delete user sessions"))
    }

    fn delete_stale_sessions(&self, created_by: UnixMs, seen_by: UnixMs) -> Result<usize, StoreError> {
        self.lock()?
            .execute(
                "DELETE FROM sessions WHERE created <= ?1 OR last_seen <= ?2",
                params![created_by.0, seen_by.0],
            )
            .map_err(db("purge sessions"))
    }

    fn list_sessions(&self, user: Option<&str>) -> Result<Vec<SessionRecord>, StoreError> {
        let conn = self.lock()?;
        let sql = format!(
            "SELECT {SESSION_COLS} FROM sessions WHERE (?1 IS NULL OR user_name = ?1) ORDER BY created, token_hash"
        );
        query_rows(&conn, "list sessions", &sql, &[Box::new(user.map(str::to_string))], session_from)
    }

    fn insert_reservation_if_free(&self, r: &NewReservation) -> Result<BookOutcome, StoreError> {
        let mut conn = self.lock()?;
        // IMMEDIATE: take the write lock before reading, so no other process can book in
        // between the overlap check and the insert.
        let tx =
            conn.transaction_with_behavior(TransactionBehavior::Immediate).map_err(db("begin booking"))?;
        let clash = tx
            .prepare_cached(&format!(
                "SELECT {RES_COLS} FROM reservations WHERE station = ?1 AND start_ms < ?3 AND ?2 < end_ms \
                 ORDER BY start_ms, id LIMIT 1"
            ))
            .and_then(|mut s| {
                s.query_row(params![r.station, r.start.0, r.end.0], reservation_from).optional()
            })
            .map_err(db("check overlap"))?;
        if let Some(other) = clash {
            return Ok(BookOutcome::Overlaps(other));
        }
        tx.execute(
            "INSERT INTO reservations (station, user_name, start_ms, end_ms, created) VALUES (?1, ?2, ?3, ?4, ?5)",
            params![r.station, r.user, r.start.0, r.end.0, r.created.0],
        )
        .map_err(db("insert reservation"))?;
        let id = tx.last_insert_rowid();
        tx.commit().map_err(db("commit booking"))?;
        Ok(BookOutcome::Booked(id))
    }

    fn get_reservation(&self, id: i64) -> Result<Option<Reservation>, StoreError> {
        self.lock()?
            .prepare_cached(&format!("SELECT {RES_COLS} FROM reservations WHERE id = ?1"))
            .and_then(|mut s| s.query_row([id], reservation_from).optional())
            .map_err(db("get reservation"))
    }

    fn update_reservation(&self, r: &Reservation) -> Result<(), StoreError> {
        let n = self
            .lock()?
            .execute(
                "UPDATE reservations SET end_ms = ?2, ended_by = ?3, cleaned = ?4 WHERE id = ?1",
                params![r.id, r.end.0, r.ended_by, r.cleaned],
            )
            .map_err(db("update reservation"))?;
        if n == 0 {
            return Err(StoreError::NotFound { what: "reservation", key: r.id.to_string() });
        }
        Ok(())
    }

    fn delete_reservation(&self, id: i64) -> Result<bool, StoreError> {
        let n = self
            .lock()?
            .execute("DELETE FROM reservations WHERE id = ?1", [id])
            .map_err(db("delete reservation"))?;
        Ok(n > 0)
    }

    fn list_reservations(&self, filter: &ReservationFilter) -> Result<Vec<Reservation>, StoreError> {
        let (wh, params) = reservation_where(filter);
        let sql = format!("SELECT {RES_COLS} FROM reservations{wh} ORDER BY start_ms, id");
        let conn = self.lock()?;
        query_rows(&conn, "list reservations", &sql, &params, reservation_from)
    }

    fn append_audit(&self, e: &AuditEntry) -> Result<i64, StoreError> {
        let conn = self.lock()?;
        conn.prepare_cached(
            "INSERT INTO audit (time, user_name, action, target, result, message) VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
        )
        .and_then(|mut s| {
            s.execute(params![e.time.0, e.user, e.action, e.target, e.outcome.kind(), e.outcome.message()])
        })
        .map_err(db("append audit"))?;
        Ok(conn.last_insert_rowid())
    }

    fn query_audit(&self, q: &AuditQuery) -> Result<Vec<AuditRecord>, StoreError> {
        let mut clauses: Vec<&str> = Vec::new();
        let mut params: Vec<Box<dyn ToSql>> = Vec::new();
        if let Some(u) = &q.user {
            clauses.push("user_name = ?");
            params.push(Box::new(u.clone()));
        }
        if let Some(p) = &q.action_prefix {
            // substr instead of LIKE: no wildcard escaping needed.
            clauses.push("substr(action, 1, length(?)) = ?");
            params.push(Box::new(p.clone()));
            params.push(Box::new(p.clone()));
        }
        if let Some(o) = &q.outcome {
            clauses.push("result = ?");
            params.push(Box::new(o.clone()));
        }
        if let Some(t) = q.since {
            clauses.push("time >= ?");
            params.push(Box::new(t.0));
        }
        if let Some(t) = q.until {
            clauses.push("time < ?");
            params.push(Box::new(t.0));
        }
        let wh = if clauses.is_empty() { String::new() } else { format!(" WHERE {}", clauses.join(" AND ")) };
        params.push(Box::new(limit_i64(q.limit)));
        let sql = format!(
            "SELECT id, time, user_name, action, target, result, message FROM audit{wh} ORDER BY id DESC LIMIT ?"
        );
        let conn = self.lock()?;
        let raw = query_rows(&conn, "query audit", &sql, &params, |r| {
            Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?, r.get(5)?, r.get(6)?))
        })?;
        raw.into_iter().map(audit_from).collect()
    }

    fn insert_alarm(&self, a: &Alarm) -> Result<i64, StoreError> {
        let conn = self.lock()?;
        conn.execute(
            "INSERT INTO alarms (code, source, message, severity, raised_at, ack_by, ack_at, cleared_at) \
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
            params![
                a.code,
                a.source,
                a.message,
                a.severity.as_str(),
                a.raised_at.0,
                a.acknowledged.as_ref().map(|k| k.by.clone()),
                a.acknowledged.as_ref().map(|k| k.at.0),
                a.cleared_at.map(|t| t.0)
            ],
        )
        .map_err(db("insert alarm"))?;
        Ok(conn.last_insert_rowid())
    }

    fn update_alarm(&self, a: &Alarm) -> Result<(), StoreError> {
        let n = self
            .lock()?
            .execute(
                "UPDATE alarms SET ack_by = ?2, ack_at = ?3, cleared_at = ?4 WHERE id = ?1",
                params![
                    a.id,
                    a.acknowledged.as_ref().map(|k| k.by.clone()),
                    a.acknowledged.as_ref().map(|k| k.at.0),
                    a.cleared_at.map(|t| t.0)
                ],
            )
            .map_err(db("update alarm"))?;
        if n == 0 {
            return Err(StoreError::NotFound { what: "alarm", key: a.id.to_string() });
        }
        Ok(())
    }

    fn get_alarm(&self, id: i64) -> Result<Option<Alarm>, StoreError> {
        let raw = self
            .lock()?
            .prepare_cached(&format!("SELECT {ALARM_COLS} FROM alarms WHERE id = ?1"))
            .and_then(|mut s| s.query_row([id], raw_alarm).optional())
            .map_err(db("get alarm"))?;
        raw.map(alarm_from).transpose()
    }

    fn list_alarms(&self, q: &AlarmQuery) -> Result<Vec<Alarm>, StoreError> {
        let sql = format!(
            "SELECT {ALARM_COLS} FROM alarms WHERE (?1 = 0 OR cleared_at IS NULL OR ack_at IS NULL) \
             AND (?2 IS NULL OR raised_at >= ?2) ORDER BY raised_at DESC, id DESC LIMIT ?3"
        );
        let conn = self.lock()?;
        let params: [Box<dyn ToSql>; 3] =
            [Box::new(q.active_only), Box::new(q.since.map(|t| t.0)), Box::new(limit_i64(q.limit))];
        let raw = query_rows(&conn, "list alarms", &sql, &params, raw_alarm)?;
        raw.into_iter().map(alarm_from).collect()
    }

    fn upsert_program(&self, p: &ProgramMeta) -> Result<(), StoreError> {
        let size = i64::try_from(p.size_bytes).map_err(|e| corrupt("program size", e))?;
        self.lock()?
            .execute(
                &format!(
                    "INSERT OR REPLACE INTO programs ({PROGRAM_COLS}) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)"
                ),
                params![p.station, p.owner, p.kind.as_str(), p.name, p.exported, size, p.created.0],
            )
            .map_err(db("upsert program"))?;
        Ok(())
    }

    fn list_programs(
        &self,
        station: Option<&str>,
        owner: Option<&str>,
    ) -> Result<Vec<ProgramMeta>, StoreError> {
        let sql = format!(
            "SELECT {PROGRAM_COLS} FROM programs WHERE (?1 IS NULL OR station = ?1) AND (?2 IS NULL OR owner = ?2) \
             ORDER BY station, owner, kind, name"
        );
        let conn = self.lock()?;
        let params: [Box<dyn ToSql>; 2] =
            [Box::new(station.map(str::to_string)), Box::new(owner.map(str::to_string))];
        let raw = query_rows(&conn, "list programs", &sql, &params, raw_program)?;
        raw.into_iter().map(program_from).collect()
    }

    fn delete_program(
        &self,
        station: &str,
        owner: &str,
        kind: ProgramKind,
        name: &str,
    ) -> Result<bool, StoreError> {
        let n = self
            .lock()?
            .execute(
                "DELETE FROM programs WHERE station = ?1 AND owner = ?2 AND kind = ?3 AND name = ?4",
                params![station, owner, kind.as_str(), name],
            )
            .map_err(db("delete program"))?;
        Ok(n > 0)
    }
}
