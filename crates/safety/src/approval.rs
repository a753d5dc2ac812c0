//! The administrator's approval of a safety configuration, as a signed file.
//!
//! `motus safety approve` writes an [`Approval`]: the canonical text of the approved
//! [`Snapshot`] (rules and drive parameters), its SHA-256 fingerprint, who approved it, and an
//! HMAC-SHA256 over all of that keyed with the **administrator key** (a secret file only the
//! administrator and the supervisor service can read). `motus safety run` verifies the HMAC
//! with the same key and then compares the current configuration with the approved snapshot
//! ([`crate::Integrity`]): any difference blocks motion with a diagnosis naming each changed
//! field. Without the key nobody can produce an approval the supervisor accepts, and nothing
//! reachable by a student program holds the key.

use crate::integrity::{Fingerprint, Snapshot};
use hmac::{Hmac, Mac};
use serde::{Deserialize, Serialize};
use sha2::Sha256;
use thiserror::Error;

/// Smallest administrator key accepted (bytes).
pub const MIN_KEY_LEN: usize = 16;

/// A signed approval (TOML file).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Approval {
    /// Who approved.
    pub admin: String,
    /// When (free text, e.g. RFC 3339; signed).
    pub approved_at: String,
    /// SHA-256 of `canonical` (hex).
    pub fingerprint: String,
    /// The approved snapshot's canonical text.
    pub canonical: String,
    /// HMAC-SHA256 (hex) over admin, time, fingerprint and canonical text.
    pub signature: String,
}

/// Why an approval is not accepted.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ApprovalError {
    /// The key is too short.
    #[error("administrator key: at least {MIN_KEY_LEN} bytes needed, got {0}")]
    KeyTooShort(usize),
    /// The file is not a valid approval.
    #[error("approval file: {0}")]
    Format(String),
    /// The signature does not match (changed file or another key).
    #[error("approval file: signature does not match (edited, or signed with another administrator key)")]
    BadSignature,
    /// The fingerprint does not match the text.
    #[error("approval file: fingerprint {stated} does not match its content ({actual})")]
    FingerprintMismatch {
        /// Fingerprint written in the file.
        stated: String,
        /// Fingerprint of the canonical text.
        actual: String,
    },
}

fn mac(key: &[u8], admin: &str, at: &str, fp: &str, canonical: &str) -> Result<String, ApprovalError> {
    if key.len() < MIN_KEY_LEN {
        return Err(ApprovalError::KeyTooShort(key.len()));
    }
    let mut m = Hmac::<Sha256>::new_from_slice(key).map_err(|e| ApprovalError::Format(e.to_string()))?;
    for part in [admin, at, fp, canonical] {
        m.update(&(part.len() as u64).to_le_bytes());
        m.update(part.as_bytes());
    }
    Ok(m.finalize().into_bytes().iter().map(|b| format!("{b:02x}")).collect())
}

impl Approval {
    /// Signs `snapshot` as approved by `admin` at `approved_at`.
    pub fn sign(
        snapshot: &Snapshot,
        admin: &str,
        approved_at: &str,
        key: &[u8],
    ) -> Result<Self, ApprovalError> {
        let canonical = snapshot.canonical_text();
        let fingerprint = snapshot.fingerprint().to_string();
        let signature = mac(key, admin, approved_at, &fingerprint, &canonical)?;
        Ok(Self { admin: admin.into(), approved_at: approved_at.into(), fingerprint, canonical, signature })
    }

    /// Parses an approval file.
    pub fn from_toml(text: &str) -> Result<Self, ApprovalError> {
        toml::from_str(text).map_err(|e| ApprovalError::Format(e.to_string()))
    }

    /// The file text.
    pub fn to_toml(&self) -> Result<String, ApprovalError> {
        toml::to_string(self).map_err(|e| ApprovalError::Format(e.to_string()))
    }

    /// Checks the signature with `key` and returns the approved snapshot.
    pub fn verify(&self, key: &[u8]) -> Result<Snapshot, ApprovalError> {
        let expected = mac(key, &self.admin, &self.approved_at, &self.fingerprint, &self.canonical)?;
        // Constant-time comparison of the hex strings.
        let a = expected.as_bytes();
        let b = self.signature.as_bytes();
        let diff = a.iter().zip(b).fold(u8::from(a.len() != b.len()), |acc, (x, y)| acc | (x ^ y));
        if diff != 0 {
            return Err(ApprovalError::BadSignature);
        }
        let snapshot = Snapshot::from_canonical_text(&self.canonical).map_err(ApprovalError::Format)?;
        let actual: Fingerprint = snapshot.fingerprint();
        if actual.to_string() != self.fingerprint {
            return Err(ApprovalError::FingerprintMismatch {
                stated: self.fingerprint.clone(),
                actual: actual.to_string(),
            });
        }
        Ok(snapshot)
    }
}
