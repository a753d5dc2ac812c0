//! A [`Store`] in memory (tests, simulations). Same semantics as the SQLite store.

use std::collections::BTreeMap;
use std::sync::{Mutex, MutexGuard};

use super::{BookOutcome, ReservationFilter, Store, StoreError};
use crate::alarm::{Alarm, AlarmQuery};
use crate::audit::{AuditEntry, AuditQuery, AuditRecord};
use crate::program::{ProgramKind, ProgramMeta};
use crate::reservation::{NewReservation, Reservation};
use crate::session::SessionRecord;
use crate::time::UnixMs;
use crate::users::User;

type ProgramKey = (String, String, ProgramKind, String);

#[derive(Default)]
struct Inner {
    users: BTreeMap<String, User>,
    sessions: BTreeMap<String, SessionRecord>,
    reservations: BTreeMap<i64, Reservation>,
    audit: Vec<AuditRecord>,
    alarms: BTreeMap<i64, Alarm>,
    programs: BTreeMap<ProgramKey, ProgramMeta>,
    next_id: i64,
}

impl Inner {
    fn id(&mut self) -> i64 {
        self.next_id += 1;
        self.next_id
    }
}

/// Everything in memory behind one lock; lost when dropped.
#[derive(Default)]
pub struct MemoryStore {
    inner: Mutex<Inner>,
}

impl MemoryStore {
    /// An empty store.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    fn lock(&self) -> Result<MutexGuard<'_, Inner>, StoreError> {
        self.inner.lock().map_err(|_| StoreError::Poisoned)
    }
}

fn not_found(what: &'static str, key: impl ToString) -> StoreError {
    StoreError::NotFound { what, key: key.to_string() }
}

impl Store for MemoryStore {
    fn insert_user(&self, user: &User) -> Result<(), StoreError> {
        let mut g = self.lock()?;
        if g.users.contains_key(&user.name) {
            return Err(StoreError::Conflict { what: "user", key: user.name.clone() });
        }
        g.users.insert(user.name.clone(), user.clone());
        Ok(())
    }

    fn update_user(&self, user: &User) -> Result<(), StoreError> {
        let mut g = self.lock()?;
        let u = g.users.get_mut(&user.name).ok_or_else(|| not_found("user", &user.name))?;
        u.role = user.role;
        u.password_hash.clone_from(&user.password_hash);
        u.updated = user.updated;
        Ok(())
    }

    fn get_user(&self, name: &str) -> Result<Option<User>, StoreError> {
        Ok(self.lock()?.users.get(name).cloned())
    }

    fn delete_user(&self, name: &str) -> Result<bool, StoreError> {
        let mut g = self.lock()?;
        g.sessions.retain(|_, s| s.user != name);
        Ok(g.users.remove(name).is_some())
    }

    fn list_users(&self) -> Result<Vec<User>, StoreError> {
        Ok(self.lock()?.users.values().cloned().collect())
    }

    fn insert_session(&self, session: &SessionRecord) -> Result<(), StoreError> {
        let mut g = self.lock()?;
        if !g.users.contains_key(&session.user) {
            return Err(not_found("user", &session.user));
        }
        if g.sessions.contains_key(&session.token_hash) {
            return Err(StoreError::Conflict { what: "session", key: session.token_hash.clone() });
        }
        g.sessions.insert(session.token_hash.clone(), session.clone());
        Ok(())
    }

    fn get_session(&self, token_hash: &str) -> Result<Option<SessionRecord>, StoreError> {
        Ok(self.lock()?.sessions.get(token_hash).cloned())
    }

    fn touch_session(&self, token_hash: &str, last_seen: UnixMs) -> Result<(), StoreError> {
        if let Some(s) = self.lock()?.sessions.get_mut(token_hash) {
            s.last_seen = last_seen;
        }
        Ok(())
    }

    fn delete_session(&self, token_hash: &str) -> Result<bool, StoreError> {
        Ok(self.lock()?.sessions.remove(token_hash).is_some())
    }

    fn delete_user_sessions(&self, user: &str) -> Result<usize, StoreError> {
        let mut g = self.lock()?;
        let before = g.sessions.len();
        g.sessions.retain(|_, s| s.user != user);
        Ok(before - g.sessions.len())
    }

    fn delete_stale_sessions(&self, created_by: UnixMs, seen_by: UnixMs) -> Result<usize, StoreError> {
        let mut g = self.lock()?;
        let before = g.sessions.len();
        g.sessions.retain(|_, s| s.created > created_by && s.last_seen > seen_by);
        Ok(before - g.sessions.len())
    }

