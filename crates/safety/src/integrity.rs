//! Integrity of the safety configuration: a SHA-256 fingerprint of the canonical form
//! of the rules and of the drive parameters they rely on, a check that names what
//! changed, and an explicit administrator approval as the only way to accept a change.
//!
//! The canonical form is a sorted list of `key=value` lines (`axis[arm_left].limits.max=1000.0`,
//! `drive[arm_left].serial_number="A1234"`, `module[x20safety].sha256=...`), one per line,
//! hashed as UTF-8. It does not depend on comments, whitespace or the spelling of
//! expressions in the TOML file. Replaces the seed's size comparison of tasks (spec:
//! "compare configuration by cryptographic hash, not size").
//!
//! Roles: this crate only checks an [`AdminToken`] against the SHA-256 of the
//! administrator secret given to [`Integrity::new`]. The station (remote lab) provides the
//! roles: it hands a token only to an authenticated administrator and never to student
//! programs. The homed flag is not part of the fingerprint: it changes at every homing and
//! is supervised each cycle (`homeOK`).

use crate::rules::RuleSet;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::fmt;
use thiserror::Error;

/// Drive parameters the supervisor relies on, as read from one amplifier.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveParameters {
    /// Axis name (as in the rules config).
    pub axis: String,
    /// Field-bus node id of the amplifier.
    pub node_id: u32,
    /// Serial number of the amplifier.
    pub serial_number: String,
    /// Quick-stop deceleration parameter (`a_stop`).
    pub a_stop: f64,
    /// Acceleration limits `a1_pos`, `a1_neg`, `a2_pos`, `a2_neg`.
    pub accel_limits: [f64; 4],
    /// Homing offset.
    pub homing_offset: f64,
    /// Homing mode (drive-specific code).
    pub homing_mode: i32,
    /// Encoder counting direction inverted.
    pub encoder_inverted: bool,
    /// Encoder scaling (raw units per algorithm unit).
    pub encoder_scaling: f64,
    /// Digital input levels (bit mask).
    pub input_levels: u32,
    /// Current motion mode (drive-specific code).
    pub motion_mode: i32,
}

/// SHA-256 fingerprint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Fingerprint(pub [u8; 32]);

impl fmt::Display for Fingerprint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0.iter().try_for_each(|b| write!(f, "{b:02x}"))
    }
}

/// Canonical description of everything covered by the fingerprint.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Snapshot {
    lines: BTreeMap<String, String>,
}

impl Snapshot {
    /// Snapshot of a rule set and the drive parameters of its axes.
    pub fn new(rules: &RuleSet, drives: &[DriveParameters]) -> Snapshot {
        let mut lines: BTreeMap<String, String> = rules.canonical_lines().into_iter().collect();
        for d in drives {
            let k = |f: &str| format!("drive[{}].{f}", d.axis);
            lines.insert(k("node_id"), d.node_id.to_string());
            lines.insert(k("serial_number"), format!("{:?}", d.serial_number));
            lines.insert(k("a_stop"), format!("{:?}", d.a_stop));
            for (n, v) in ["a1_pos", "a1_neg", "a2_pos", "a2_neg"].iter().zip(d.accel_limits) {
                lines.insert(k(n), format!("{v:?}"));
            }
            lines.insert(k("homing_offset"), format!("{:?}", d.homing_offset));
            lines.insert(k("homing_mode"), d.homing_mode.to_string());
            lines.insert(k("encoder_inverted"), d.encoder_inverted.to_string());
            lines.insert(k("encoder_scaling"), format!("{:?}", d.encoder_scaling));
            lines.insert(k("input_levels"), format!("{:#x}", d.input_levels));
            lines.insert(k("motion_mode"), d.motion_mode.to_string());
        }
        Snapshot { lines }
    }

    /// Adds a supervised software module (task, I/O mapping) by the SHA-256 of its bytes.
    pub fn with_module(mut self, name: &str, bytes: &[u8]) -> Snapshot {
        let digest = Fingerprint(Sha256::digest(bytes).into());
        self.lines.insert(format!("module[{name}].sha256"), digest.to_string());
        self
    }

    /// The canonical text that is hashed.
    pub fn canonical_text(&self) -> String {
        let mut s = String::new();
        for (k, v) in &self.lines {
            s.push_str(k);
            s.push('=');
            s.push_str(v);
            s.push('\n');
        }
        s
    }

    /// Parses [`Snapshot::canonical_text`] back (`key=value` lines, sorted, no duplicates).
    pub fn from_canonical_text(text: &str) -> Result<Snapshot, String> {
        let mut lines = BTreeMap::new();
        for (i, line) in text.lines().enumerate() {
            let (k, v) = line.split_once('=').ok_or_else(|| format!("line {}: no '=' in {line:?}", i + 1))?;
            if lines.insert(k.to_owned(), v.to_owned()).is_some() {
                return Err(format!("line {}: key {k:?} given twice", i + 1));
            }
        }
        Ok(Snapshot { lines })
    }

    /// SHA-256 of [`Snapshot::canonical_text`].
    pub fn fingerprint(&self) -> Fingerprint {
        Fingerprint(Sha256::digest(self.canonical_text().as_bytes()).into())
    }

