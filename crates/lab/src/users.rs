//! Users: names, roles, Argon2id password hashes, and the operations behind
//! `motus user add|passwd|role|delete|list`.

use std::fmt;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

use serde::{Deserialize, Serialize};

use crate::hashing::{HashPool, HashPoolError};
use crate::password::{self, HashError, HashParams, PasswordPolicy, PolicyViolation};
use crate::role::Role;
use crate::store::{Store, StoreError};
use crate::time::UnixMs;

/// Longest accepted user name.
pub const MAX_NAME_LEN: usize = 64;

/// A stored user. `Debug` does not print the password hash.
#[derive(Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct User {
    /// Login name: 1-64 of `a-z 0-9 . _ -`, starting with a letter or digit.
    pub name: String,
    /// Role.
    pub role: Role,
    /// Argon2id PHC string.
    pub password_hash: String,
    /// When the user was added.
    pub created: UnixMs,
    /// Last change of role or password.
    pub updated: UnixMs,
}

impl fmt::Debug for User {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("User")
            .field("name", &self.name)
            .field("role", &self.role)
            .field("password_hash", &"<redacted>")
            .field("created", &self.created)
            .field("updated", &self.updated)
            .finish()
    }
}

/// Why a user operation failed.
#[derive(Debug, thiserror::Error)]
pub enum UserError {
    /// The name breaks the naming rule.
    #[error("invalid user name {name:?}: {reason}")]
    InvalidName {
        /// The name given.
        name: String,
        /// Which rule.
        reason: &'static str,
    },
    /// The password breaks the policy.
    #[error(transparent)]
    WeakPassword(#[from] PolicyViolation),
    /// A user with this name exists.
    #[error("user {0:?} already exists")]
    Exists(String),
    /// No such user.
    #[error("no user {0:?}")]
    NotFound(String),
    /// Unknown user or wrong password (deliberately not distinguished).
    #[error("wrong user name or password")]
    BadCredentials,
    /// The operation would leave no admin.
    #[error("refused: {0:?} is the last admin")]
    LastAdmin(String),
    /// Hashing failed or a stored hash is malformed.
    #[error(transparent)]
    Hash(#[from] HashError),
    /// The hashing pool refused (busy: retry shortly) or failed.
    #[error(transparent)]
    HashPool(#[from] HashPoolError),
    /// Storage failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// Checks the user-name rule: 1-64 characters of `a-z 0-9 . _ -`, first a letter or digit.
///
/// # Errors
/// [`UserError::InvalidName`] with the rule broken.
pub fn validate_name(name: &str) -> Result<(), UserError> {
    let bad = |reason| Err(UserError::InvalidName { name: name.to_string(), reason });
    let Some(first) = name.chars().next() else { return bad("empty") };
    if name.len() > MAX_NAME_LEN {
        return bad("longer than 64 characters");
    }
    if !(first.is_ascii_lowercase() || first.is_ascii_digit()) {
        return bad("must start with a-z or 0-9");
    }
    if !name.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || matches!(c, '.' | '_' | '-')) {
        return bad("only a-z, 0-9, '.', '_' and '-' are allowed");
    }
    Ok(())
}

/// The password verified for an unknown user name (so that the answer takes as long).
const DUMMY_PASSWORD: &str = "motus-lab dummy password";

/// User management over a [`Store`]. Every Argon2 computation runs on its [`HashPool`].
pub struct Users {
    store: Arc<dyn Store>,
    policy: PasswordPolicy,
    dummy_hash: Arc<OnceLock<String>>,
    pool: HashPool,
    verifications: Arc<AtomicU64>,
}

impl Users {
    /// Users in `store`, with `policy` for new passwords and for the hashing pool
    /// (`hash_workers`, `hash_queue`; its threads start at the first hash).
    #[must_use]
    pub fn new(store: Arc<dyn Store>, policy: PasswordPolicy) -> Self {
        let pool = HashPool::new(policy.hash_workers, policy.hash_queue);
        Users {
            store,
            policy,
            dummy_hash: Arc::new(OnceLock::new()),
            pool,
            verifications: Arc::new(AtomicU64::new(0)),
        }
    }

    /// The pool that runs every password hash and check.
    #[must_use]
    pub fn hash_pool(&self) -> &HashPool {
        &self.pool
    }

    /// Password verifications performed so far (including those of the dummy hash for
    /// unknown user names).
    #[must_use]
    pub fn verifications(&self) -> u64 {
        self.verifications.load(Ordering::Relaxed)
    }

    /// Hashes `password` on the pool, waiting for room (administrative work).
    fn hash(&self, password: &str) -> Result<String, UserError> {
        let password = password.to_string();
        let params = self.policy.hash;
        Ok(self.pool.run(move || password::hash_password(&password, params))??)
    }

    /// The password policy in force.
    #[must_use]
    pub fn policy(&self) -> &PasswordPolicy {
        &self.policy
    }

    /// Adds a user (`motus user add`).
    ///
    /// # Errors
    /// [`UserError::InvalidName`], [`UserError::WeakPassword`], [`UserError::Exists`], or a
    /// hashing/storage failure.
    pub fn add(&self, name: &str, password: &str, role: Role, now: UnixMs) -> Result<User, UserError> {
        validate_name(name)?;
        self.policy.check(name, password)?;
        if self.store.get_user(name)?.is_some() {
            return Err(UserError::Exists(name.to_string()));
        }
        let user = User {
            name: name.to_string(),
            role,
            password_hash: self.hash(password)?,
            created: now,
            updated: now,
        };
        match self.store.insert_user(&user) {
            Ok(()) => {}
            Err(StoreError::Conflict { .. }) => return Err(UserError::Exists(name.to_string())),
            Err(e) => return Err(e.into()),
        }
        tracing::info!(user = name, role = %role, "user added");
        Ok(user)
    }

    /// Sets a new password (`motus user passwd`) and ends all the user's sessions.
    ///
    /// # Errors
    /// [`UserError::NotFound`], [`UserError::WeakPassword`], or a hashing/storage failure.
    pub fn passwd(&self, name: &str, password: &str, now: UnixMs) -> Result<(), UserError> {
        let mut user = self.get_existing(name)?;
        self.policy.check(name, password)?;
        user.password_hash = self.hash(password)?;
        user.updated = now;
        self.store.update_user(&user)?;
        let ended = self.store.delete_user_sessions(name)?;
        tracing::info!(user = name, sessions_ended = ended, "password changed");
        Ok(())
    }

    /// Changes a user's role (`motus user role`). Demoting the last admin is refused.
    /// Sessions stay valid: the role is read afresh at every session lookup.
    ///
    /// # Errors
    /// [`UserError::NotFound`], [`UserError::LastAdmin`], or a storage failure.
    pub fn set_role(&self, name: &str, role: Role, now: UnixMs) -> Result<User, UserError> {
        let mut user = self.get_existing(name)?;
        if user.role == Role::Admin && role != Role::Admin && self.admin_count()? <= 1 {
            return Err(UserError::LastAdmin(name.to_string()));
        }
        user.role = role;
        user.updated = now;
        self.store.update_user(&user)?;
        tracing::info!(user = name, role = %role, "role changed");
        Ok(user)
    }

    /// Deletes a user and their sessions. Deleting the last admin is refused.
    ///
    /// # Errors
    /// [`UserError::NotFound`], [`UserError::LastAdmin`], or a storage failure.
    pub fn delete(&self, name: &str) -> Result<(), UserError> {
        let user = self.get_existing(name)?;
        if user.role == Role::Admin && self.admin_count()? <= 1 {
            return Err(UserError::LastAdmin(name.to_string()));
        }
        if !self.store.delete_user(name)? {
            return Err(UserError::NotFound(name.to_string()));
        }
        tracing::info!(user = name, "user deleted");
        Ok(())
    }

    /// Every user, ordered by name.
    ///
    /// # Errors
    /// A storage failure.
    pub fn list(&self) -> Result<Vec<User>, UserError> {
        Ok(self.store.list_users()?)
    }

    /// One user, if present.
    ///
    /// # Errors
    /// A storage failure.
    pub fn get(&self, name: &str) -> Result<Option<User>, UserError> {
        Ok(self.store.get_user(name)?)
    }

    /// Checks a login. For an unknown name a dummy hash is verified anyway, so the answer
    /// takes about as long as for a known one. A hash made with other parameters than the
    /// policy's is replaced after a successful check. The check runs on the hashing pool and
    /// is refused at once when the pool is full.
    ///
    /// # Errors
    /// [`UserError::BadCredentials`] for an unknown user or a wrong password;
    /// [`UserError::HashPool`] with [`HashPoolError::Busy`] when the pool is full (no check
    /// was made); a storage or hash failure.
    pub fn verify(&self, name: &str, password: &str, now: UnixMs) -> Result<User, UserError> {
        let stored = self.store.get_user(name)?;
        let password = password.to_string();
        let params = self.policy.hash;
        let counter = Arc::clone(&self.verifications);
        let Some(mut user) = stored else {
            let dummy = Arc::clone(&self.dummy_hash);
            self.pool.try_run(move || -> Result<(), HashError> {
                let phc = dummy_hash(&dummy, params)?;
                counter.fetch_add(1, Ordering::Relaxed);
                let _ = password::verify_password(&password, phc);
                Ok(())
            })??;
            return Err(UserError::BadCredentials);
        };
        let phc = user.password_hash.clone();
        let (ok, rehashed) = self.pool.try_run(move || -> Result<(bool, Option<String>), HashError> {
            counter.fetch_add(1, Ordering::Relaxed);
            if !password::verify_password(&password, &phc)? {
                return Ok((false, None));
            }
            let rehashed = if password::needs_rehash(&phc, params) {
                Some(password::hash_password(&password, params)?)
            } else {
                None
            };
            Ok((true, rehashed))
        })??;
        if !ok {
            return Err(UserError::BadCredentials);
        }
        if let Some(new_hash) = rehashed {
            user.password_hash = new_hash;
            user.updated = now;
            self.store.update_user(&user)?;
            tracing::info!(user = name, "password hash upgraded to current parameters");
        }
        Ok(user)
    }

    fn get_existing(&self, name: &str) -> Result<User, UserError> {
        self.store.get_user(name)?.ok_or_else(|| UserError::NotFound(name.to_string()))
    }

    fn admin_count(&self) -> Result<usize, UserError> {
        Ok(self.store.list_users()?.iter().filter(|u| u.role == Role::Admin).count())
    }
}

/// The dummy hash, made at its first use (on a hashing worker).
fn dummy_hash(cell: &OnceLock<String>, params: HashParams) -> Result<&str, HashError> {
    if let Some(h) = cell.get() {
        return Ok(h);
    }
    let h = password::hash_password(DUMMY_PASSWORD, params)?;
    Ok(cell.get_or_init(|| h))
}
