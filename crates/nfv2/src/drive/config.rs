//! Per-drive settings and the limits a 1209A enforces itself (device units).

/// Per-drive settings (device units).
#[derive(Debug, Clone, PartialEq)]
pub struct DriveConfig {
    /// Bus address (DIP switch).
    pub address: u8,
    /// Default profile speed of POSITION moves and holds, speed units (10 counts/s).
    pub speed: i64,
    /// Default acceleration of moves and jogs, counts/s².
    pub acceleration: i64,
    /// Acceleration of a quick stop, counts/s².
    pub quick_stop_acceleration: i64,
    /// A target is reached within this many counts.
    pub tolerance: i64,
    /// Below this speed (counts/s) the axis is at rest.
    pub standstill: f64,
    /// The drive's acceleration before we set one (its power-on value), counts/s².
    pub device_acceleration: i64,
    /// Fastest plausible axis speed for the plausibility gate, counts/s.
    pub plausible_speed: f64,
    /// Acceleration allowed beyond twice the drive's ramp (servo overshoot, coasting),
    /// counts/s², for the plausibility gate.
    pub plausible_extra_acceleration: f64,
}

impl DriveConfig {
    /// Defaults for the 1209A of the pan-tilt head at `address`: profile speed 5000
    /// units (50 000 counts/s), acceleration 200 000 counts/s², quick stop 1 000 000.
    #[must_use]
    pub fn new(address: u8) -> Self {
        DriveConfig {
            address,
            speed: 5_000,
            acceleration: 200_000,
            quick_stop_acceleration: 1_000_000,
            tolerance: 5,
            standstill: 200.0,
            device_acceleration: 1_000_000,
            plausible_speed: 200_000.0,
            plausible_extra_acceleration: 200_000.0,
        }
    }
}

/// Limits the drive enforces itself (it clamps and flags status bits 10-12).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DeviceLimits {
    /// Position limits `(min, max)`, counts; `(0, 0)` switches them off.
    pub position: Option<(i64, i64)>,
    /// Speed limit, speed units.
    pub max_speed: Option<i64>,
    /// Current limit, mA.
    pub max_current_ma: Option<i64>,
    /// Acceleration of the trajectory generator and ramps, counts/s².
    pub max_acceleration: Option<i64>,
}
