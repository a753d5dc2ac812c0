//! Password hashing with Argon2id (PHC strings) and the password policy.

use std::cell::RefCell;

use argon2::password_hash::{Output, ParamsString, PasswordHash, SaltString};
use argon2::{Algorithm, Argon2, Block, Params, Version};
use serde::{Deserialize, Serialize};

/// Argon2id cost parameters. The default is the OWASP recommendation
/// (19 MiB, 2 passes, 1 lane).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HashParams {
    /// Memory cost in KiB (at least 8 x parallelism).
    pub memory_kib: u32,
    /// Number of passes.
    pub iterations: u32,
    /// Degree of parallelism (lanes).
    pub parallelism: u32,
}

impl Default for HashParams {
    fn default() -> Self {
        HashParams { memory_kib: 19 * 1024, iterations: 2, parallelism: 1 }
    }
}

/// Rules a new password must satisfy.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PasswordPolicy {
    /// Minimum length in characters (Unicode scalar values).
    pub min_length: usize,
    /// Maximum length in characters (bounds the hashing work an attacker can cause).
    pub max_length: usize,
    /// Argon2id parameters for new hashes.
    pub hash: HashParams,
    /// Dedicated threads that verify and hash passwords (default 2, at least 1): bounds the
    /// CPU and memory a burst of logins can take (see [`crate::hashing`]).
    pub hash_workers: usize,
    /// Password checks that may wait for a hashing thread (default 4); a login beyond
    /// workers + queue is refused at once as busy.
    pub hash_queue: usize,
}

impl Default for PasswordPolicy {
    fn default() -> Self {
        PasswordPolicy {
            min_length: 10,
            max_length: 256,
            hash: HashParams::default(),
            hash_workers: 2,
            hash_queue: 4,
        }
    }
}

/// Why a password was refused by the policy.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PolicyViolation {
    /// Fewer characters than the policy's minimum.
    #[error("password too short: {length} characters, at least {min} required")]
    TooShort {
        /// Characters given.
        length: usize,
        /// Policy minimum.
        min: usize,
    },
    /// More characters than the policy's maximum.
    #[error("password too long: {length} characters, at most {max} allowed")]
    TooLong {
        /// Characters given.
        length: usize,
        /// Policy maximum.
        max: usize,
    },
    /// The password equals the user name (ignoring case).
    #[error("password must not equal the user name")]
    EqualsUserName,
}

/// A failure of the hashing library or a stored hash that is not a valid PHC string.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum HashError {
    /// The Argon2 parameters are out of range.
    #[error("invalid argon2 parameters: {0}")]
    Params(String),
    /// Hashing failed.
    #[error("argon2 hashing failed: {0}")]
    Hash(String),
    /// A stored hash could not be parsed as a PHC string.
    #[error("stored password hash is not a valid PHC string: {0}")]
    Malformed(String),
}

impl PasswordPolicy {
    /// Checks `password` for `user` against the policy.
    ///
    /// # Errors
    /// The first rule broken.
    pub fn check(&self, user: &str, password: &str) -> Result<(), PolicyViolation> {
        let length = password.chars().count();
        if length < self.min_length {
            return Err(PolicyViolation::TooShort { length, min: self.min_length });
        }
        if length > self.max_length {
            return Err(PolicyViolation::TooLong { length, max: self.max_length });
        }
        if password.eq_ignore_ascii_case(user) {
            return Err(PolicyViolation::EqualsUserName);
        }
        Ok(())
    }
}

fn argon2(params: HashParams) -> Result<Argon2<'static>, HashError> {
    let p = Params::new(params.memory_kib, params.iterations, params.parallelism, None)
        .map_err(|e| HashError::Params(e.to_string()))?;
    Ok(Argon2::new(Algorithm::Argon2id, Version::V0x13, p))
}

/// The most memory a stored hash may ask for (KiB): a hash string asking for more is refused
/// as malformed rather than allocated.
const MAX_MEMORY_KIB: u32 = 256 * 1024;

thread_local! {
    /// This thread's Argon2 working memory, kept from one hash to the next: the hashing
    /// threads are few (`HashPool`), so the memory is a fixed amount per thread instead of
    /// 19 MiB allocated and given back on every login (a burst of logins grew the process
    /// by ~40 MB that the allocator returned only later, and never under `mlockall`).
    static MEMORY: RefCell<Vec<Block>> = const { RefCell::new(Vec::new()) };
}

