//! Remote-laboratory domain layer ("Lablink", `specs/remote-lab.md`): users with Argon2id
//! passwords and roles, login sessions with CSRF tokens, a login rate limiter, reservations
//! of a station by time slot with end-of-slot cleanup, the single authorisation decision,
//! an audit log, alarms, and the storage behind them (SQLite by default, or memory).
//!
//! Pure library: no HTTP, no clock reads, and no threads except the small pool that runs
//! the Argon2 work ([`hashing`]). Every operation takes the current time as a [`UnixMs`]
//! argument (convert `SystemTime::now()` with `UnixMs::from`).
//!
//! No interface here can set SafeToRun: [`Action`] has no such variant for any role.

#![forbid(unsafe_code)]

pub mod alarm;
pub mod audit;
pub mod authz;
pub mod config;
pub mod hashing;
pub mod lab;
pub mod limiter;
pub mod password;
pub mod program;
pub mod reservation;
pub mod role;
pub mod session;
pub mod store;
pub mod time;
pub mod users;

pub use alarm::{Ack, AckOutcome, Alarm, AlarmQuery, Alarms, Severity};
pub use audit::{Audit, AuditEntry, AuditOutcome, AuditQuery, AuditRecord};
pub use authz::{
    decide, Action, Actor, Authorizer, AuthzError, AxisOp, Command, Denied, DenyReason, Facts, MotionDemand,
    MotionLimits, StudentLimits,
};
pub use config::LabConfig;
pub use hashing::{HashPool, HashPoolError};
pub use lab::{EndSessionError, EndedSession, Lab, LoginError, LoginSuccess};
pub use limiter::{Attempt, LimitKey, LimiterPolicy, LoginLimiter, RateLimited};
pub use password::{HashParams, PasswordPolicy, PolicyViolation};
pub use program::{ProgramKind, ProgramMeta, Programs};
pub use reservation::{
    Cleanup, CleanupAction, Reservation, ReservationError, ReservationPolicy, Reservations,
};
pub use role::Role;
pub use session::{CookieConfig, SessionError, SessionInfo, SessionPolicy, Sessions};
pub use store::{MemoryStore, ReservationFilter, SqliteStore, Store, StoreError};
pub use time::UnixMs;
pub use users::{User, UserError, Users};
