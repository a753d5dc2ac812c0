//! The approved safety configuration on disk: the one place that reads the administrator
//! key, the rules and the drive-parameter file, builds the [`Snapshot`] they make, checks it
//! against the signed approval and signs a new approval.
//!
//! `motus safety approve`/`run`, the station (its integrity watcher and the administrator's
//! rule change) and the tests all call these functions:
//!
//! - [`ConfigFiles::check`]: the integrity check (approval verified with the key, then the
//!   current rules and drive parameters compared with the approved snapshot through
//!   [`Integrity`]; a change is reported field by field, e.g.
//!   `drive[thrower].a_stop: 20000000.0 -> 15000000.0`).
//! - [`approve`]: the approval signer ([`Approval::sign`], then the file written atomically).
//! - [`read_key`], [`read_rules`], [`read_drives`], [`read_snapshot`],
//!   [`snapshot_with_drives`]: the pieces.
//!
//! The drive-parameter file is TOML, one `[[drive]]` table per amplifier with the fields of
//! [`DriveParameters`] (`crates/safety/examples/juggler-drives.toml`).

use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::approval::{Approval, ApprovalError};
use crate::integrity::{secret_hash, DriveParameters, Integrity, IntegrityError, Snapshot};
use crate::rules::{ConfigError, RuleSet};

/// The way out when the administrator key or the approval does not exist yet.
fn missing_hint(what: &str, source: &std::io::Error) -> &'static str {
    match (what, source.kind()) {
        ("key" | "approval", std::io::ErrorKind::NotFound) => {
            " (an administrator writes the key file and approves the rules with `motus safety approve \
             --rules R [--drives D] --key K --admin NAME --out A`; `motus demo --write-cell DIR` writes a cell \
             with both)"
        }
        _ => "",
    }
}

