//! Login rate limiting per user name and per client address, with growing lock-outs.
//!
//! Each key (the attempted user name, and the client address — IPv6 grouped by /64) counts
//! failed logins in a sliding window. Reaching the key's threshold locks it: the first
//! lock-out lasts `lockout_secs`, each further one twice as long as the last (up to
//! `max_lockout_secs`). A success clears the user-name key; the address key is cleared only
//! by time, so one valid account cannot be used to reset an attacker's address. A lock-out
//! of a user name can be caused by anyone who knows it (the usual trade-off; admins can log
//! in from the console with `motus user`). The state is in memory: a restart clears it.
//!
//! A login reserves its attempt with [`LoginLimiter::reserve`] *before* the password is
//! checked: the reservation counts as a failure of both keys at once (and may start their
//! lock-out), so concurrent attempts cannot all pass the check while the slow hashes run:
//! N concurrent wrong passwords for one name check at most `user_max_failures` of them.
//! The outcome then settles the reservation: [`LoginLimiter::failed`] keeps the failure,
//! [`LoginLimiter::succeeded`] gives it back and clears the user name as before, and
//! [`LoginLimiter::release`] gives it back when no password was checked (busy, error).

use std::collections::{HashMap, VecDeque};
use std::net::IpAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::time::UnixMs;

/// Thresholds of the limiter.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LimiterPolicy {
    /// Failures of one user name within the window that lock it (default 5).
    pub user_max_failures: u32,
    /// Failures from one address within the window that lock it (default 20: a class
    /// behind one NAT address shares it).
    pub ip_max_failures: u32,
    /// Sliding window (default 300 s).
    pub window_secs: u64,
    /// First lock-out (default 300 s); each following one doubles.
    pub lockout_secs: u64,
    /// Longest lock-out (default 3600 s).
    pub max_lockout_secs: u64,
    /// Keys kept before stale ones are pruned (bounds memory; default 100 000).
    pub max_keys: usize,
}

impl Default for LimiterPolicy {
    fn default() -> Self {
        LimiterPolicy {
            user_max_failures: 5,
            ip_max_failures: 20,
            window_secs: 300,
            lockout_secs: 300,
            max_lockout_secs: 3600,
            max_keys: 100_000,
        }
    }
}

/// What is being limited.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum LimitKey {
    /// An attempted user name.
    User(String),
    /// A client address (IPv6 reduced to its /64 prefix).
    Ip(IpAddr),
}

/// A login refused before checking the password.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("too many failed logins for {key:?}; retry in {} s", retry_after.as_secs())]
pub struct RateLimited {
    /// The locked key (the one locked longest when both are).
    pub key: LimitKey,
    /// How long until a login may be tried again.
    pub retry_after: Duration,
}

#[derive(Debug, Default)]
struct KeyState {
    /// Failures in the window: when, and the reserved attempt that counted it (0: recorded
    /// by [`LoginLimiter::record_failure`]).
    failures: VecDeque<(UnixMs, u64)>,
    locked_until: Option<UnixMs>,
    /// The attempt whose reservation started the lock-out in force (0: none or a recorded
    /// failure).
    locked_by: u64,
    last_lockout: Option<Duration>,
    last_event: UnixMs,
}

/// What one counted failure changed on one key, to give it back exactly.
#[derive(Debug)]
struct Counted {
    key: LimitKey,
    /// The failure started a lock-out: the state it replaced.
    locked: Option<Replaced>,
}

#[derive(Debug)]
struct Replaced {
    locked_until: Option<UnixMs>,
    last_lockout: Option<Duration>,
    /// The failures the lock-out cleared (without this attempt's).
    failures: VecDeque<(UnixMs, u64)>,
}

/// A login attempt reserved by [`LoginLimiter::reserve`]: counted as a failure of its user
/// name and address until [`LoginLimiter::succeeded`] or [`LoginLimiter::release`] gives it
/// back. [`LoginLimiter::failed`] (or dropping it) keeps the failure.
#[derive(Debug)]
#[must_use = "settle the attempt with failed, succeeded or release"]
pub struct Attempt {
    id: u64,
    user: String,
    counted: Vec<Counted>,
    lockout: Option<RateLimited>,
}

impl Attempt {
    /// The lock-out this attempt's failure started (it holds back later attempts; this
    /// one is still checked), if any.
    #[must_use]
    pub fn lockout(&self) -> Option<&RateLimited> {
        self.lockout.as_ref()
    }
}

