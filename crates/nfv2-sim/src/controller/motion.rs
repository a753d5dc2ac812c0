//! The regulators of each mode, once per 1 ms cycle, and the power stage's 20 current-loop
//! substeps.
//!
//! | mode | what runs |
//! |---|---|
//! | ERROR (and PVT, SYNC_PWM0, SYNC_CURRENT0, unknown numbers) | bridge off |
//! | MANUAL | duty from AI0 (direction and power), current limiter |
//! | PWM | duty = `SetDrivesPWM` / 1000, current limiter |
//! | CURRENT | current loop on `SetDrivesCurrent` (mA) |
//! | SPEED | ramp (max acceleration) to `SetDrivesSpeed` -> speed loop -> current loop |
//! | POSITION | trapezoid (`motus_axis::profile::Plan`) to `SetDrivesPosition` at the profile speed -> position loop (+ speed feed-forward) -> speed loop -> current loop |
//! | POS_INCREMENT | the position reference advances by the ramped `SetDrivesSpeed` each cycle -> position loop ... |
//! | HOMING (SYNC_POS0 before 2014) | speed loop at the homing speed towards the HOME edge, then the position loop holds |
//!
//! Limits (clamping, never refusing: NFv2 has no negative answer; the status bit says it):
//! - speed set-point beyond `SetDrivesMaxSpeed`: clamped, bit 11;
//! - current reference beyond `SetDrivesMaxCurrent` (a set-point, the speed loop's output,
//!   or the limiter in PWM / MANUAL): clamped, bit 12;
//! - position (active when min < max): a target outside is clamped to the limit, a speed
//!   ramp decelerates to stop at the limit, PWM / current / MANUAL beyond a limit may only
//!   drive back (the reference's `motorPWMpositionLimit`); bit 10 while that happens.

use motus_axis::profile::Plan;
use motus_nfv2_protocol::DriveMode;

use super::{ActivePlan, Controller, Demand, Homing, CURRENT_LOOP_SUBSTEPS, REGULATOR_PERIOD};
use crate::config::COUNTS_PER_S_PER_SPEED_UNIT as UNIT;
use crate::motor::Bridge;

/// Full PWM duty in set-point units (the reference's `MAX_PWM`).
pub(crate) const FULL_DUTY: f64 = 1000.0;

/// What a mode makes the regulators do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Family {
    Off,
    Manual,
    Pwm,
    Current,
    Speed,
    Position,
    PosIncrement,
    Homing,
}

impl Family {
    /// The behaviour of `mode`.
    pub(crate) fn of(mode: DriveMode) -> Self {
        match mode {
            DriveMode::Manual => Family::Manual,
            DriveMode::Pwm => Family::Pwm,
            DriveMode::Current => Family::Current,
            DriveMode::Speed => Family::Speed,
            DriveMode::Position => Family::Position,
            DriveMode::PosIncrement => Family::PosIncrement,
            DriveMode::Homing | DriveMode::SyncPos0 => Family::Homing,
            DriveMode::Error
            | DriveMode::Pvt
            | DriveMode::SyncPwm0
            | DriveMode::SyncCurrent0
            | DriveMode::Unknown(_) => Family::Off,
        }
    }

    /// The speed loop runs (and, below it, the current loop).
    pub(crate) fn uses_speed_loop(self) -> bool {
        matches!(self, Family::Speed | Family::Position | Family::PosIncrement | Family::Homing)
    }

    /// The current loop runs.
    pub(crate) fn uses_current_loop(self) -> bool {
        self.uses_speed_loop() || self == Family::Current
    }
}

fn dt() -> f64 {
    REGULATOR_PERIOD.as_secs_f64()
}

