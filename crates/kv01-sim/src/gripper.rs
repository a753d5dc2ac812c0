//! The gripper's open/close motor, driven by module 0xE6 itself (D5 speed and direction,
//! D1 0xC1/0xC0 current limitation; `specs/kv01.md`).
//!
//! The jaws move at `speed / 31` of a full stroke per `full_stroke_s`, between closed (0)
//! and open (1); closing jaws stop at an object (`object_opening`). The load (0..=31,
//! reported in D5) is small while the jaws move (`2 + speed / 4`, friction) and is the stall
//! load `min(31, 2 * speed)` while they are blocked (end stop or object: stall current rises
//! with the drive level). Over-current = load above `over_current_load`; with the current
//! limitation on, `trip_after_ms` of continuous over-current switches the motor off until
//! a D5 with speed 0 re-arms it. BRAKE (software brake released) = the motor is driven.

use motus_kv01_protocol::{GripperLoad, GripperStatus};

use crate::config::GripperConfig;

/// Highest D5 speed.
const MAX_SPEED: u8 = 31;

/// The open/close drive.
#[derive(Debug, Clone)]
pub(crate) struct Gripper {
    config: GripperConfig,
    opening: f64,
    speed: u8,
    opening_direction: bool,
    current_limit: bool,
    over_current_s: f64,
    tripped: bool,
    load: u8,
    object: Option<f64>,
}

/// A snapshot of the gripper for tests and status displays.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GripperState {
    /// Jaw opening, 0 (closed) ..= 1 (open).
    pub opening: f64,
    /// Commanded speed (0..=31).
    pub speed: u8,
    /// Commanded direction: opening (PHASE).
    pub opening_direction: bool,
    /// The current limitation is on (LIMIT).
    pub current_limit: bool,
    /// The current limitation has switched the motor off (re-arm: D5 speed 0).
    pub tripped: bool,
    /// Motor load, 0..=31.
    pub load: u8,
    /// The motor is driven (BRAKE: software brake released).
    pub driven: bool,
}

impl Gripper {
    /// The gripper at its first power-on.
    pub(crate) fn new(config: GripperConfig) -> Self {
        Self {
            config,
            opening: config.initial_opening.clamp(0.0, 1.0),
            speed: 0,
            opening_direction: false,
            current_limit: config.current_limit_at_power_on,
            over_current_s: 0.0,
            tripped: false,
            load: 0,
            object: config.object_opening,
        }
    }

    /// Power off and on: motor off, power-on current limitation; the jaws stay where they are.
    pub(crate) fn power_cycle(&mut self) {
        let (opening, object) = (self.opening, self.object);
        *self = Self { opening, object, ..Self::new(self.config) };
    }

    /// Puts an object between the jaws at `opening` (or removes it).
    pub(crate) fn set_object(&mut self, opening: Option<f64>) {
        self.object = opening.map(|o| o.clamp(0.0, 1.0));
    }

    fn driven(&self) -> bool {
        self.speed > 0 && !self.tripped
    }

    /// D5: speed (0..=31) and direction. Speed 0 stops the motor and re-arms a trip;
    /// while tripped any other speed is ignored.
    pub(crate) fn command(&mut self, speed: u8, opening: bool) {
        if speed == 0 {
            self.speed = 0;
            self.tripped = false;
            self.over_current_s = 0.0;
        } else if !self.tripped {
            self.speed = speed.min(MAX_SPEED);
            self.opening_direction = opening;
        }
    }

    /// D1 0xC1 / 0xC0.
    pub(crate) fn set_current_limit(&mut self, on: bool) {
        self.current_limit = on;
        if !on {
            self.over_current_s = 0.0;
        }
    }

    /// Stops the motor (safety time-out).
    pub(crate) fn stop(&mut self) {
        self.speed = 0;
        self.load = 0;
        self.over_current_s = 0.0;
    }

    /// Advances `dt` seconds.
    pub(crate) fn step(&mut self, dt: f64) {
        if !self.driven() {
            self.load = 0;
            return;
        }
        let rate = f64::from(self.speed) / f64::from(MAX_SPEED) / self.config.full_stroke_s;
        let (lo, hi) = (self.object.unwrap_or(0.0).min(self.opening), 1.0);
        let next = if self.opening_direction { self.opening + rate * dt } else { self.opening - rate * dt };
        let blocked = next >= hi || next <= lo;
        self.opening = next.clamp(lo, hi);
        self.load = if blocked { (2 * self.speed).min(MAX_SPEED) } else { 2 + self.speed / 4 };
        if self.current_limit && self.load > self.config.over_current_load {
            self.over_current_s += dt;
            if self.over_current_s * 1000.0 >= self.config.trip_after_ms {
                tracing::info!("gripper: over-current for {:.1} s, motor switched off", self.over_current_s);
                self.tripped = true;
                self.load = 0;
            }
        } else {
            self.over_current_s = 0.0;
        }
    }

    /// D1 reply (LIMIT, PHASE, BRAKE).
    pub(crate) fn status(&self) -> GripperStatus {
        GripperStatus {
            current_limit: self.current_limit,
            opening: self.opening_direction,
            brake_released: self.driven(),
        }
    }

    /// D5 reply (load, PHASE, BRAKE).
    pub(crate) fn load(&self) -> GripperLoad {
        GripperLoad { load: self.load, opening: self.opening_direction, brake_released: self.driven() }
    }

    /// A snapshot.
    pub(crate) fn state(&self) -> GripperState {
        GripperState {
            opening: self.opening,
            speed: self.speed,
            opening_direction: self.opening_direction,
            current_limit: self.current_limit,
            tripped: self.tripped,
            load: self.load,
            driven: self.driven(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(g: &mut Gripper, seconds: f64) {
        for _ in 0..(seconds * 1000.0).round() as usize {
            g.step(0.001);
        }
    }

    #[test]
    fn full_speed_stroke_takes_full_stroke_time() {
        let mut g = Gripper::new(GripperConfig { initial_opening: 0.0, ..GripperConfig::default() });
        g.command(31, true);
        run(&mut g, 1.0);
        assert!((g.state().opening - 0.5).abs() < 1e-9);
        // Moving freely: load 2 + 31 / 4 = 9.
        assert_eq!(g.load(), GripperLoad { load: 9, opening: true, brake_released: true });
    }

    #[test]
    fn closing_on_an_object_blocks_the_jaws() {
        let mut g = Gripper::new(GripperConfig { object_opening: Some(0.3), ..GripperConfig::default() });
        g.set_current_limit(false);
        g.command(10, false);
        run(&mut g, 3.0);
        let s = g.state();
        assert_eq!(s.opening, 0.3);
        assert_eq!(s.load, 20);
        assert!(!s.tripped, "no current limitation: keeps squeezing");
    }
}