    fn list_sessions(&self, user: Option<&str>) -> Result<Vec<SessionRecord>, StoreError> {
        let mut v: Vec<SessionRecord> =
            self.lock()?.sessions.values().filter(|s| user.map_or(true, |u| s.user == u)).cloned().collect();
        v.sort_by(|a, b| (a.created, &a.token_hash).cmp(&(b.created, &b.token_hash)));
        Ok(v)
    }

    fn insert_reservation_if_free(&self, r: &NewReservation) -> Result<BookOutcome, StoreError> {
        let mut g = self.lock()?;
        let clash = g
            .reservations
            .values()
            .filter(|o| o.station == r.station && o.start < r.end && r.start < o.end)
            .min_by_key(|o| (o.start, o.id))
            .cloned();
        if let Some(o) = clash {
            return Ok(BookOutcome::Overlaps(o));
        }
        let id = g.id();
        g.reservations.insert(
            id,
            Reservation {
                id,
                station: r.station.clone(),
                user: r.user.clone(),
                start: r.start,
                end: r.end,
                created: r.created,
                ended_by: None,
                cleaned: false,
            },
        );
        Ok(BookOutcome::Booked(id))
    }

    fn get_reservation(&self, id: i64) -> Result<Option<Reservation>, StoreError> {
        Ok(self.lock()?.reservations.get(&id).cloned())
    }

    fn update_reservation(&self, r: &Reservation) -> Result<(), StoreError> {
        let mut g = self.lock()?;
        let o = g.reservations.get_mut(&r.id).ok_or_else(|| not_found("reservation", r.id))?;
        o.end = r.end;
        o.ended_by.clone_from(&r.ended_by);
        o.cleaned = r.cleaned;
        Ok(())
    }

    fn delete_reservation(&self, id: i64) -> Result<bool, StoreError> {
        Ok(self.lock()?.reservations.remove(&id).is_some())
    }

    fn list_reservations(&self, filter: &ReservationFilter) -> Result<Vec<Reservation>, StoreError> {
        let mut v: Vec<Reservation> =
            self.lock()?.reservations.values().filter(|r| filter.matches(r)).cloned().collect();
        v.sort_by_key(|r| (r.start, r.id));
        Ok(v)
    }

    fn append_audit(&self, entry: &AuditEntry) -> Result<i64, StoreError> {
        let mut g = self.lock()?;
        let id = g.id();
        g.audit.push(AuditRecord { id, entry: entry.clone() });
        Ok(id)
    }

    fn query_audit(&self, query: &AuditQuery) -> Result<Vec<AuditRecord>, StoreError> {
        Ok(self
            .lock()?
            .audit
            .iter()
            .rev()
            .filter(|r| query.matches(&r.entry))
            .take(query.limit)
            .cloned()
            .collect())
    }

    fn insert_alarm(&self, alarm: &Alarm) -> Result<i64, StoreError> {
        let mut g = self.lock()?;
        let id = g.id();
        g.alarms.insert(id, Alarm { id, ..alarm.clone() });
        Ok(id)
    }

    fn update_alarm(&self, alarm: &Alarm) -> Result<(), StoreError> {
        let mut g = self.lock()?;
        let a = g.alarms.get_mut(&alarm.id).ok_or_else(|| not_found("alarm", alarm.id))?;
        a.acknowledged.clone_from(&alarm.acknowledged);
        a.cleared_at = alarm.cleared_at;
        Ok(())
    }

    fn get_alarm(&self, id: i64) -> Result<Option<Alarm>, StoreError> {
        Ok(self.lock()?.alarms.get(&id).cloned())
    }

    fn list_alarms(&self, query: &AlarmQuery) -> Result<Vec<Alarm>, StoreError> {
        let mut v: Vec<Alarm> = self.lock()?.alarms.values().filter(|a| query.matches(a)).cloned().collect();
        v.sort_by_key(|a| std::cmp::Reverse((a.raised_at, a.id)));
        v.truncate(query.limit);
        Ok(v)
    }

    fn upsert_program(&self, p: &ProgramMeta) -> Result<(), StoreError> {
        let key = (p.station.clone(), p.owner.clone(), p.kind, p.name.clone());
        self.lock()?.programs.insert(key, p.clone());
        Ok(())
    }

    fn list_programs(
        &self,
        station: Option<&str>,
        owner: Option<&str>,
    ) -> Result<Vec<ProgramMeta>, StoreError> {
        Ok(self
            .lock()?
            .programs
            .values()
            .filter(|p| station.map_or(true, |s| p.station == s) && owner.map_or(true, |o| p.owner == o))
            .cloned()
            .collect())
    }

    fn delete_program(
        &self,
        station: &str,
        owner: &str,
        kind: ProgramKind,
        name: &str,
    ) -> Result<bool, StoreError> {
        let key = (station.to_string(), owner.to_string(), kind, name.to_string());
        Ok(self.lock()?.programs.remove(&key).is_some())
    }
}
