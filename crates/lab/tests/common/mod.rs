//! Helpers shared by the integration tests.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, dead_code)]

use std::sync::Arc;

use motus_lab::{HashParams, Lab, LabConfig, MemoryStore, MotionLimits, Role, SqliteStore, Store, UnixMs};

/// Cheap Argon2 parameters (debug builds hash slowly); verification reads them from the hash.
pub const FAST: HashParams = HashParams { memory_kib: 64, iterations: 1, parallelism: 1 };

pub const MIN: i64 = 60_000;
pub const HOUR: i64 = 3_600_000;

/// 2030-01-01T00:00:00Z in ms (python: int(datetime(2030,1,1,tzinfo=timezone.utc).timestamp()*1000)).
pub const T0: UnixMs = UnixMs(1_893_456_000_000);

pub fn at(offset_ms: i64) -> UnixMs {
    UnixMs(T0.0 + offset_ms)
}

pub fn config() -> LabConfig {
    let mut c = LabConfig::default();
    c.password.hash = FAST;
    c.student_limits.axes.insert("x".into(), MotionLimits::new(1.0, 10.0));
    c
}

/// One memory store and one SQLite (in-memory) store: every behaviour test runs on both.
pub fn stores() -> Vec<(&'static str, Arc<dyn Store>)> {
    vec![
        ("memory", Arc::new(MemoryStore::new()) as Arc<dyn Store>),
        ("sqlite", Arc::new(SqliteStore::open_in_memory().unwrap()) as Arc<dyn Store>),
    ]
}

/// A lab with users `admin` (admin), `alice` and `bob` (students), `vera` (viewer),
/// all with password `password-<name>`.
pub fn lab_with_users(store: Arc<dyn Store>) -> Lab {
    let lab = Lab::new(store, config());
    for (name, role) in
        [("admin", Role::Admin), ("alice", Role::Student), ("bob", Role::Student), ("vera", Role::Viewer)]
    {
        lab.users().add(name, &format!("password-{name}"), role, T0).unwrap();
    }
    lab
}

pub fn labs() -> Vec<(&'static str, Lab)> {
    stores().into_iter().map(|(n, s)| (n, lab_with_users(s))).collect()
}