    /// Differences from `approved` to `self`, sorted by key.
    pub fn diff(&self, approved: &Snapshot) -> Vec<Change> {
        let mut out = Vec::new();
        for (k, v) in &approved.lines {
            match self.lines.get(k) {
                Some(c) if c == v => {}
                c => out.push(Change { key: k.clone(), approved: Some(v.clone()), current: c.cloned() }),
            }
        }
        for (k, c) in &self.lines {
            if !approved.lines.contains_key(k) {
                out.push(Change { key: k.clone(), approved: None, current: Some(c.clone()) });
            }
        }
        out.sort_by(|a, b| a.key.cmp(&b.key));
        out
    }
}

/// One changed, added or removed field.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Change {
    /// Field key (`axis[arm_left].limits.max`, `rule[5].arms_pass`, `drive[x].serial_number`).
    pub key: String,
    /// Approved value (`None`: the field is new).
    pub approved: Option<String>,
    /// Current value (`None`: the field disappeared).
    pub current: Option<String>,
}

impl fmt::Display for Change {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let o = |v: &Option<String>| v.clone().unwrap_or_else(|| "(absent)".into());
        write!(f, "{}: {} -> {}", self.key, o(&self.approved), o(&self.current))
    }
}

/// Integrity failures.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum IntegrityError {
    /// The current configuration differs from the approved one.
    #[error("configuration changed (fingerprint {current}): {}", list(changes))]
    Changed {
        /// Fingerprint of the current configuration (what an administrator would approve).
        current: Fingerprint,
        /// What changed.
        changes: Vec<Change>,
    },
    /// The token is not the administrator's.
    #[error("approval refused: not an administrator token")]
    NotAuthorised,
    /// The fingerprint to approve is not the one last seen by [`Integrity::check`].
    #[error("approval refused: fingerprint {given} is not the pending change ({pending})")]
    NotPending {
        /// Fingerprint given to approve.
        given: Fingerprint,
        /// Pending fingerprint, if any.
        pending: String,
    },
}

fn list(c: &[Change]) -> String {
    c.iter().map(ToString::to_string).collect::<Vec<_>>().join("; ")
}

/// Credential of an administrator, created by the station after authenticating one.
#[derive(Clone)]
pub struct AdminToken {
    admin: String,
    secret: Vec<u8>,
}

impl AdminToken {
    /// Token for administrator `admin` holding `secret`.
    pub fn new(admin: impl Into<String>, secret: impl Into<Vec<u8>>) -> AdminToken {
        AdminToken { admin: admin.into(), secret: secret.into() }
    }
    /// Administrator name (for logs).
    pub fn admin(&self) -> &str {
        &self.admin
    }
}

impl fmt::Debug for AdminToken {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "AdminToken({}, <secret>)", self.admin)
    }
}

/// SHA-256 of an administrator secret (what the station stores instead of the secret).
pub fn secret_hash(secret: &[u8]) -> [u8; 32] {
    Sha256::digest(secret).into()
}

/// The approved configuration and the approval gate.
#[derive(Debug, Clone)]
pub struct Integrity {
    approved: Snapshot,
    approved_fp: Fingerprint,
    pending: Option<Snapshot>,
    admin_hash: [u8; 32],
}

impl Integrity {
    /// Starts from an approved snapshot (installed by an administrator) and the SHA-256 of
    /// the administrator secret ([`secret_hash`]).
    pub fn new(approved: Snapshot, admin_secret_hash: [u8; 32]) -> Integrity {
        let approved_fp = approved.fingerprint();
        Integrity { approved, approved_fp, pending: None, admin_hash: admin_secret_hash }
    }

    /// Fingerprint of the approved configuration.
    pub fn approved(&self) -> Fingerprint {
        self.approved_fp
    }

    /// Compares `current` with the approved snapshot; on a difference, remembers it as the
    /// pending change and names every changed field.
    pub fn check(&mut self, current: &Snapshot) -> Result<(), IntegrityError> {
        let fp = current.fingerprint();
        if fp == self.approved_fp {
            return Ok(());
        }
        let changes = current.diff(&self.approved);
        tracing::warn!(fingerprint = %fp, changes = changes.len(), "safety configuration changed");
        self.pending = Some(current.clone());
        Err(IntegrityError::Changed { current: fp, changes })
    }

    /// Accepts the pending change whose fingerprint is `new_fingerprint`; the only way
    /// to change the approved configuration.
    pub fn approve(
        &mut self,
        new_fingerprint: Fingerprint,
        token: &AdminToken,
    ) -> Result<(), IntegrityError> {
        let h = secret_hash(&token.secret);
        let diff = h.iter().zip(self.admin_hash.iter()).fold(0u8, |acc, (a, b)| acc | (a ^ b));
        if diff != 0 {
            tracing::warn!(admin = token.admin, "refused approval with a wrong token");
            return Err(IntegrityError::NotAuthorised);
        }
        match self.pending.take() {
            Some(p) if p.fingerprint() == new_fingerprint => {
                tracing::info!(admin = token.admin, fingerprint = %new_fingerprint, "safety configuration approved");
                self.approved = p;
                self.approved_fp = new_fingerprint;
                Ok(())
            }
            other => {
                let pending = other.as_ref().map_or("none".to_string(), |p| p.fingerprint().to_string());
                self.pending = other;
                Err(IntegrityError::NotPending { given: new_fingerprint, pending })
            }
        }
    }
}