impl Controller {
    /// The regulators of the active mode for this cycle.
    pub(super) fn regulate(&mut self) -> Demand {
        let f = &mut self.flags;
        (f.position_limit, f.speed_limit, f.current_limit, f.following_error) = (false, false, false, false);
        self.current_ref_a = 0.0;
        let family = Family::of(self.active_mode);
        let demand = match family {
            Family::Off => Demand::Off,
            Family::Manual => self.duty_demand(self.manual_duty()),
            Family::Pwm => {
                let duty = self.set.pwm as f64 / FULL_DUTY;
                self.duty_demand(duty.clamp(-1.0, 1.0))
            }
            Family::Current => self.current_mode(),
            Family::Speed => {
                let target = self.limited_speed_setpoint();
                let v = self.ramp_speed(target, self.counter as f64, true);
                self.trajectory.p_ref = self.counter as f64;
                self.speed_loop(v)
            }
            Family::PosIncrement => self.pos_increment(),
            Family::Position => self.position_mode(),
            Family::Homing => self.homing(),
        };
        if !family.uses_speed_loop() || !self.sensed.power_ok {
            // Nothing to follow (or nothing can move): the references stay with the axis,
            // so a trajectory restarts from where the axis is.
            let t = &mut self.trajectory;
            t.p_ref = self.counter as f64;
            t.v_ref = self.measured_speed * UNIT;
            t.plan = None;
        }
        if !self.sensed.power_ok {
            self.speed_pid.reset();
            self.position_pid.reset();
            self.current_pid.reset();
        }
        demand
    }

    /// MANUAL: AI0 sets direction and power (seed, "Tryby pracy").
    fn manual_duty(&self) -> f64 {
        let m = self.config.manual;
        let x = self.inputs.analog_v[0] - m.zero_v;
        if x.abs() <= m.deadband_v {
            return 0.0;
        }
        let span = (m.span_v - m.deadband_v).max(f64::EPSILON);
        ((x - m.deadband_v * x.signum()) / span).clamp(-1.0, 1.0)
    }

    /// Zeroes `value` if it drives towards a closed limit switch.
    fn block_switches(&self, value: f64) -> f64 {
        let (up, down) = self.sensed.blocked();
        if (up && value > 0.0) || (down && value < 0.0) {
            0.0
        } else {
            value
        }
    }

    /// Beyond a position limit only driving back is allowed (PWM, current, MANUAL).
    fn block_outside_limits(&mut self, value: f64) -> f64 {
        let Some((lo, hi)) = self.position_limits() else { return value };
        if self.counter < lo {
            self.flags.position_limit = true;
            return value.max(0.0);
        }
        if self.counter > hi {
            self.flags.position_limit = true;
            return value.min(0.0);
        }
        value
    }

    fn duty_demand(&mut self, duty: f64) -> Demand {
        let duty = self.block_outside_limits(duty);
        Demand::Duty(self.block_switches(duty))
    }

    fn current_mode(&mut self) -> Demand {
        let max = self.set.max_current_ma as f64;
        let mut i = self.set.current_ma as f64;
        if i.abs() > max {
            self.flags.current_limit = true;
            i = i.clamp(-max, max);
        }
        // Over-speed protection: no more torque in the direction of a too fast motion.
        let v = self.measured_speed;
        if v.abs() > self.set.max_speed as f64 && i * v > 0.0 {
            self.flags.speed_limit = true;
            i = 0.0;
        }
        let i = self.block_outside_limits(i);
        self.current_ref_a = self.block_switches(i) / 1000.0;
        Demand::Current(self.current_ref_a)
    }

    /// `SetDrivesSpeed` clamped to the speed limit, in counts/s.
    fn limited_speed_setpoint(&mut self) -> f64 {
        let max = self.set.max_speed;
        if self.set.speed.abs() > max {
            self.flags.speed_limit = true;
        }
        self.set.speed.clamp(-max, max) as f64 * UNIT
    }