/// Runs Argon2 into `out` on this thread's kept memory.
fn compute(argon: &Argon2<'_>, password: &[u8], salt: &[u8], out: &mut [u8]) -> Result<(), argon2::Error> {
    let blocks = argon.params().block_count();
    MEMORY.with(|m| {
        let mut m = m.borrow_mut();
        if m.len() < blocks {
            m.resize(blocks, Block::default());
        }
        let memory = m.get_mut(..blocks).unwrap_or_default();
        argon.hash_password_into_with_memory(password, salt, out, memory)
    })
}

/// Hashes `password` with Argon2id, a fresh 128-bit random salt and `params`; returns the
/// PHC string (`$argon2id$v=19$m=...,t=...,p=...$salt$hash`).
///
/// # Errors
/// [`HashError::Params`] for parameters out of range, [`HashError::Hash`] if hashing fails.
pub fn hash_password(password: &str, params: HashParams) -> Result<String, HashError> {
    let argon = argon2(params)?;
    let salt = SaltString::generate(&mut rand::rngs::OsRng);
    let mut salt_buf = [0u8; 64];
    let salt_bytes = salt.as_salt().decode_b64(&mut salt_buf).map_err(|e| HashError::Hash(e.to_string()))?;
    let output = Output::init_with(Params::DEFAULT_OUTPUT_LEN, |out| {
        compute(&argon, password.as_bytes(), salt_bytes, out)
            .map_err(|_| argon2::password_hash::Error::Crypto)
    })
    .map_err(|e| HashError::Hash(e.to_string()))?;
    let hash = PasswordHash {
        algorithm: Algorithm::Argon2id.ident(),
        version: Some(Version::V0x13.into()),
        params: ParamsString::try_from(argon.params()).map_err(|e| HashError::Hash(e.to_string()))?,
        salt: Some(salt.as_salt()),
        hash: Some(output),
    };
    Ok(hash.to_string())
}

/// Verifies `password` against a stored PHC string (its own parameters are used; the
/// comparison takes constant time). Returns `Ok(false)` for a wrong password.
///
/// # Errors
/// [`HashError::Malformed`] if `phc` cannot be parsed, names an unsupported algorithm or
/// asks for more than 256 MiB.
pub fn verify_password(password: &str, phc: &str) -> Result<bool, HashError> {
    let malformed = |e: &dyn std::fmt::Display| HashError::Malformed(e.to_string());
    let parsed = PasswordHash::new(phc).map_err(|e| malformed(&e))?;
    let (Some(expected), Some(salt)) = (parsed.hash, parsed.salt) else {
        return Err(HashError::Malformed("no salt or hash value".to_string()));
    };
    let algorithm = Algorithm::try_from(parsed.algorithm).map_err(|e| malformed(&e))?;
    let version =
        parsed.version.map(Version::try_from).transpose().map_err(|e| malformed(&e))?.unwrap_or_default();
    let params = Params::try_from(&parsed).map_err(|e| malformed(&e))?;
    if params.m_cost() > MAX_MEMORY_KIB {
        return Err(HashError::Malformed(format!("m={} KiB exceeds {MAX_MEMORY_KIB} KiB", params.m_cost())));
    }
    let mut salt_buf = [0u8; 64];
    let salt_bytes = salt.decode_b64(&mut salt_buf).map_err(|e| malformed(&e))?;
    let argon = Argon2::new(algorithm, version, params);
    let computed = Output::init_with(expected.len(), |out| {
        compute(&argon, password.as_bytes(), salt_bytes, out)
            .map_err(|_| argon2::password_hash::Error::Crypto)
    })
    .map_err(|e| malformed(&e))?;
    // `Output`'s equality is constant-time.
    Ok(computed == expected)
}

