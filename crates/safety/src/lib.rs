//! Predictive collision supervisor for servo machines (the juggler's `SafeToRun`),
//! after specs/juggler-safety.md. Protocol-independent and without clocks (samples and time
//! are passed in); only [`config_files`] touches the file system.
//!
//! - [`model`]: axis models and their validation.
//! - [`predict`]: reachable positions until standstill (worst-case acceleration during the
//!   horizon, then braking).
//! - [`expr`] and [`rules`]: rule expressions (limits, region, collision, interlocks,
//!   `&&`/`||`/`!`) and the TOML configuration.
//! - [`supervisor`]: per-cycle evaluation, [`supervisor::Lease`], diagnosis.
//! - [`fanout`]: quick-stop fan-out of decisions to every drive ([`fanout::StopTarget`], for any
//!   axis of the axis model or a field-bus broadcast), lease renewal and expiry.
//! - [`integrity`]: SHA-256 fingerprint of the configuration, change report, admin approval.
//! - [`approval`]: the administrator's signed approval file (HMAC-SHA256 with the admin key).
//! - [`config_files`]: the approved configuration on disk (key, rules, drive parameters,
//!   approval): the one integrity check ([`config_files::ConfigFiles::check`]) and the one
//!   approval signer ([`config_files::approve`]) of the CLI, the station and the tests.
//! - [`trace`]: offline evaluation of a CSV trace.
//! - [`sim`]: a simulated juggler for tests and benchmarks.
//!
//! There is deliberately no way to set SafeToRun from outside: it only results from
//! [`supervisor::Supervisor::evaluate`].

pub mod approval;
pub mod config_files;
pub mod expr;
pub mod fanout;
pub mod integrity;
pub mod model;
pub mod predict;
pub mod rules;
pub mod sim;
pub mod supervisor;
pub mod trace;

pub use approval::{Approval, ApprovalError};
pub use config_files::{ConfigFiles, DrivesFile, FilesError};
pub use fanout::{AxisStop, Fanout, FanoutReport, Restart, StopError, StopTarget};
pub use integrity::{
    secret_hash, AdminToken, DriveParameters, Fingerprint, Integrity, IntegrityError, Snapshot,
};
pub use model::{AxisModel, Limits, ModelError, Unit, UpDown};
pub use rules::{ConfigError, RuleSet, SafetyConfig};
pub use supervisor::{CycleInput, Decision, Diagnosis, Lease, Mode, Sample, Supervisor};

/// The juggler's rule set shipped with the crate (`examples/juggler.toml`).
pub const JUGGLER_TOML: &str = include_str!("../examples/juggler.toml");

/// The juggler's drive parameters shipped with the crate (`examples/juggler-drives.toml`:
/// the simulated juggler's five amplifiers, consistent with [`JUGGLER_TOML`]).
pub const JUGGLER_DRIVES_TOML: &str = include_str!("../examples/juggler-drives.toml");