    /// One step of the speed ramp towards `target` (counts/s) at the maximum acceleration;
    /// with `limits`, slowed so that it stops at a position limit (seen from `position`)
    /// and zero towards a closed switch. Stores and returns the new speed reference.
    fn ramp_speed(&mut self, target: f64, position: f64, limits: bool) -> f64 {
        let acc = self.set.max_acceleration as f64;
        let step = acc * dt();
        let v = self.trajectory.v_ref;
        let mut next = v + (target - v).clamp(-step, step);
        if let (true, Some((lo, hi))) = (limits, self.position_limits()) {
            let room = if next > 0.0 { hi as f64 - position } else { position - lo as f64 };
            let allowed = (2.0 * acc * room.max(0.0)).sqrt();
            if next.abs() > allowed {
                self.flags.position_limit = true;
                next = allowed * next.signum();
            }
        }
        let next = self.block_switches(next);
        self.trajectory.v_ref = next;
        next
    }

    /// Speed loop (1 kHz) on a reference in counts/s: its output is the current reference.
    fn speed_loop(&mut self, v_ref: f64) -> Demand {
        let reference = self.block_switches(v_ref / UNIT);
        let max = self.set.max_current_ma as f64;
        let out = self.speed_pid.update(reference, self.measured_speed, max);
        if out.saturated {
            self.flags.current_limit = true;
        }
        self.current_ref_a = self.block_switches(out.value) / 1000.0;
        Demand::Current(self.current_ref_a)
    }

    /// Position loop (1 kHz) on the trajectory's reference, with its speed as feed-forward.
    fn position_loop(&mut self) -> Demand {
        let (p_ref, v_ref) = (self.trajectory.p_ref, self.trajectory.v_ref);
        let measured = self.counter as f64;
        self.flags.following_error = (p_ref - measured).abs() > self.config.following_error_counts as f64;
        let max = self.set.max_speed as f64;
        let correction = self.position_pid.update(p_ref, measured, max).value;
        let speed = (v_ref / UNIT + correction).clamp(-max, max);
        self.speed_loop(speed * UNIT)
    }

    fn position_mode(&mut self) -> Demand {
        let mut target = self.set.position;
        if let Some((lo, hi)) = self.position_limits() {
            if !(lo..=hi).contains(&target) {
                self.flags.position_limit = true;
                target = target.clamp(lo, hi);
            }
        }
        // The reference firmware moves at SetDrivesSpeed in POSITION mode; 0 (never moving
        // there) is read here as "at the speed limit".
        let max = self.set.max_speed;
        let speed = match self.set.speed.unsigned_abs() {
            0 => max,
            s => {
                if s > max.unsigned_abs() {
                    self.flags.speed_limit = true;
                }
                i64::try_from(s).unwrap_or(max).min(max)
            }
        };
        let key = (target, speed, self.set.max_acceleration);
        if self.trajectory.plan.as_ref().map(|p| p.key) != Some(key) {
            let t = &self.trajectory;
            let plan = Plan::to_target(t.p_ref, t.v_ref, target as f64, speed as f64 * UNIT, key.2 as f64);
            self.trajectory.plan = Some(ActivePlan { plan, cycles: 0, key });
        }
        self.follow_plan();
        self.position_loop()
    }

    /// Advances the active plan by one cycle into the references.
    fn follow_plan(&mut self) {
        let t = &mut self.trajectory;
        if let Some(active) = t.plan.as_mut() {
            active.cycles += 1;
            let (p, v) = active.plan.sample(active.cycles as f64 * dt());
            t.p_ref = p;
            t.v_ref = v;
        } else {
            t.v_ref = 0.0;
        }
    }

    fn pos_increment(&mut self) -> Demand {
        let target = self.limited_speed_setpoint();
        let v = self.ramp_speed(target, self.trajectory.p_ref, true);
        let t = &mut self.trajectory;
        t.p_ref += v * dt();
        if let Some((lo, hi)) = self.position_limits() {
            let (lo, hi) = (lo as f64, hi as f64);
            if !(lo..=hi).contains(&self.trajectory.p_ref) {
                self.flags.position_limit = true;
                self.trajectory.p_ref = self.trajectory.p_ref.clamp(lo, hi);
                self.trajectory.v_ref = 0.0;
            }
        }
        self.position_loop()
    }

