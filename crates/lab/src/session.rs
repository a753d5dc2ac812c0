//! Login sessions: random bearer tokens in a cookie, a separate CSRF token, idle and
//! absolute expiry, logout, and the `Set-Cookie` header builder.
//!
//! The token (256 random bits from the OS) is given to the client once, in the cookie; the
//! store keeps only its SHA-256, so a copy of the database cannot be used to log in. The CSRF
//! token (another 256 bits) is stored as is: the web layer sends it in the page and requires
//! it back in a header on every state-changing request ([`Sessions::check_csrf`]).

use std::sync::Arc;
use std::time::Duration;

use rand::RngCore;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::role::Role;
use crate::store::{Store, StoreError};
use crate::time::UnixMs;
use crate::users::User;

/// Session lifetimes and cookie settings.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SessionPolicy {
    /// A session unused for this long expires (default 30 min).
    pub idle_timeout_secs: u64,
    /// A session expires this long after login however much it is used (default 12 h).
    pub absolute_timeout_secs: u64,
    /// `last_seen` is written at most once per this interval (default 60 s), sparing the
    /// database a write per request; idle expiry is exact to within this interval.
    pub touch_interval_secs: u64,
    /// Cookie attributes.
    pub cookie: CookieConfig,
}

impl Default for SessionPolicy {
    fn default() -> Self {
        SessionPolicy {
            idle_timeout_secs: 30 * 60,
            absolute_timeout_secs: 12 * 3600,
            touch_interval_secs: 60,
            cookie: CookieConfig::default(),
        }
    }
}

/// Attributes of the session cookie.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CookieConfig {
    /// Adds `Secure` (the browser sends the cookie over HTTPS only). Turn off only for plain
    /// HTTP on localhost. With `Secure` the cookie is named with the `__Host-` prefix, which
    /// browsers accept only with `Secure`, `Path=/` and no `Domain`.
    pub secure: bool,
    /// Base name of the cookie (default `motus_session`).
    pub name: String,
}

impl Default for CookieConfig {
    fn default() -> Self {
        CookieConfig { secure: true, name: "motus_session".to_string() }
    }
}

impl CookieConfig {
    /// The cookie's full name (`__Host-motus_session` when secure).
    #[must_use]
    pub fn cookie_name(&self) -> String {
        if self.secure {
            format!("__Host-{}", self.name)
        } else {
            self.name.clone()
        }
    }

    /// A `Set-Cookie` header value carrying `token`:
    /// `NAME=TOKEN; Path=/; Max-Age=N; HttpOnly; SameSite=Strict[; Secure]`.
    /// `max_age` is normally the absolute timeout.
    #[must_use]
    pub fn set_cookie(&self, token: &str, max_age: Duration) -> String {
        let mut s = format!(
            "{}={}; Path=/; Max-Age={}; HttpOnly; SameSite=Strict",
            self.cookie_name(),
            token,
            max_age.as_secs()
        );
        if self.secure {
            s.push_str("; Secure");
        }
        s
    }

    /// A `Set-Cookie` header value that deletes the cookie (logout).
    #[must_use]
    pub fn clear_cookie(&self) -> String {
        self.set_cookie("", Duration::ZERO)
    }

    /// The session token from a request's `Cookie` header (`a=1; NAME=TOKEN; b=2`), if present.
    #[must_use]
    pub fn token_from_header<'h>(&self, cookie_header: &'h str) -> Option<&'h str> {
        let name = self.cookie_name();
        cookie_header.split(';').find_map(|pair| {
            let (k, v) = pair.trim().split_once('=')?;
            (k == name && !v.is_empty()).then_some(v)
        })
    }
}

/// A stored session.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SessionRecord {
    /// Lower-case hex SHA-256 of the token (the key).
    pub token_hash: String,
    /// The user logged in.
    pub user: String,
    /// CSRF token (64 hex characters).
    pub csrf_token: String,
    /// Login time.
    pub created: UnixMs,
    /// Last use (updated at most once per touch interval).
    pub last_seen: UnixMs,
    /// Client address at login, for the admin's session list.
    pub source: Option<String>,
}

/// What [`Sessions::create`] returns: the only time the plain token exists.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NewSession {
    /// The bearer token for the cookie (64 hex characters).
    pub token: String,
    /// The CSRF token the pages must send back.
    pub csrf_token: String,
    /// The `Set-Cookie` header value.
    pub set_cookie: String,
    /// The stored record.
    pub record: SessionRecord,
}

/// A valid session, as found by [`Sessions::lookup`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SessionInfo {
    /// Lower-case hex SHA-256 of the token (identifies the session for logout).
    pub token_hash: String,
    /// The user.
    pub user: String,
    /// The user's role now (read from the users table at each lookup).
    pub role: Role,
    /// CSRF token.
    pub csrf_token: String,
    /// Login time.
    pub created: UnixMs,
    /// When the session expires if unused from now on.
    pub idle_expires: UnixMs,
    /// When the session expires at the latest.
    pub absolute_expires: UnixMs,
}

/// Which limit an expired session reached.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExpiryKind {
    /// Unused for longer than the idle timeout.
    Idle,
    /// Older than the absolute timeout.
    Absolute,
}

/// Why a session is not valid.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// No session with this token (never existed, logged out, or ended by an admin).
    #[error("no such session")]
    Unknown,
    /// The session expired (it has been deleted).
    #[error("session expired ({0:?} timeout)")]
    Expired(ExpiryKind),
    /// The session's user no longer exists (the session has been deleted).
    #[error("user {0:?} of this session no longer exists")]
    UserGone(String),
    /// The CSRF token presented is missing or wrong.
    #[error("CSRF token missing or wrong")]
    CsrfMismatch,
    /// Storage failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// Session management over a [`Store`].