/// True when `phc` was not made with Argon2id and exactly `params` (so it should be
/// re-hashed at the next successful login). A malformed string also needs re-hashing.
#[must_use]
pub fn needs_rehash(phc: &str, params: HashParams) -> bool {
    let Ok(parsed) = PasswordHash::new(phc) else { return true };
    if parsed.algorithm.as_str() != "argon2id" {
        return true;
    }
    match Params::try_from(&parsed) {
        Ok(p) => {
            p.m_cost() != params.memory_kib
                || p.t_cost() != params.iterations
                || p.p_cost() != params.parallelism
        }
        Err(_) => true,
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    /// Cheap parameters so debug-build tests stay fast; verification reads them from the PHC.
    const FAST: HashParams = HashParams { memory_kib: 64, iterations: 1, parallelism: 1 };

    #[test]
    fn hashes_agree_with_the_argon2_crates_own_hasher_and_verifier() {
        use argon2::password_hash::{PasswordHasher as _, PasswordVerifier as _};
        // A hash stored by the crate's own hasher (as earlier versions did) verifies here...
        let salt = SaltString::generate(&mut rand::rngs::OsRng);
        let theirs = argon2(FAST).unwrap().hash_password(b"correct horse", &salt).unwrap().to_string();
        assert!(verify_password("correct horse", &theirs).unwrap());
        assert!(!verify_password("wrong horse", &theirs).unwrap());
        // ...and ours verifies with the crate's verifier; other parameters (from the PHC) too.
        for params in [FAST, HashParams { memory_kib: 256, iterations: 2, parallelism: 2 }] {
            let ours = hash_password("correct horse", params).unwrap();
            let parsed = PasswordHash::new(&ours).unwrap();
            Argon2::default().verify_password(b"correct horse", &parsed).unwrap();
            assert!(verify_password("correct horse", &ours).unwrap());
        }
    }

    #[test]
    fn a_hash_asking_for_too_much_memory_is_malformed() {
        let phc = hash_password("correct horse", FAST).unwrap().replace("m=64", "m=4194304");
        assert!(matches!(verify_password("correct horse", &phc), Err(HashError::Malformed(_))));
    }

    #[test]
    fn hash_then_verify() {
        let phc = hash_password("correct horse", FAST).unwrap();
        assert!(phc.starts_with("$argon2id$v=19$m=64,t=1,p=1$"), "{phc}");
        assert!(verify_password("correct horse", &phc).unwrap());
        assert!(!verify_password("correct horsE", &phc).unwrap());
        assert!(!verify_password("", &phc).unwrap());
        // Two hashes of the same password differ (random salt) and both verify.
        let phc2 = hash_password("correct horse", FAST).unwrap();
        assert_ne!(phc, phc2);
        assert!(verify_password("correct horse", &phc2).unwrap());
    }

    #[test]
    fn known_vector_from_independent_implementation() {
        // Computed with Python argon2-cffi 25.1 (the reference C implementation):
        // argon2.low_level.hash_secret(b"password", b"somesalt", time_cost=2, memory_cost=64,
        //     parallelism=1, hash_len=32, type=Type.ID)
        // Only verification is exercised here, so this checks our code against another one.
        let phc = "$argon2id$v=19$m=64,t=2,p=1$c29tZXNhbHQ$FqGkmHNGCd0BRW2kBt6fPZ2pPmyGwwChL8FGUhTOSSI";
        assert_eq!(verify_password("password", phc), Ok(true));
        assert_eq!(verify_password("passwore", phc), Ok(false));
        // Same tool: hash_secret(b"correct horse battery", b"motus-lab-salt16", time_cost=1,
        //     memory_cost=64, parallelism=1, hash_len=32, type=Type.ID)
        let phc2 =
            "$argon2id$v=19$m=64,t=1,p=1$bW90dXMtbGFiLXNhbHQxNg$UEdvIEmBVKReaMei+lxdsBUAEH63nn8x3qs3pe0ochg";
        assert_eq!(verify_password("correct horse battery", phc2), Ok(true));
        assert_eq!(verify_password("correct horse batterY", phc2), Ok(false));
    }

    #[test]
    fn malformed_hash_is_an_error() {
        assert!(matches!(verify_password("x", "not-a-phc"), Err(HashError::Malformed(_))));
        assert!(matches!(verify_password("x", "$argon2id$v=19$m=64"), Err(HashError::Malformed(_))));
    }

    #[test]
    fn params_out_of_range() {
        let bad = HashParams { memory_kib: 1, iterations: 1, parallelism: 1 };
        assert!(matches!(hash_password("whatever1234", bad), Err(HashError::Params(_))));
    }

    #[test]
    fn rehash_detection() {
        let phc = hash_password("abcdefghijk", FAST).unwrap();
        assert!(!needs_rehash(&phc, FAST));
        assert!(needs_rehash(&phc, HashParams { iterations: 2, ..FAST }));
        assert!(needs_rehash("garbage", FAST));
    }

    #[test]
    fn policy_rules() {
        let p = PasswordPolicy { min_length: 10, max_length: 20, hash: FAST, ..PasswordPolicy::default() };
        assert_eq!(p.check("alice", "short"), Err(PolicyViolation::TooShort { length: 5, min: 10 }));
        // 9 characters but 18 bytes: length is counted in characters.
        assert_eq!(p.check("alice", "ééééééééé"), Err(PolicyViolation::TooShort { length: 9, min: 10 }));
        assert_eq!(p.check("alice", &"x".repeat(21)), Err(PolicyViolation::TooLong { length: 21, max: 20 }));
        assert_eq!(p.check("alicealice", "AliceAlice"), Err(PolicyViolation::EqualsUserName));
        assert_eq!(p.check("alice", "ten chars!"), Ok(()));
    }
}