/// What a configuration file operation failed on.
#[derive(Debug, Error)]
pub enum FilesError {
    /// A file cannot be read.
    #[error("cannot read the {what} {}: {source}{}", path.display(), missing_hint(what, source))]
    Read {
        /// Which file (`key`, `rules`, `drive parameters`, `approval`).
        what: &'static str,
        /// Its path.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A file cannot be written.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// Its path.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The rules file is not a valid rule set.
    #[error("rules {}: {source}", path.display())]
    Rules {
        /// The rules file.
        path: PathBuf,
        /// Why.
        source: ConfigError,
    },
    /// The drive-parameter file is not valid (`[[drive]]` tables of [`DriveParameters`]).
    #[error("drive parameters {}: {reason}", path.display())]
    Drives {
        /// The drive-parameter file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// The approval file is invalid, or its signature does not verify with the key, or it
    /// cannot be signed (key too short).
    #[error("approval {}: {source}", path.display())]
    Approval {
        /// The approval file.
        path: PathBuf,
        /// Why.
        source: ApprovalError,
    },
    /// The current configuration differs from the approved one; the message names every
    /// changed field (`axis[thrower].limits.max: 3400.0 -> 9400.0`,
    /// `drive[thrower].a_stop: 20000000.0 -> 15000000.0`).
    #[error(transparent)]
    Changed(#[from] IntegrityError),
}

/// The drive-parameter file: one `[[drive]]` table per amplifier.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DrivesFile {
    /// The drives, in file order.
    #[serde(default)]
    pub drive: Vec<DriveParameters>,
}

impl DrivesFile {
    /// Parses the file's text.
    ///
    /// # Errors
    /// Not TOML, an unknown or missing field, a value of the wrong type (the message says
    /// which).
    pub fn from_toml(text: &str) -> Result<Self, String> {
        toml::from_str(text).map_err(|e| e.to_string())
    }

    /// The file's text.
    ///
    /// # Errors
    /// A value TOML cannot represent (e.g. NaN).
    pub fn to_toml(&self) -> Result<String, String> {
        toml::to_string(self).map_err(|e| e.to_string())
    }
}

fn read(what: &'static str, path: &Path) -> Result<Vec<u8>, FilesError> {
    std::fs::read(path).map_err(|source| FilesError::Read { what, path: path.to_path_buf(), source })
}

fn read_text(what: &'static str, path: &Path) -> Result<String, FilesError> {
    std::fs::read_to_string(path).map_err(|source| FilesError::Read {
        what,
        path: path.to_path_buf(),
        source,
    })
}

/// Reads the administrator key file, trailing whitespace (a final newline) removed.
///
/// # Errors
/// [`FilesError::Read`] naming the file.
pub fn read_key(path: &Path) -> Result<Vec<u8>, FilesError> {
    let mut key = read("key", path)?;
    while key.last().is_some_and(u8::is_ascii_whitespace) {
        key.pop();
    }
    Ok(key)
}

/// Reads and validates the rules file.
///
/// # Errors
/// [`FilesError::Read`], or [`FilesError::Rules`] with what is wrong in it.
pub fn read_rules(path: &Path) -> Result<RuleSet, FilesError> {
    let text = read_text("rules", path)?;
    RuleSet::from_toml(&text).map_err(|source| FilesError::Rules { path: path.to_path_buf(), source })
}

/// Reads the drive-parameter file (TOML `[[drive]]` tables of [`DriveParameters`]).
///
/// # Errors
/// [`FilesError::Read`], or [`FilesError::Drives`] with what is wrong in it.
pub fn read_drives(path: &Path) -> Result<Vec<DriveParameters>, FilesError> {
    let text = read_text("drive parameters", path)?;
    DrivesFile::from_toml(&text)
        .map(|f| f.drive)
        .map_err(|reason| FilesError::Drives { path: path.to_path_buf(), reason })
}

/// Writes `drives` as a drive-parameter file at `path` (atomically, see
/// [`write_atomically`]).
///
/// # Errors
/// [`FilesError::Drives`] (a value TOML cannot hold) or [`FilesError::Write`].
pub fn write_drives(path: &Path, drives: &[DriveParameters]) -> Result<(), FilesError> {
    let text = DrivesFile { drive: drives.to_vec() }
        .to_toml()
        .map_err(|reason| FilesError::Drives { path: path.to_path_buf(), reason })?;
    write_atomically(path, text.as_bytes())
}

/// The snapshot of `rules` and the drive parameters in `drives` (none without a file).
///
/// # Errors
/// The drive-parameter file cannot be read or is invalid.
pub fn snapshot_with_drives(rules: &RuleSet, drives: Option<&Path>) -> Result<Snapshot, FilesError> {
    let d = drives.map(read_drives).transpose()?.unwrap_or_default();
    Ok(Snapshot::new(rules, &d))
}

/// Reads the rules and the drive parameters and returns the rules and their snapshot (what
/// an administrator approves, and what is compared with the approval).
///
/// # Errors
/// A file cannot be read or is invalid.
pub fn read_snapshot(rules: &Path, drives: Option<&Path>) -> Result<(RuleSet, Snapshot), FilesError> {
    let set = read_rules(rules)?;
    let snap = snapshot_with_drives(&set, drives)?;
    Ok((set, snap))
}

/// Writes `bytes` to `path` through a temporary file in the same folder (synced) and a
/// rename, so a reader sees the old file or the new one, never half a file.
///
/// # Errors
/// [`FilesError::Write`] naming `path`.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), FilesError> {
    let failed = |source| FilesError::Write { path: path.to_path_buf(), source };
    let mut name = path.file_name().map(ToOwned::to_owned).unwrap_or_default();
    name.push(format!(".tmp-motus-{}", std::process::id()));
    let tmp = path.with_file_name(name);
    let written = std::fs::File::create(&tmp).and_then(|mut f| {
        f.write_all(bytes)?;
        f.sync_all()
    });
    if let Err(e) = written.and_then(|()| std::fs::rename(&tmp, path)) {
        let _ = std::fs::remove_file(&tmp);
        return Err(failed(e));
    }
    Ok(())
}

/// The approval signer: signs `snapshot` as approved by `admin` at `approved_at` (free text,
/// e.g. `unix:1700000000`) with the administrator `key` ([`Approval::sign`]) and writes the
/// approval file `out` atomically. Nothing is written when signing fails.
///
/// # Errors
/// [`FilesError::Approval`] (key too short) or [`FilesError::Write`].
pub fn approve(
    snapshot: &Snapshot,
    admin: &str,
    approved_at: &str,
    key: &[u8],
    out: &Path,
) -> Result<Approval, FilesError> {
    let approval_err = |source| FilesError::Approval { path: out.to_path_buf(), source };
    let approval = Approval::sign(snapshot, admin, approved_at, key).map_err(approval_err)?;
    let text = approval.to_toml().map_err(approval_err)?;
    write_atomically(out, text.as_bytes())?;
    tracing::info!(admin, fingerprint = %approval.fingerprint, file = %out.display(), "safety configuration approved");
    Ok(approval)
}

/// The files of an approved safety configuration (what `motus safety run` and the cell's
/// `[supervisor]` table name).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigFiles {
    /// The rules file.
    pub rules: PathBuf,
    /// The drive-parameter file (`None`: no drive parameters are supervised).
    pub drives: Option<PathBuf>,
    /// The approval file (written by [`approve`]).
    pub approval: PathBuf,
    /// The administrator key file.
    pub key: PathBuf,
}