pub struct Sessions {
    store: Arc<dyn Store>,
    policy: SessionPolicy,
}

/// 32 random bytes from the operating system, as 64 lower-case hex characters.
fn random_token() -> String {
    let mut bytes = [0u8; 32];
    rand::rngs::OsRng.fill_bytes(&mut bytes);
    hex(&bytes)
}

fn hex(bytes: &[u8]) -> String {
    use std::fmt::Write as _;
    bytes.iter().fold(String::with_capacity(bytes.len() * 2), |mut s, b| {
        let _ = write!(s, "{b:02x}");
        s
    })
}

/// Lower-case hex SHA-256 of a token: the key under which its session is stored.
#[must_use]
pub fn token_hash(token: &str) -> String {
    hex(&Sha256::digest(token.as_bytes()))
}

/// Compares two byte strings in time independent of where they differ.
#[must_use]
pub fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

impl Sessions {
    /// Sessions in `store` under `policy`.
    #[must_use]
    pub fn new(store: Arc<dyn Store>, policy: SessionPolicy) -> Self {
        Sessions { store, policy }
    }

    /// The policy in force.
    #[must_use]
    pub fn policy(&self) -> &SessionPolicy {
        &self.policy
    }

    fn idle(&self) -> Duration {
        Duration::from_secs(self.policy.idle_timeout_secs)
    }

    fn absolute(&self) -> Duration {
        Duration::from_secs(self.policy.absolute_timeout_secs)
    }

    /// Starts a session for `user` (after a successful password check).
    ///
    /// # Errors
    /// A storage failure.
    pub fn create(&self, user: &User, source: Option<&str>, now: UnixMs) -> Result<NewSession, SessionError> {
        let token = random_token();
        let record = SessionRecord {
            token_hash: token_hash(&token),
            user: user.name.clone(),
            csrf_token: random_token(),
            created: now,
            last_seen: now,
            source: source.map(str::to_string),
        };
        self.store.insert_session(&record)?;
        Ok(NewSession {
            set_cookie: self.policy.cookie.set_cookie(&token, self.absolute()),
            csrf_token: record.csrf_token.clone(),
            token,
            record,
        })
    }

    /// Finds the session of `token` at `now`. An expired session, or one whose user is gone,
    /// is deleted and reported as such. Updates `last_seen` (at most once per touch interval).
    ///
    /// # Errors
    /// [`SessionError::Unknown`], [`SessionError::Expired`], [`SessionError::UserGone`], or a
    /// storage failure.
    pub fn lookup(&self, token: &str, now: UnixMs) -> Result<SessionInfo, SessionError> {
        let hash = token_hash(token);
        let Some(rec) = self.store.get_session(&hash)? else { return Err(SessionError::Unknown) };
        let absolute_expires = rec.created.plus(self.absolute());
        if now >= absolute_expires {
            self.store.delete_session(&hash)?;
            return Err(SessionError::Expired(ExpiryKind::Absolute));
        }
        if now >= rec.last_seen.plus(self.idle()) {
            self.store.delete_session(&hash)?;
            return Err(SessionError::Expired(ExpiryKind::Idle));
        }
        let Some(user) = self.store.get_user(&rec.user)? else {
            self.store.delete_session(&hash)?;
            return Err(SessionError::UserGone(rec.user));
        };
        let mut last_seen = rec.last_seen;
        if now.since(rec.last_seen) >= Duration::from_secs(self.policy.touch_interval_secs) {
            self.store.touch_session(&hash, now)?;
            last_seen = now;
        }
        Ok(SessionInfo {
            token_hash: hash,
            user: user.name,
            role: user.role,
            csrf_token: rec.csrf_token,
            created: rec.created,
            idle_expires: last_seen.plus(self.idle()).min(absolute_expires),
            absolute_expires,
        })
    }

    /// Checks the CSRF token sent with a state-changing request (constant-time comparison).
    ///
    /// # Errors
    /// [`SessionError::CsrfMismatch`] if `presented` is absent or differs.
    pub fn check_csrf(&self, session: &SessionInfo, presented: Option<&str>) -> Result<(), SessionError> {
        match presented {
            Some(p) if constant_time_eq(p.as_bytes(), session.csrf_token.as_bytes()) => Ok(()),
            _ => Err(SessionError::CsrfMismatch),
        }
    }

    /// Ends the session of `token`; false if there was none.
    ///
    /// # Errors
    /// A storage failure.
    pub fn logout(&self, token: &str) -> Result<bool, SessionError> {
        Ok(self.store.delete_session(&token_hash(token))?)
    }

    /// Ends the session with this stored hash (e.g. from [`SessionInfo::token_hash`]).
    ///
    /// # Errors
    /// A storage failure.
    pub fn end_by_hash(&self, token_hash: &str) -> Result<bool, SessionError> {
        Ok(self.store.delete_session(token_hash)?)
    }

    /// Ends every session of `user` (an admin ending a user's sessions; password change).
    ///
    /// # Errors
    /// A storage failure.
    pub fn end_all_for(&self, user: &str) -> Result<usize, SessionError> {
        Ok(self.store.delete_user_sessions(user)?)
    }

    /// Deletes every session expired at `now`; returns how many.
    ///
    /// # Errors
    /// A storage failure.
    pub fn purge_expired(&self, now: UnixMs) -> Result<usize, SessionError> {
        Ok(self.store.delete_stale_sessions(now.minus(self.absolute()), now.minus(self.idle()))?)
    }

    /// Sessions of one user, or all, oldest first (expired ones not yet purged included).
    ///
    /// # Errors
    /// A storage failure.
    pub fn list(&self, user: Option<&str>) -> Result<Vec<SessionRecord>, SessionError> {
        Ok(self.store.list_sessions(user)?)
    }
}
