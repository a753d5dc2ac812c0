//! Motion: the trajectory generator of the CiA 402 modes the IclA supports (specs/canopen.md
//! 2.7, 2.9): profile position with the set-point handshake (CW bits 4/5/6/8, SW bits
//! 10/12/13), profile velocity, homing (methods 17/18 on the simulated limit switches,
//! 35/37 on the current position), trapezoidal ramps, quick-stop / fault-reaction ramps,
//! the position window (0x6067/0x6068), the following error monitor (0x6065/0x6066) and
//! the software position limits (0x607D).
//!
//! Relative targets (CW bit 6) are relative to the previous target position (to the actual
//! position after the power stage was off).

use motus_cia402_protocol::{cw, sw, HomingStatus, Mode};

use crate::motor::Motor;

/// Profile parameters sampled from the dictionary.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Params {
    /// 0x607A target position.
    pub target_position: f64,
    /// 0x60FF target velocity.
    pub target_velocity: f64,
    /// 0x6081 profile velocity.
    pub velocity: f64,
    /// 0x6083 profile acceleration.
    pub acceleration: f64,
    /// 0x6084 profile deceleration.
    pub deceleration: f64,
    /// 0x6067 position window.
    pub position_window: f64,
    /// 0x6068 position window time (s).
    pub position_window_time: f64,
    /// 0x6065 following error window (`None` = off, 0xFFFFFFFF).
    pub following_window: Option<f64>,
    /// 0x6066 following error time-out (s).
    pub following_timeout: f64,
    /// 0x607D (min, max), when min < max.
    pub limits: Option<(f64, f64)>,
    /// 0x6098 homing method.
    pub homing_method: i8,
    /// 0x6099 sub 1 / sub 2.
    pub homing_speeds: (f64, f64),
    /// 0x609A homing acceleration.
    pub homing_acceleration: f64,
    /// 0x607C home offset.
    pub home_offset: f64,
    /// Simulated negative / positive limit switch (world Inc).
    pub switches: (Option<f64>, Option<f64>),
}

/// How the power stage lets the generator run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Regime {
    /// Power stage off: the demand follows the shaft.
    Off,
    /// Operation enabled: the mode runs.
    Enabled,
    /// Ramp to standstill with this deceleration (quick stop, fault reaction, option 1).
    Stopping(f64),
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Homing {
    Idle,
    Search(f64),
    Leave(f64),
    Settle,
}

/// Result of one step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StepOutcome {
    /// The demand velocity is zero.
    pub standstill: bool,
    /// The following error exceeded the window for longer than the time-out.
    pub following_error_fault: bool,
}

/// The trajectory generator state.
#[derive(Debug, Clone, PartialEq)]
pub struct Motion {
    demand: f64,
    velocity: f64,
    target: f64,
    next: Option<f64>,
    moving: bool,
    set_point_ack: bool,
    controlword: u16,
    homing: Homing,
    homing_status: HomingStatus,
    homing_travel: f64,
    fe_time: f64,
    following_error: bool,
    window_time: f64,
    in_window: bool,
    internal_limit: bool,
    pv_goal: f64,
}

/// Travel without finding the switch before homing gives up (20 output revolutions).
const HOMING_MAX_TRAVEL: f64 = 20.0 * crate::motor::INC_PER_OUTPUT_REV;

/// Moves `v` toward `goal` by at most `rate * dt`.
fn ramp(v: f64, goal: f64, rate: f64, dt: f64) -> f64 {
    let step = rate * dt;
    if (goal - v).abs() <= step {
        goal
    } else {
        v + step * (goal - v).signum()
    }
}

impl Motion {
    /// Standing still at `position`.
    pub fn new(position: f64) -> Self {
        Self {
            demand: position,
            velocity: 0.0,
            target: position,
            next: None,
            moving: false,
            set_point_ack: false,
            controlword: 0,
            homing: Homing::Idle,
            homing_status: HomingStatus::Interrupted,
            homing_travel: 0.0,
            fe_time: 0.0,
            following_error: false,
            window_time: 0.0,
            in_window: true,
            internal_limit: false,
            pv_goal: 0.0,
        }
    }

    /// Position demand (Inc).
    pub fn demand(&self) -> f64 {
        self.demand
    }

    /// Demand velocity (Inc/s).
    pub fn demand_velocity(&self) -> f64 {
        self.velocity
    }

    /// The current target position.
    pub fn target(&self) -> f64 {
        self.target
    }

    /// Whether a profile move or homing run is in progress.
    pub fn busy(&self) -> bool {
        self.moving || self.homing != Homing::Idle || self.velocity != 0.0
    }

    /// Moves the position counter (0x200B, homing) by shifting the motor's offset.
    pub fn set_position(&mut self, motor: &mut Motor, position: f64) {
        let delta = position - motor.position();
        motor.set_position(position);
        self.demand += delta;
        self.target += delta;
        self.next = self.next.map(|n| n + delta);
    }