    /// CALIBRATION (seed): with the speed regulator, move until the edge of the HOME field
    /// and calibrate the position counter there. As the reference (`motorSetSynchronization
    /// Speed`): outside the field move negative, inside move positive; the edge is where the
    /// field ends when moving positive, so it is always approached from the same side.
    fn homing(&mut self) -> Demand {
        let Homing::Seek(direction) = self.trajectory.homing else {
            self.follow_plan();
            return self.position_loop();
        };
        let home = self.sensed.home;
        if direction < 0 && home {
            self.trajectory.homing = Homing::Seek(1);
        } else if direction > 0 && !home {
            self.calibrate();
            self.follow_plan();
            return self.position_loop();
        }
        let dir = if let Homing::Seek(d) = self.trajectory.homing { f64::from(d) } else { 0.0 };
        let speed = self.config.homing_speed.min(self.set.max_speed) as f64 * UNIT;
        let v = self.ramp_speed(dir * speed, self.counter as f64, false);
        self.trajectory.p_ref = self.counter as f64;
        self.speed_loop(v)
    }

    /// The HOME edge: the counter reads `home_position` here; synchronized; stop and hold.
    fn calibrate(&mut self) {
        let shift = self.config.home_position - self.counter;
        self.counter_offset += shift;
        self.counter += shift;
        for h in &mut self.history {
            *h += shift;
        }
        self.flags.synchronized = true;
        self.trajectory.homing = Homing::Done;
        let v = self.measured_speed * UNIT;
        let acc = self.set.max_acceleration as f64;
        let plan = Plan::stop(self.counter as f64, v, acc);
        self.trajectory.plan = Some(ActivePlan { plan, cycles: 0, key: (self.counter, 0, 0) });
        tracing::info!(address = self.address, counter = self.counter, "home edge found: synchronized");
    }

    /// The 20 kHz substeps: current loop or duty (with the cycle-by-cycle current limiter)
    /// into the H-bridge, and the motor. The bridge is off without ENABLE, without supply,
    /// after an over-current trip, or for a zero duty.
    pub(super) fn power_stage(&mut self) {
        let n = CURRENT_LOOP_SUBSTEPS;
        let dt = dt() / f64::from(n);
        let vbus = self.sensed.supply_v.max(0.0);
        let powered = self.sensed.power_ok && self.inputs.enable;
        let imax = self.set.max_current_ma as f64 / 1000.0;
        let trip = self.config.overcurrent_trip_ma as f64 / 1000.0;
        for _ in 0..n {
            let bridge = match self.demand {
                _ if !powered || self.flags.overcurrent => Bridge::Off,
                Demand::Off => Bridge::Off,
                Demand::Duty(0.0) => Bridge::Off,
                Demand::Duty(d) => Bridge::Drive(self.limit_current(d * vbus, imax, dt)),
                Demand::Current(i_ref) => {
                    let measured = self.motor.current() * 1000.0;
                    let duty = self.current_pid.update(i_ref * 1000.0, measured, FULL_DUTY).value;
                    Bridge::Drive(duty / FULL_DUTY * vbus)
                }
            };
            self.bridge_on = matches!(bridge, Bridge::Drive(_));
            self.motor.substep(dt, bridge, vbus);
            if self.motor.current().abs() > trip && !self.flags.overcurrent {
                tracing::warn!(address = self.address, current = self.motor.current(), "over-current trip");
                self.flags.overcurrent = true;
            }
        }
    }

    /// Limits the voltage so the current does not pass `+-imax` in the next substep.
    fn limit_current(&mut self, v: f64, imax: f64, dt: f64) -> f64 {
        let hi = self.motor.voltage_for_current(imax, dt);
        let lo = self.motor.voltage_for_current(-imax, dt);
        if v > hi || v < lo {
            self.flags.current_limit = true;
            v.clamp(lo, hi)
        } else {
            v
        }
    }
}