impl ConfigFiles {
    /// The approved snapshot: the approval file, its signature verified with `key`.
    ///
    /// # Errors
    /// [`FilesError::Read`] or [`FilesError::Approval`] (invalid file, signature or
    /// fingerprint that does not match).
    pub fn approved(&self, key: &[u8]) -> Result<Snapshot, FilesError> {
        let text = read_text("approval", &self.approval)?;
        Approval::from_toml(&text)
            .and_then(|a| a.verify(key))
            .map_err(|source| FilesError::Approval { path: self.approval.clone(), source })
    }

    /// The integrity check: verifies the approval with the key, reads the current rules and
    /// drive parameters and compares their snapshot with the approved one. Returns the
    /// (approved) rules.
    ///
    /// # Errors
    /// A file cannot be read or is invalid, the approval does not verify, or
    /// [`FilesError::Changed`] naming every field that differs from the approval.
    pub fn check(&self) -> Result<RuleSet, FilesError> {
        let key = read_key(&self.key)?;
        let approved = self.approved(&key)?;
        let (rules, current) = read_snapshot(&self.rules, self.drives.as_deref())?;
        Integrity::new(approved, secret_hash(&key)).check(&current)?;
        Ok(rules)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]
    use super::*;
    use crate::{JUGGLER_DRIVES_TOML, JUGGLER_TOML};

    const KEY: &str = "an-administrator-key-0123456789\n";

    /// The shipped juggler rules and drives, a key and an approval of both in `dir`.
    fn approved_files(dir: &Path) -> ConfigFiles {
        let files = ConfigFiles {
            rules: dir.join("juggler.toml"),
            drives: Some(dir.join("drives.toml")),
            approval: dir.join("juggler.approved"),
            key: dir.join("admin.key"),
        };
        std::fs::write(&files.rules, JUGGLER_TOML).unwrap();
        std::fs::write(files.drives.as_ref().unwrap(), JUGGLER_DRIVES_TOML).unwrap();
        std::fs::write(&files.key, KEY).unwrap();
        let (_, snap) = read_snapshot(&files.rules, files.drives.as_deref()).unwrap();
        approve(&snap, "alice", "test", &read_key(&files.key).unwrap(), &files.approval).unwrap();
        files
    }

