//! Alarms: raised with a time stamp, acknowledged by a user, cleared when the condition is
//! gone; an alarm stays *active* until it is both cleared and acknowledged, and stays in the
//! history for good.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::store::{Store, StoreError};
use crate::time::UnixMs;

/// How serious an alarm is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Severity {
    /// Information.
    Info,
    /// Needs attention.
    Warning,
    /// Motion is blocked or a function failed.
    Error,
    /// Safety-relevant.
    Critical,
}

impl Severity {
    /// Storage name.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        match self {
            Severity::Info => "info",
            Severity::Warning => "warning",
            Severity::Error => "error",
            Severity::Critical => "critical",
        }
    }

    /// Parses a storage name.
    #[must_use]
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "info" => Some(Severity::Info),
            "warning" => Some(Severity::Warning),
            "error" => Some(Severity::Error),
            "critical" => Some(Severity::Critical),
            _ => None,
        }
    }
}

/// An acknowledgement.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Ack {
    /// Who.
    pub by: String,
    /// When.
    pub at: UnixMs,
}

/// One alarm occurrence.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Alarm {
    /// Id (assigned by the store).
    pub id: i64,
    /// Machine-readable code (`axis_config_wrong`, `safe_to_run_false`...).
    pub code: String,
    /// Where (`st1/axis2`, `supervisor`...).
    pub source: String,
    /// Text for people.
    pub message: String,
    /// Severity.
    pub severity: Severity,
    /// When raised.
    pub raised_at: UnixMs,
    /// Acknowledgement, if any.
    pub acknowledged: Option<Ack>,
    /// When the condition went away, if it has.
    pub cleared_at: Option<UnixMs>,
}

impl Alarm {
    /// Active: not yet both cleared and acknowledged.
    #[must_use]
    pub fn is_active(&self) -> bool {
        self.cleared_at.is_none() || self.acknowledged.is_none()
    }
}

/// Which alarms [`Store::list_alarms`] returns, newest first.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct AlarmQuery {
    /// Only active ones.
    pub active_only: bool,
    /// Only those raised at or after.
    pub since: Option<UnixMs>,
    /// At most this many (default 1000).
    pub limit: usize,
}

impl Default for AlarmQuery {
    fn default() -> Self {
        AlarmQuery { active_only: false, since: None, limit: 1000 }
    }
}

impl AlarmQuery {
    /// True if `a` passes the filters (the limit aside).
    #[must_use]
    pub fn matches(&self, a: &Alarm) -> bool {
        (!self.active_only || a.is_active()) && self.since.map_or(true, |t| a.raised_at >= t)
    }
}

/// Result of [`Alarms::acknowledge`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum AckOutcome {
    /// Acknowledged now.
    Acknowledged(Alarm),
    /// It already was (by the [`Ack`] inside); nothing changed.
    AlreadyAcknowledged(Alarm),
    /// No such alarm.
    NotFound,
}

/// Alarms over a [`Store`].
pub struct Alarms {
    store: Arc<dyn Store>,
}

impl Alarms {
    /// Alarms in `store`.
    #[must_use]
    pub fn new(store: Arc<dyn Store>) -> Self {
        Alarms { store }
    }

    /// Raises an alarm. If one with the same code and source is raised and not yet cleared,
    /// no duplicate is made: its id is returned.
    ///
    /// # Errors
    /// A storage failure.
    pub fn raise(
        &self,
        code: &str,
        source: &str,
        message: &str,
        severity: Severity,
        now: UnixMs,
    ) -> Result<i64, StoreError> {
        if let Some(a) = self.uncleared(code, source)?.into_iter().next() {
            return Ok(a.id);
        }
        let id = self.store.insert_alarm(&Alarm {
            id: 0,
            code: code.to_string(),
            source: source.to_string(),
            message: message.to_string(),
            severity,
            raised_at: now,
            acknowledged: None,
            cleared_at: None,
        })?;
        tracing::warn!(id, code, source, severity = severity.as_str(), message, "alarm raised");
        Ok(id)
    }

    fn uncleared(&self, code: &str, source: &str) -> Result<Vec<Alarm>, StoreError> {
        Ok(self
            .store
            .list_alarms(&AlarmQuery { active_only: true, since: None, limit: usize::MAX })?
            .into_iter()
            .filter(|a| a.code == code && a.source == source && a.cleared_at.is_none())
            .collect())
    }

    /// Acknowledges alarm `id` by `by` at `now`.
    ///
    /// # Errors
    /// A storage failure.
    pub fn acknowledge(&self, id: i64, by: &str, now: UnixMs) -> Result<AckOutcome, StoreError> {
        let Some(mut a) = self.store.get_alarm(id)? else { return Ok(AckOutcome::NotFound) };
        if a.acknowledged.is_some() {
            return Ok(AckOutcome::AlreadyAcknowledged(a));
        }
        a.acknowledged = Some(Ack { by: by.to_string(), at: now });
        self.store.update_alarm(&a)?;
        Ok(AckOutcome::Acknowledged(a))
    }

    /// Clears the uncleared alarms with this code and source (the condition is gone);
    /// returns how many.
    ///
    /// # Errors
    /// A storage failure.
    pub fn clear(&self, code: &str, source: &str, now: UnixMs) -> Result<usize, StoreError> {
        let open = self.uncleared(code, source)?;
        for mut a in open.iter().cloned() {
            a.cleared_at = Some(now);
            self.store.update_alarm(&a)?;
        }
        Ok(open.len())
    }

    /// Active alarms, newest first.
    ///
    /// # Errors
    /// A storage failure.
    pub fn active(&self) -> Result<Vec<Alarm>, StoreError> {
        self.store.list_alarms(&AlarmQuery { active_only: true, since: None, limit: usize::MAX })
    }

    /// The history (every alarm), newest first, at most `limit`.
    ///
    /// # Errors
    /// A storage failure.
    pub fn history(&self, limit: usize) -> Result<Vec<Alarm>, StoreError> {
        self.store.list_alarms(&AlarmQuery { active_only: false, since: None, limit })
    }

    /// One alarm.
    ///
    /// # Errors
    /// A storage failure.
    pub fn get(&self, id: i64) -> Result<Option<Alarm>, StoreError> {
        self.store.get_alarm(id)
    }
}
