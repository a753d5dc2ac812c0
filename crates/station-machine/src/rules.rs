//! An administrator installs new supervisor rules through the station (`PUT
//! /api/safety/rules`; the web layer lets only admins through and audits the call): the text
//! is checked, must describe the same drives as the running machine, is signed together with
//! the cell's drive parameters (the `[supervisor] drives` file, unchanged) with the cell's
//! administrator key into its approval file by the one approval signer
//! ([`motus_safety::config_files::approve`], as `motus safety approve`), written over the
//! cell's rules file, and loaded into the running supervisor, which stops and holds the
//! drives until an operator's reset. The fingerprint shown changes with it.

use std::sync::PoisonError;

use motus_safety::config_files::{self, FilesError};
use motus_safety::RuleSet;
use motus_station_web::{BackendError, Caller};

use crate::Shared;

fn state(e: FilesError) -> BackendError {
    BackendError::State(e.to_string())
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
    let key = config_files::read_key(key_path).map_err(state)?;
    let snapshot = config_files::snapshot_with_drives(&rules, sup.drives.as_deref()).map_err(state)?;
    let fingerprint = snapshot.fingerprint().to_string();
    let approved_at = motus_lab::UnixMs::from(std::time::SystemTime::now()).0.to_string();
    // Signed first: a key that signs nothing leaves both files as they were. Between the two
    // renames the integrity watcher may see a difference: a stop (fail closed), and the new
    // rules hold the drives until a reset anyway.
    config_files::approve(&snapshot, &caller.user, &approved_at, &key, approval_path).map_err(state)?;
    config_files::write_atomically(&sup.rules, toml.as_bytes()).map_err(state)?;
    juggler.install_rules(rules.clone()).map_err(BackendError::State)?;
    *shared.rules_fingerprint.write().unwrap_or_else(PoisonError::into_inner) = fingerprint.clone();
    *shared.rule_limits.write().unwrap_or_else(PoisonError::into_inner) =
        rules.axes().iter().map(|a| (a.name.clone(), a.limits.min, a.limits.max)).collect();
    tracing::warn!(admin = %caller.user, %fingerprint, "new supervisor rules installed");
    Ok(fingerprint)
}
