//! The audit log: who did what, when, to what, with which result.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::authz::{Action, Actor};
use crate::store::{Store, StoreError};
use crate::time::UnixMs;

/// The result of an audited action.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "result", content = "message", rename_all = "snake_case")]
pub enum AuditOutcome {
    /// Done.
    Ok,
    /// Refused by the rules (why).
    Denied(String),
    /// Allowed but failed (why).
    Error(String),
}

impl AuditOutcome {
    /// `ok`, `denied` or `error`.
    #[must_use]
    pub fn kind(&self) -> &'static str {
        match self {
            AuditOutcome::Ok => "ok",
            AuditOutcome::Denied(_) => "denied",
            AuditOutcome::Error(_) => "error",
        }
    }

    /// The message (empty for `Ok`).
    #[must_use]
    pub fn message(&self) -> &str {
        match self {
            AuditOutcome::Ok => "",
            AuditOutcome::Denied(m) | AuditOutcome::Error(m) => m,
        }
    }

    /// Rebuilds an outcome from its stored kind and message.
    #[must_use]
    pub fn from_parts(kind: &str, message: &str) -> Option<Self> {
        match kind {
            "ok" => Some(AuditOutcome::Ok),
            "denied" => Some(AuditOutcome::Denied(message.to_string())),
            "error" => Some(AuditOutcome::Error(message.to_string())),
            _ => None,
        }
    }
}

/// One entry of the log.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct AuditEntry {
    /// When.
    pub time: UnixMs,
    /// Who (a user name; the attempted name for a failed login; `console` for the CLI).
    pub user: String,
    /// What (see [`Action::name`]; also `login`, `logout`, `cleanup`...).
    pub action: String,
    /// On what (see [`Action::target`]).
    pub target: String,
    /// Result.
    pub outcome: AuditOutcome,
}

/// A stored entry.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct AuditRecord {
    /// Increasing id.
    pub id: i64,
    /// The entry.
    pub entry: AuditEntry,
}

/// Which entries [`Audit::query`] returns (filters combine with AND), newest first.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct AuditQuery {
    /// Only this user's.
    pub user: Option<String>,
    /// Only actions starting with this prefix (`command.` gives every command).
    pub action_prefix: Option<String>,
    /// Only this result kind (`ok`, `denied`, `error`).
    pub outcome: Option<String>,
    /// Only at or after.
    pub since: Option<UnixMs>,
    /// Only before.
    pub until: Option<UnixMs>,
    /// At most this many (default 100).
    pub limit: usize,
}

impl Default for AuditQuery {
    fn default() -> Self {
        AuditQuery { user: None, action_prefix: None, outcome: None, since: None, until: None, limit: 100 }
    }
}

impl AuditQuery {
    /// True if `e` passes the filters (the limit aside).
    #[must_use]
    pub fn matches(&self, e: &AuditEntry) -> bool {
        self.user.as_ref().map_or(true, |u| *u == e.user)
            && self.action_prefix.as_ref().map_or(true, |p| e.action.starts_with(p.as_str()))
            && self.outcome.as_ref().map_or(true, |o| o == e.outcome.kind())
            && self.since.map_or(true, |t| e.time >= t)
            && self.until.map_or(true, |t| e.time < t)
    }
}

/// The audit log over a [`Store`].
pub struct Audit {
    store: Arc<dyn Store>,
}

impl Audit {
    /// The log in `store`.
    #[must_use]
    pub fn new(store: Arc<dyn Store>) -> Self {
        Audit { store }
    }

    /// Appends an entry; returns its id.
    ///
    /// # Errors
    /// A storage failure.
    pub fn append(&self, entry: &AuditEntry) -> Result<i64, StoreError> {
        self.store.append_audit(entry)
    }

    /// Appends the result of `action` by `actor`.
    ///
    /// # Errors
    /// A storage failure.
    pub fn record(
        &self,
        actor: &Actor,
        action: &Action,
        outcome: AuditOutcome,
        now: UnixMs,
    ) -> Result<i64, StoreError> {
        self.append(&AuditEntry {
            time: now,
            user: actor.name.clone(),
            action: action.name(),
            target: action.target(),
            outcome,
        })
    }

    /// Entries passing `query`, newest first.
    ///
    /// # Errors
    /// A storage failure.
    pub fn query(&self, query: &AuditQuery) -> Result<Vec<AuditRecord>, StoreError> {
        self.store.query_audit(query)
    }
}