    #[test]
    fn key_loses_trailing_whitespace_only() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("k");
        std::fs::write(&p, " a key \r\n\n").unwrap();
        assert_eq!(read_key(&p).unwrap(), b" a key");
        let e = read_key(&dir.path().join("missing.key")).unwrap_err();
        assert!(matches!(e, FilesError::Read { what: "key", .. }), "{e:?}");
        assert!(e.to_string().contains("missing.key"), "{e}");
    }

    #[test]
    fn approved_files_check_and_return_the_rules() {
        let dir = tempfile::tempdir().unwrap();
        let files = approved_files(dir.path());
        let rules = files.check().unwrap();
        assert_eq!(rules.axes().len(), 5);
        // No temporary file is left behind.
        let names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        assert!(names.iter().all(|n| !n.contains("tmp")), "{names:?}");
    }

    #[test]
    fn a_changed_drive_parameter_is_named_with_its_axis_and_field() {
        let dir = tempfile::tempdir().unwrap();
        let files = approved_files(dir.path());
        let path = files.drives.clone().unwrap();
        let mut drives = read_drives(&path).unwrap();
        let thrower = drives.iter_mut().find(|d| d.axis == "thrower").unwrap();
        let before = thrower.a_stop;
        thrower.a_stop = before * 0.75;
        write_drives(&path, &drives).unwrap();
        let e = files.check().unwrap_err();
        let FilesError::Changed(IntegrityError::Changed { changes, .. }) = &e else { panic!("{e:?}") };
        assert_eq!(changes.len(), 1, "{changes:?}");
        assert_eq!(changes[0].key, "drive[thrower].a_stop");
        let text = e.to_string();
        assert!(
            text.contains(&format!("drive[thrower].a_stop: {before:?} -> {:?}", before * 0.75)),
            "{text}"
        );
        // Restored: the check passes again.
        std::fs::write(&path, JUGGLER_DRIVES_TOML).unwrap();
        files.check().unwrap();
    }

    #[test]
    fn a_removed_drive_file_or_drive_is_a_change_or_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let files = approved_files(dir.path());
        let path = files.drives.clone().unwrap();
        let mut drives = read_drives(&path).unwrap();
        drives.retain(|d| d.axis != "arm_left");
        write_drives(&path, &drives).unwrap();
        let text = files.check().unwrap_err().to_string();
        assert!(text.contains("drive[arm_left].a_stop: ") && text.contains("-> (absent)"), "{text}");
        std::fs::remove_file(&path).unwrap();
        let e = files.check().unwrap_err();
        assert!(matches!(e, FilesError::Read { what: "drive parameters", .. }), "{e:?}");
        // Without a drive file in the configuration, the approved drives are missing.
        let none = ConfigFiles { drives: None, ..files };
        assert!(none.check().unwrap_err().to_string().contains("(absent)"));
    }

    #[test]
    fn changed_rules_a_forged_approval_and_bad_files_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let files = approved_files(dir.path());
        // A rule change.
        let edited = JUGGLER_TOML
            .replace("limits = { min = -7600, max = 3400 }", "limits = { min = -7600, max = 9400 }");
        std::fs::write(&files.rules, &edited).unwrap();
        let text = files.check().unwrap_err().to_string();
        assert!(text.contains("axis[thrower].limits.max: 3400.0 -> 9400.0"), "{text}");
        // Re-approved with another key: the signature does not verify.
        let (_, snap) = read_snapshot(&files.rules, files.drives.as_deref()).unwrap();
        approve(&snap, "mallory", "test", b"not-the-administrator-key", &files.approval).unwrap();
        let e = files.check().unwrap_err();
        assert!(matches!(e, FilesError::Approval { source: ApprovalError::BadSignature, .. }), "{e:?}");
        // Re-approved with the key: accepted.
        approve(&snap, "alice", "test", &read_key(&files.key).unwrap(), &files.approval).unwrap();
        files.check().unwrap();
        // A short key signs nothing and leaves the approval as it was.
        let before = std::fs::read(&files.approval).unwrap();
        let e = approve(&snap, "alice", "test", b"short", &files.approval).unwrap_err();
        assert!(matches!(e, FilesError::Approval { source: ApprovalError::KeyTooShort(5), .. }), "{e:?}");
        assert_eq!(std::fs::read(&files.approval).unwrap(), before);
        // Invalid rules and drive files name the file.
        std::fs::write(&files.rules, "[supervisor]\n").unwrap();
        assert!(matches!(files.check().unwrap_err(), FilesError::Rules { .. }));
        std::fs::write(&files.rules, JUGGLER_TOML).unwrap();
        std::fs::write(files.drives.as_ref().unwrap(), "[[drive]]\naxis = \"x\"\n").unwrap();
        let e = files.check().unwrap_err();
        assert!(matches!(e, FilesError::Drives { .. }), "{e:?}");
        assert!(e.to_string().contains("drives.toml"), "{e}");
        // No approval file.
        std::fs::remove_file(&files.approval).unwrap();
        assert!(matches!(files.check().unwrap_err(), FilesError::Read { what: "approval", .. }));
    }

    #[test]
    fn drive_files_round_trip() {
        let d = DrivesFile::from_toml(JUGGLER_DRIVES_TOML).unwrap();
        assert_eq!(d.drive.len(), 5);
        assert_eq!(DrivesFile::from_toml(&d.to_toml().unwrap()).unwrap(), d);
        assert!(DrivesFile::from_toml("").unwrap().drive.is_empty());
        assert!(DrivesFile::from_toml("[[drive]]\nbogus = 1\n").is_err());
    }
}