    fn accept(&mut self, p: &Params, word: u16) -> f64 {
        let mut t =
            if word & cw::RELATIVE != 0 { self.target + p.target_position } else { p.target_position };
        self.internal_limit = false;
        if let Some((lo, hi)) = p.limits {
            if t < lo || t > hi {
                t = t.clamp(lo, hi);
                self.internal_limit = true;
            }
        }
        t
    }

    /// A controlword reached the drive (operation enabled or not).
    pub fn on_controlword(&mut self, word: u16, mode: Mode, p: &Params, motor: &mut Motor, enabled: bool) {
        let edge = word & cw::NEW_SET_POINT != 0 && self.controlword & cw::NEW_SET_POINT == 0;
        self.controlword = word;
        if word & cw::NEW_SET_POINT == 0 && self.next.is_none() {
            self.set_point_ack = false;
        }
        if !enabled || !edge {
            return;
        }
        match mode {
            Mode::ProfilePosition => {
                if !self.moving || word & cw::CHANGE_SET_IMMEDIATELY != 0 {
                    self.target = self.accept(p, word);
                    self.next = None;
                    self.moving = true;
                    self.set_point_ack = true;
                    self.in_window = false;
                } else if self.next.is_none() {
                    let t = self.accept(p, word);
                    // Relative to the move in progress: its target is the base.
                    self.next = Some(t);
                    self.set_point_ack = true;
                }
            }
            Mode::Homing => self.start_homing(p, motor),
            _ => {}
        }
    }

    fn start_homing(&mut self, p: &Params, motor: &mut Motor) {
        self.homing_travel = 0.0;
        match p.homing_method {
            35 | 37 => {
                self.set_position(motor, p.home_offset);
                self.target = self.demand;
                self.homing_status = HomingStatus::Completed;
            }
            17 if p.switches.0.is_some() => {
                self.homing = Homing::Search(-1.0);
                self.homing_status = HomingStatus::InProgress;
            }
            18 if p.switches.1.is_some() => {
                self.homing = Homing::Search(1.0);
                self.homing_status = HomingStatus::InProgress;
            }
            _ => self.homing_status = HomingStatus::ErrorStopped,
        }
    }

    fn on_switch(p: &Params, motor: &Motor, dir: f64) -> bool {
        let w = motor.world();
        match (dir < 0.0, p.switches) {
            (true, (Some(neg), _)) => w <= neg,
            (false, (_, Some(pos))) => w >= pos,
            _ => false,
        }
    }

    fn step_homing(&mut self, p: &Params, motor: &mut Motor, dt: f64) {
        let acc = p.homing_acceleration;
        match self.homing {
            Homing::Idle => self.velocity = ramp(self.velocity, 0.0, acc, dt),
            Homing::Search(dir) => {
                self.velocity = ramp(self.velocity, dir * p.homing_speeds.0, acc, dt);
                self.homing_travel += (self.velocity * dt).abs();
                if Self::on_switch(p, motor, dir) {
                    self.homing = Homing::Leave(dir);
                } else if self.homing_travel > HOMING_MAX_TRAVEL {
                    self.homing = Homing::Idle;
                    self.homing_status = HomingStatus::ErrorMoving;
                }
            }
            Homing::Leave(dir) => {
                self.velocity = ramp(self.velocity, -dir * p.homing_speeds.1, acc, dt);
                if self.velocity * dir < 0.0 && !Self::on_switch(p, motor, dir) {
                    // The switch edge is the home position.
                    self.set_position(motor, p.home_offset);
                    self.homing = Homing::Settle;
                    self.homing_status = HomingStatus::AttainedNotReached;
                }
            }
            Homing::Settle => {
                self.velocity = ramp(self.velocity, 0.0, acc, dt);
                if self.velocity == 0.0 {
                    self.homing = Homing::Idle;
                    self.target = self.demand;
                    self.homing_status = HomingStatus::Completed;
                }
            }
        }
        if self.homing_status == HomingStatus::ErrorMoving && self.velocity == 0.0 {
            self.homing_status = HomingStatus::ErrorStopped;
        }
        self.demand += self.velocity * dt;
    }

    fn step_position(&mut self, p: &Params, dt: f64) {
        if !self.moving {
            self.velocity = ramp(self.velocity, 0.0, p.deceleration, dt);
            self.demand += self.velocity * dt;
            return;
        }
        let s = self.target - self.demand;
        let dir = if s == 0.0 { self.velocity.signum() } else { s.signum() };
        let along = self.velocity * dir;
        let (acc, dec, vmax) = (p.acceleration, p.deceleration, p.velocity);
        let new = if along < 0.0 {
            along + dec * dt
        } else {
            let cap = (2.0 * dec * s.abs()).sqrt();
            let cruise =
                if along > vmax { (along - dec * dt).max(vmax) } else { (along + acc * dt).min(vmax) };
            cruise.min(cap)
        };
        let travel = new * dt;
        if new >= 0.0 && (travel >= s.abs() || (s.abs() < 1e-9 && new.abs() < 1e-9)) {
            self.demand = self.target;
            self.velocity = 0.0;
            if let Some(n) = self.next.take() {
                self.target = n;
            } else {
                self.moving = false;
            }
        } else {
            self.demand += dir * travel;
            self.velocity = dir * new;
        }
    }

