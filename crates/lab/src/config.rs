//! The laboratory section of a station configuration (TOML), every field defaulted.
//!
//! ```toml
//! [password]
//! min_length = 12
//! [sessions]
//! idle_timeout_secs = 1800
//! cookie = { secure = false }          # plain http on localhost only
//! [limiter]
//! user_max_failures = 5
//! [reservations]
//! max_slot_secs = 7200
//! [student_limits.axes.arm_left]
//! max_speed = 87.266                   # rad/s (5000 deg/s)
//! max_acceleration = 872.66            # rad/s^2 (50 000 deg/s^2)
//! ```

use serde::{Deserialize, Serialize};

use crate::authz::StudentLimits;
use crate::limiter::LimiterPolicy;
use crate::password::PasswordPolicy;
use crate::reservation::ReservationPolicy;
use crate::session::SessionPolicy;

/// Every policy of the laboratory layer.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LabConfig {
    /// Password rules and hashing cost.
    pub password: PasswordPolicy,
    /// Session lifetimes and cookie.
    pub sessions: SessionPolicy,
    /// Login rate limits.
    pub limiter: LimiterPolicy,
    /// Booking rules.
    pub reservations: ReservationPolicy,
    /// Student motion limits per axis.
    pub student_limits: StudentLimits,
}