/// The login limiter. Shared between request handlers (`&self` methods, internal lock).
#[derive(Debug)]
pub struct LoginLimiter {
    policy: LimiterPolicy,
    keys: Mutex<HashMap<LimitKey, KeyState>>,
    next_attempt: AtomicU64,
}

/// The address key: IPv4 as is, IPv6 by /64 (one subscriber usually holds a whole /64).
#[must_use]
pub fn ip_key(ip: IpAddr) -> IpAddr {
    match ip {
        IpAddr::V4(_) => ip,
        IpAddr::V6(v6) => match v6.to_ipv4_mapped() {
            Some(v4) => IpAddr::V4(v4),
            None => IpAddr::V6((u128::from(v6) & !((1u128 << 64) - 1)).into()),
        },
    }
}

impl LoginLimiter {
    /// A limiter with no history.
    #[must_use]
    pub fn new(policy: LimiterPolicy) -> Self {
        LoginLimiter { policy, keys: Mutex::new(HashMap::new()), next_attempt: AtomicU64::new(1) }
    }

    /// The thresholds in force.
    #[must_use]
    pub fn policy(&self) -> &LimiterPolicy {
        &self.policy
    }

    fn keys(user: &str, ip: IpAddr) -> [(LimitKey, bool); 2] {
        [(LimitKey::User(user.to_string()), true), (LimitKey::Ip(ip_key(ip)), false)]
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<LimitKey, KeyState>> {
        // A panic while holding this lock cannot leave the map inconsistent in a way that
        // matters for limiting, so a poisoned lock is used as is.
        self.keys.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// May `user` try to log in from `ip` at `now`?
    ///
    /// # Errors
    /// [`RateLimited`] with the longer remaining lock-out of the two keys.
    pub fn check(&self, user: &str, ip: IpAddr, now: UnixMs) -> Result<(), RateLimited> {
        Self::check_map(&self.lock(), user, ip, now)
    }

    fn check_map(
        map: &HashMap<LimitKey, KeyState>,
        user: &str,
        ip: IpAddr,
        now: UnixMs,
    ) -> Result<(), RateLimited> {
        let mut worst: Option<RateLimited> = None;
        for (key, _) in Self::keys(user, ip) {
            if let Some(until) = map.get(&key).and_then(|s| s.locked_until) {
                if until > now {
                    let retry_after = until.since(now);
                    if worst.as_ref().map_or(true, |w| retry_after > w.retry_after) {
                        worst = Some(RateLimited { key, retry_after });
                    }
                }
            }
        }
        worst.map_or(Ok(()), Err)
    }

    /// Reserves a login attempt of `user` from `ip` at `now`, before its password is
    /// checked: refused if either key is locked; otherwise counted at once as a failure of
    /// both keys (which may lock them for the following attempts). Settle it with
    /// [`LoginLimiter::failed`], [`LoginLimiter::succeeded`] or [`LoginLimiter::release`].
    ///
    /// # Errors
    /// [`RateLimited`] with the longer remaining lock-out of the two keys (nothing counted).
    pub fn reserve(&self, user: &str, ip: IpAddr, now: UnixMs) -> Result<Attempt, RateLimited> {
        let id = self.next_attempt.fetch_add(1, Ordering::Relaxed);
        let mut map = self.lock();
        Self::check_map(&map, user, ip, now)?;
        let (lockout, counted) = self.count_failure(&mut map, user, ip, now, id);
        Ok(Attempt { id, user: user.to_string(), counted, lockout })
    }

    /// The reserved attempt failed (wrong password): its failure stays counted. Returns the
    /// lock-out it started, if any.
    #[must_use = "the lock-out belongs in the audit"]
    pub fn failed(&self, attempt: Attempt) -> Option<RateLimited> {
        attempt.lockout
    }

    /// The reserved attempt succeeded: its failure is given back (also on the address) and
    /// the user name's failures and lock-out history are cleared.
    pub fn succeeded(&self, attempt: Attempt) {
        let mut map = self.lock();
        Self::give_back(&mut map, &attempt);
        map.remove(&LimitKey::User(attempt.user));
    }

    /// The reserved attempt was not checked (hashing busy, storage error): its failure is
    /// given back, with any lock-out it started.
    pub fn release(&self, attempt: Attempt) {
        Self::give_back(&mut self.lock(), &attempt);
    }

    fn give_back(map: &mut HashMap<LimitKey, KeyState>, attempt: &Attempt) {
        for counted in &attempt.counted {
            let Some(state) = map.get_mut(&counted.key) else { continue };
            state.failures.retain(|(_, id)| *id != attempt.id);
            if let Some(replaced) = &counted.locked {
                if state.locked_by == attempt.id {
                    // Undo the lock-out this attempt started; failures counted since stay.
                    let mut failures = replaced.failures.clone();
                    failures.extend(state.failures.drain(..));
                    state.failures = failures;
                    state.locked_until = replaced.locked_until;
                    state.last_lockout = replaced.last_lockout;
                    state.locked_by = 0;
                }
            }
        }
    }

    /// Records a failed login (not reserved). Returns the lock-out it caused, if any (the
    /// longer one).
    pub fn record_failure(&self, user: &str, ip: IpAddr, now: UnixMs) -> Option<RateLimited> {
        self.count_failure(&mut self.lock(), user, ip, now, 0).0
    }

    /// Counts a failure of both keys for attempt `id` (0: not reserved): the lock-out it
    /// caused (the longer one) and what it changed on each key.
    fn count_failure(
        &self,
        map: &mut HashMap<LimitKey, KeyState>,
        user: &str,
        ip: IpAddr,
        now: UnixMs,
        id: u64,
    ) -> (Option<RateLimited>, Vec<Counted>) {
        let window = Duration::from_secs(self.policy.window_secs);
        if map.len() >= self.policy.max_keys {
            Self::prune_map(map, now, self.stale_after());
        }
        let mut worst: Option<RateLimited> = None;
        let mut changes = Vec::with_capacity(2);
        for (key, is_user) in Self::keys(user, ip) {
            let max = if is_user { self.policy.user_max_failures } else { self.policy.ip_max_failures };
            let state = map.entry(key.clone()).or_default();
            state.last_event = now;
            while state.failures.front().is_some_and(|(t, _)| now.since(*t) >= window) {
                state.failures.pop_front();
            }
            state.failures.push_back((now, id));
            let already_locked = state.locked_until.is_some_and(|u| u > now);
            let mut locked = None;
            if !already_locked && state.failures.len() >= usize::try_from(max).unwrap_or(usize::MAX) {
                let first = Duration::from_secs(self.policy.lockout_secs);
                let cap = Duration::from_secs(self.policy.max_lockout_secs);
                let d = state.last_lockout.map_or(first, |l| l.saturating_mul(2)).min(cap);
                let mut cleared = std::mem::take(&mut state.failures);
                cleared.retain(|(_, f)| *f != id || id == 0);
                locked = Some(Replaced {
                    locked_until: state.locked_until,
                    last_lockout: state.last_lockout,
                    failures: cleared,
                });
                state.last_lockout = Some(d);
                state.locked_until = Some(now.plus(d));
                state.locked_by = id;
                tracing::warn!(?key, lockout_s = d.as_secs(), "login locked after repeated failures");
                if worst.as_ref().map_or(true, |w| d > w.retry_after) {
                    worst = Some(RateLimited { key: key.clone(), retry_after: d });
                }
            }
            changes.push(Counted { key, locked });
        }
        (worst, changes)
    }

    /// Records a successful login (not reserved): clears the user name's failures and
    /// lock-out history.
    pub fn record_success(&self, user: &str, _ip: IpAddr, _now: UnixMs) {
        self.lock().remove(&LimitKey::User(user.to_string()));
    }

    fn stale_after(&self) -> Duration {
        Duration::from_secs(self.policy.window_secs.max(self.policy.max_lockout_secs))
    }

    fn prune_map(map: &mut HashMap<LimitKey, KeyState>, now: UnixMs, stale: Duration) {
        map.retain(|_, s| s.locked_until.is_some_and(|u| u > now) || now.since(s.last_event) < stale);
    }

    /// Forgets keys with no lock-out and no event for the longer of the window and the
    /// longest lock-out (which also resets the doubling). Returns how many keys remain.
    pub fn prune(&self, now: UnixMs) -> usize {
        let stale = self.stale_after();
        let mut map = self.lock();
        Self::prune_map(&mut map, now, stale);
        map.len()
    }
}