    /// One step of `dt` seconds.
    pub fn step(
        &mut self,
        regime: Regime,
        mode: Mode,
        p: &Params,
        motor: &mut Motor,
        dt: f64,
    ) -> StepOutcome {
        let halt = self.controlword & cw::HALT != 0;
        match regime {
            Regime::Off => {
                self.demand = motor.position();
                self.velocity = 0.0;
                self.target = self.demand;
                self.moving = false;
                self.next = None;
                self.abort_homing();
            }
            Regime::Stopping(dec) => {
                self.moving = false;
                self.next = None;
                self.abort_homing();
                self.velocity = if dec <= 0.0 { 0.0 } else { ramp(self.velocity, 0.0, dec, dt) };
                self.demand += self.velocity * dt;
                self.target = self.demand;
            }
            Regime::Enabled if halt => {
                let dec = if mode == Mode::Homing { p.homing_acceleration } else { p.deceleration };
                self.velocity = ramp(self.velocity, 0.0, dec, dt);
                self.demand += self.velocity * dt;
                if self.homing != Homing::Idle && self.velocity == 0.0 {
                    self.homing = Homing::Idle;
                    self.homing_status = HomingStatus::Interrupted;
                }
            }
            Regime::Enabled => match mode {
                Mode::ProfilePosition => self.step_position(p, dt),
                Mode::ProfileVelocity => {
                    let goal = p.target_velocity;
                    self.pv_goal = goal;
                    let rate = if goal.abs() > self.velocity.abs() && goal * self.velocity >= 0.0 {
                        p.acceleration
                    } else {
                        p.deceleration
                    };
                    self.velocity = ramp(self.velocity, goal, rate, dt);
                    self.demand += self.velocity * dt;
                }
                Mode::Homing => self.step_homing(p, motor, dt),
                _ => {
                    self.velocity = ramp(self.velocity, 0.0, p.deceleration, dt);
                    self.demand += self.velocity * dt;
                }
            },
        }
        if let Some((lo, hi)) = p.limits {
            if regime != Regime::Off && (self.demand < lo || self.demand > hi) {
                self.demand = self.demand.clamp(lo, hi);
                self.velocity = 0.0;
                self.internal_limit = true;
            }
        }
        let powered = regime != Regime::Off;
        motor.step(self.demand, powered, dt);
        if self.controlword & cw::NEW_SET_POINT == 0 && self.next.is_none() {
            self.set_point_ack = false;
        }
        // Position window.
        let err = (motor.position() - self.target).abs();
        if !self.moving && err <= p.position_window {
            self.window_time += dt;
            if self.window_time + 1e-9 >= p.position_window_time {
                self.in_window = true;
            }
        } else {
            self.window_time = 0.0;
            self.in_window = false;
        }
        StepOutcome {
            standstill: self.velocity == 0.0,
            following_error_fault: self.monitor(p, motor, powered, dt),
        }
    }

    fn monitor(&mut self, p: &Params, motor: &Motor, powered: bool, dt: f64) -> bool {
        let Some(window) = p.following_window.filter(|_| powered) else {
            // Unpowered: the flag stays as it was (latched until a fault reset).
            self.fe_time = 0.0;
            return false;
        };
        if (self.demand - motor.position()).abs() > window {
            self.fe_time += dt;
            if self.fe_time + 1e-9 >= p.following_timeout && !self.following_error {
                self.following_error = true;
                return true;
            }
        } else {
            self.fe_time = 0.0;
            self.following_error = false;
        }
        false
    }

    /// Fault reset: the following error flag (SW bit 13) is cleared.
    pub fn clear_following_error(&mut self) {
        self.following_error = false;
        self.fe_time = 0.0;
    }

    fn abort_homing(&mut self) {
        if self.homing != Homing::Idle {
            self.homing = Homing::Idle;
            self.homing_status = HomingStatus::Interrupted;
        }
    }

    /// Statusword bits 10-13 for a mode.
    pub fn statusword_bits(&self, mode: Mode, motor: &Motor) -> u16 {
        let halt = self.controlword & cw::HALT != 0;
        let limit = if self.internal_limit { sw::INTERNAL_LIMIT } else { 0 };
        let bits = match mode {
            Mode::ProfilePosition => {
                let reached = if halt { self.velocity == 0.0 } else { !self.moving && self.in_window };
                (if reached { sw::TARGET_REACHED } else { 0 })
                    | (if self.set_point_ack { sw::SET_POINT_ACKNOWLEDGE } else { 0 })
                    | (if self.following_error { sw::FOLLOWING_ERROR } else { 0 })
            }
            Mode::ProfileVelocity => {
                let reached = if halt { self.velocity == 0.0 } else { self.velocity == self.pv_goal };
                (if reached { sw::TARGET_REACHED } else { 0 })
                    | (if motor.velocity().abs() < 0.5 { sw::SPEED_ZERO } else { 0 })
            }
            Mode::Homing => self.homing_status.statusword_bits(),
            _ => 0,
        };
        bits | limit
    }
}
