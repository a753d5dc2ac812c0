//! [`Lab`]: every facade over one store, plus the flows that combine them with the audit
//! log (login, logout, authorise-and-audit, ending a user's session).

use std::net::IpAddr;
use std::sync::Arc;

use crate::alarm::Alarms;
use crate::audit::{Audit, AuditEntry, AuditOutcome};
use crate::authz::{Action, Actor, Authorizer, AuthzError};
use crate::config::LabConfig;
use crate::hashing::HashPoolError;
use crate::limiter::{LoginLimiter, RateLimited};
use crate::program::Programs;
use crate::reservation::{Reservation, ReservationError, Reservations};
use crate::session::{NewSession, SessionError, SessionInfo, Sessions};
use crate::store::{ReservationFilter, Store, StoreError};
use crate::time::UnixMs;
use crate::users::{User, UserError, MAX_NAME_LEN};

/// Why a login failed.
#[derive(Debug, thiserror::Error)]
pub enum LoginError {
    /// Too many failures: try again later (HTTP 429 with `Retry-After`).
    #[error(transparent)]
    RateLimited(#[from] RateLimited),
    /// Unknown user or wrong password.
    #[error("wrong user name or password")]
    BadCredentials,
    /// Every password-hashing worker is busy and its queue is full: no password was
    /// checked and the attempt was not counted; retry in a moment (HTTP 503).
    #[error("password checks are busy; retry in a moment")]
    Busy,
    /// A user-store or hashing failure.
    #[error(transparent)]
    User(UserError),
    /// A session-store failure.
    #[error(transparent)]
    Session(#[from] SessionError),
    /// Storage failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// A successful login.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LoginSuccess {
    /// The user.
    pub user: User,
    /// The new session (token, CSRF token, `Set-Cookie` value).
    pub session: NewSession,
}

/// What [`Lab::end_user_session`] ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EndedSession {
    /// Login sessions deleted.
    pub sessions: usize,
    /// Running slots ended (their cleanup is now due).
    pub slots: Vec<Reservation>,
}

/// Why [`Lab::end_user_session`] failed.
#[derive(Debug, thiserror::Error)]
pub enum EndSessionError {
    /// Refused or the facts could not be read.
    #[error(transparent)]
    Authz(#[from] AuthzError),
    /// Sessions could not be deleted.
    #[error(transparent)]
    Session(#[from] SessionError),
    /// A slot could not be ended.
    #[error(transparent)]
    Reservation(#[from] ReservationError),
}

/// The laboratory layer over one store.
pub struct Lab {
    store: Arc<dyn Store>,
    users: Users,
    sessions: Sessions,
    limiter: LoginLimiter,
    reservations: Reservations,
    authorizer: Authorizer,
    audit: Audit,
    alarms: Alarms,
    programs: Programs,
}

use crate::users::Users;

/// Clips an attempted user name for the audit log (unvalidated input).
fn clip(name: &str) -> String {
    name.chars().take(MAX_NAME_LEN).collect()
}

impl Lab {
    /// Every facade over `store`, with the policies of `config`.
    #[must_use]
    pub fn new(store: Arc<dyn Store>, config: LabConfig) -> Self {
        Lab {
            users: Users::new(Arc::clone(&store), config.password),
            sessions: Sessions::new(Arc::clone(&store), config.sessions),
            limiter: LoginLimiter::new(config.limiter),
            reservations: Reservations::new(Arc::clone(&store), config.reservations),
            authorizer: Authorizer::new(Arc::clone(&store), config.student_limits),
            audit: Audit::new(Arc::clone(&store)),
            alarms: Alarms::new(Arc::clone(&store)),
            programs: Programs::new(Arc::clone(&store)),
            store,
        }
    }

    /// The store.
    #[must_use]
    pub fn store(&self) -> &Arc<dyn Store> {
        &self.store
    }
    /// User management.
    #[must_use]
    pub fn users(&self) -> &Users {
        &self.users
    }
    /// Sessions.
    #[must_use]
    pub fn sessions(&self) -> &Sessions {
        &self.sessions
    }
    /// The login limiter.
    #[must_use]
    pub fn limiter(&self) -> &LoginLimiter {
        &self.limiter
    }
    /// Reservations.
    #[must_use]
    pub fn reservations(&self) -> &Reservations {
        &self.reservations
    }
    /// The authorizer.
    #[must_use]
    pub fn authorizer(&self) -> &Authorizer {
        &self.authorizer
    }
    /// The audit log.
    #[must_use]
    pub fn audit(&self) -> &Audit {
        &self.audit
    }
    /// Alarms.
    #[must_use]
    pub fn alarms(&self) -> &Alarms {
        &self.alarms
    }
    /// Program metadata.
    #[must_use]
    pub fn programs(&self) -> &Programs {
        &self.programs
    }

    fn audit_quietly(&self, entry: AuditEntry) {
        if let Err(e) = self.audit.append(&entry) {
            tracing::error!(error = %e, action = %entry.action, user = %entry.user, "audit write failed");
        }
    }

    /// Login: rate limit, password check, session creation; audited as `login` with the
    /// client address as target (also when refused).
    ///
    /// The attempt is reserved with the limiter before the password is checked (counted as
    /// a failure until it succeeds), so concurrent attempts cannot exceed the limits. The
    /// check runs on the users' hashing pool ([`Users::hash_pool`]) and this call waits for
    /// it; a full pool refuses at once.
    ///
    /// # Errors
    /// [`LoginError::RateLimited`] (no password check was made), [`LoginError::Busy`] (no
    /// check was made, the attempt is not counted), [`LoginError::BadCredentials`], or a
    /// storage/hash failure.
    pub fn login(
        &self,
        name: &str,
        password: &str,
        ip: IpAddr,
        now: UnixMs,
    ) -> Result<LoginSuccess, LoginError> {
        let entry = |outcome| AuditEntry {
            time: now,
            user: clip(name),
            action: "login".into(),
            target: ip.to_string(),
            outcome,
        };
        let attempt = match self.limiter.reserve(name, ip, now) {
            Ok(a) => a,
            Err(limited) => {
                self.audit_quietly(entry(AuditOutcome::Denied(limited.to_string())));
                return Err(limited.into());
            }
        };
        let user = match self.users.verify(name, password, now) {
            Ok(u) => u,
            Err(UserError::BadCredentials) => {
                let locked = self.limiter.failed(attempt);
                let msg = match &locked {
                    Some(l) => format!("wrong user name or password; {l}"),
                    None => "wrong user name or password".to_string(),
                };
                self.audit_quietly(entry(AuditOutcome::Denied(msg)));
                return Err(LoginError::BadCredentials);
            }
            Err(UserError::HashPool(HashPoolError::Busy)) => {
                self.limiter.release(attempt);
                self.audit_quietly(entry(AuditOutcome::Denied(LoginError::Busy.to_string())));
                return Err(LoginError::Busy);
            }
            Err(e) => {
                self.limiter.release(attempt);
                self.audit_quietly(entry(AuditOutcome::Error(e.to_string())));
                return Err(LoginError::User(e));
            }
        };
        self.limiter.succeeded(attempt);
        let session = self.sessions.create(&user, Some(&ip.to_string()), now)?;
        self.audit.append(&entry(AuditOutcome::Ok))?;
        Ok(LoginSuccess { user, session })
    }

    /// Logout of `session`; audited.
    ///
    /// # Errors
    /// A storage failure.
    pub fn logout(&self, session: &SessionInfo, now: UnixMs) -> Result<bool, SessionError> {
        let ended = self.sessions.end_by_hash(&session.token_hash)?;
        self.audit_quietly(AuditEntry {
            time: now,
            user: session.user.clone(),
            action: "logout".into(),
            target: String::new(),
            outcome: AuditOutcome::Ok,
        });
        Ok(ended)
    }

    /// [`Authorizer::authorize`] for `actor`, auditing a refusal (the caller audits the
    /// result of an allowed action with [`Lab::record`]).
    ///
    /// # Errors
    /// [`AuthzError::Denied`] (audited as `denied`) or [`AuthzError::Store`] (audited as
    /// `error`; treat as refused).
    pub fn authorize(&self, actor: &Actor, action: &Action, now: UnixMs) -> Result<(), AuthzError> {
        let r = self.authorizer.authorize(&actor.name, actor.role, action, now);
        match &r {
            Ok(()) => {}
            Err(AuthzError::Denied(d)) => {
                tracing::info!(user = %actor.name, action = %action.name(), target = %action.target(), %d, "denied");
                if let Err(e) =
                    self.audit.record(actor, action, AuditOutcome::Denied(d.reason.to_string()), now)
                {
                    tracing::error!(error = %e, "audit write failed");
                }
            }
            Err(AuthzError::Store(e)) => {
                if let Err(e2) = self.audit.record(actor, action, AuditOutcome::Error(e.to_string()), now) {
                    tracing::error!(error = %e2, "audit write failed");
                }
            }
        }
        r
    }

    /// Audits the result of an allowed action (`Err(message)` for a failure).
    ///
    /// # Errors
    /// A storage failure.
    pub fn record(
        &self,
        actor: &Actor,
        action: &Action,
        result: Result<(), String>,
        now: UnixMs,
    ) -> Result<i64, StoreError> {
        let outcome = match result {
            Ok(()) => AuditOutcome::Ok,
            Err(m) => AuditOutcome::Error(m),
        };
        self.audit.record(actor, action, outcome, now)
    }

    /// An admin ends `user`'s login sessions and every slot of theirs running at `now`
    /// (the cleanups become due); audited.
    ///
    /// # Errors
    /// [`EndSessionError::Authz`] unless admin (audited), or a storage failure.
    pub fn end_user_session(
        &self,
        admin: &Actor,
        user: &str,
        now: UnixMs,
    ) -> Result<EndedSession, EndSessionError> {
        let action = Action::EndSession { user: user.to_string() };
        self.authorize(admin, &action, now)?;
        let sessions = self.sessions.end_all_for(user)?;
        let running = self.reservations.list(&ReservationFilter {
            user: Some(user.to_string()),
            window: Some((now, now.plus(std::time::Duration::from_millis(1)))),
            ..ReservationFilter::default()
        })?;
        let mut slots = Vec::with_capacity(running.len());
        for r in running {
            slots.push(self.reservations.end_current(admin, &r.station, now)?);
        }
        self.audit_quietly(AuditEntry {
            time: now,
            user: admin.name.clone(),
            action: action.name(),
            target: action.target(),
            outcome: AuditOutcome::Ok,
        });
        Ok(EndedSession { sessions, slots })
    }
}
