//! An administrator installs new supervisor rules through the station (`PUT
//! /api/safety/rules`; the web layer lets only admins through and audits the call): the text
//! is checked, must describe the same drives as the running machine, is written over the
//! cell's rules file, signed with the cell's administrator key into its approval file (as
//! `motus safety approve` would), and loaded into the running supervisor, which stops and
//! holds the drives until an operator's reset. The fingerprint shown changes with it.

use std::path::Path;
use std::sync::PoisonError;

use motus_safety::{Approval, RuleSet, Snapshot};
use motus_station_web::{BackendError, Caller};

use crate::Shared;

/// Writes `text` to `path` through a temporary file in the same folder and a rename, so a
/// reader never sees half a file.
fn write_atomically(path: &Path, text: &str) -> Result<(), BackendError> {
    let failed = |e: std::io::Error| BackendError::State(format!("cannot write {}: {e}", path.display()));
    let tmp = path.with_extension("tmp-motus");
    std::fs::write(&tmp, text).map_err(failed)?;
    std::fs::rename(&tmp, path).map_err(failed)
}

/// The rules' drives: (name, node id), in order.
fn drives(rules: &RuleSet) -> Vec<(String, u32)> {
    rules.axes().iter().map(|a| (a.name.clone(), a.id)).collect()
}

/// Checks, writes, approves and installs `toml` (see the module documentation); returns
/// the new fingerprint.
pub(crate) fn install(shared: &Shared, caller: &Caller, toml: &str) -> Result<String, BackendError> {
    let (Some(sup), Some(juggler)) = (shared.config.supervisor.as_ref(), shared.juggler.as_ref()) else {
        return Err(BackendError::State("this cell has no supervisor".into()));
    };
    let rules = RuleSet::from_toml(toml).map_err(|e| BackendError::invalid("rules", e.to_string()))?;
    let running = std::fs::read_to_string(&sup.rules)
        .ok()
        .and_then(|t| RuleSet::from_toml(&t).ok())
        .map(|r| drives(&r))
        .unwrap_or_default();
    if drives(&rules) != running {
        return Err(BackendError::invalid(
            "rules",
            format!("the rules must describe the machine's drives {running:?}, not {:?}", drives(&rules)),
        ));
    }
    let (Some(key_path), Some(approval_path)) = (sup.key.as_ref(), sup.approval.as_ref()) else {
        return Err(BackendError::State(
            "the cell names no administrator key and approval file: rules cannot be approved here".into(),
        ));
    };
    let key = motus_cell::juggler::read_key(key_path).map_err(BackendError::State)?;
    let snapshot = Snapshot::new(&rules, &[]);
    let fingerprint = snapshot.fingerprint().to_string();
    let approved_at = motus_lab::UnixMs::from(std::time::SystemTime::now()).0.to_string();
    let approval = Approval::sign(&snapshot, &caller.user, &approved_at, &key)
        .and_then(|a| a.to_toml())
        .map_err(|e| BackendError::State(format!("cannot sign the approval: {e}")))?;
    write_atomically(&sup.rules, toml)?;
    write_atomically(approval_path, &approval)?;
    juggler.install_rules(rules.clone());
    *shared.rules_fingerprint.write().unwrap_or_else(PoisonError::into_inner) = fingerprint.clone();
    *shared.rule_limits.write().unwrap_or_else(PoisonError::into_inner) =
        rules.axes().iter().map(|a| (a.name.clone(), a.limits.min, a.limits.max)).collect();
    tracing::warn!(admin = %caller.user, %fingerprint, "new supervisor rules installed");
    Ok(fingerprint)
}
