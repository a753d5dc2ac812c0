//! `sim-axis` devices: an axis simulated inside the station, with no link. Motion is a list
//! of constant-acceleration segments from a start state, evaluated from [`Instant`] on
//! every call (no thread): trapezoidal moves, jogs (a move to the machine limit in that
//! direction), homing (a move to 0, clamped into the limits, at half speed), stop (the
//! machine deceleration) and quick stop (five times it). "Killing" it makes every call fail
//! like a lost device until it is restarted (then disabled and not homed, where it was).

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Instant;

use motus_axis::{Axis, AxisCommand, AxisError, AxisFlags, AxisState, Capabilities, MotionProfile, Scale};
use motus_station::config::AxisConfig;
use motus_station::devices::DeviceError;

use crate::sim::SimControl;
use crate::{CellError, DeviceCtl};

/// A motion: from `x0`, `v0` at `t0`, through `(duration s, acceleration)` segments.
#[derive(Debug, Clone)]
struct Motion {
    t0: Instant,
    x0: f64,
    v0: f64,
    segments: Vec<(f64, f64)>,
    homing: bool,
}

impl Motion {
    /// Position, velocity and whether it ended, at `now`.
    fn at(&self, now: Instant) -> (f64, f64, bool) {
        let mut t = now.saturating_duration_since(self.t0).as_secs_f64();
        let (mut x, mut v) = (self.x0, self.v0);
        for &(d, a) in &self.segments {
            let dt = t.min(d);
            x += v * dt + 0.5 * a * dt * dt;
            v += a * dt;
            t -= dt;
            if t <= 0.0 {
                return (x, v, false);
            }
        }
        (x, 0.0, true)
    }
}

/// Segments of a move by `d` from rest with speed `v` and acceleration `a` (trapezoid, or
/// triangle when the speed is not reached).
fn trapezoid(d: f64, v: f64, a: f64) -> Vec<(f64, f64)> {
    let (s, dist) = (d.signum(), d.abs());
    if dist == 0.0 || v <= 0.0 || a <= 0.0 {
        return Vec::new();
    }
    if dist >= v * v / a {
        let ta = v / a;
        vec![(ta, s * a), ((dist - v * v / a) / v, 0.0), (ta, -s * a)]
    } else {
        let ta = (dist / a).sqrt();
        vec![(ta, s * a), (ta, -s * a)]
    }
}

/// The simulated axis's state.
/// Segments from velocity `v0` to rest at distance `d`, cruising at most at `vmax`: slow down
/// or speed up toward `vmax`, cruise, brake; when `v0` points away from the target or cannot
/// stop in time, brake to rest first, then move back.
fn retarget(d: f64, v0: f64, vmax: f64, a: f64) -> Vec<(f64, f64)> {
    if v0 == 0.0 {
        return trapezoid(d, vmax, a);
    }
    if a <= 0.0 || vmax <= 0.0 {
        return Vec::new();
    }
    let s = v0.signum();
    let u = v0.abs();
    let braking = u * u / (2.0 * a);
    if d * s < braking {
        // Brake to rest, then go to the target from there.
        let mut segs = vec![(u / a, -s * a)];
        segs.extend(trapezoid(d - s * braking, vmax, a));
        return segs;
    }
    let dist = d.abs();
    // Peak speed: reach vp from u, then brake from vp, within dist.
    let vp = ((2.0 * a * dist + u * u) / 2.0).sqrt().min(vmax.max(0.0));
    let mut segs = Vec::new();
    let (to_peak, d1) = if vp >= u {
        ((vp - u) / a, (vp * vp - u * u) / (2.0 * a))
    } else {
        ((u - vp) / a, (u * u - vp * vp) / (2.0 * a))
    };
    if to_peak > 0.0 {
        segs.push((to_peak, if vp >= u { s * a } else { -s * a }));
    }
    let d3 = vp * vp / (2.0 * a);
    let cruise = dist - d1 - d3;
    if cruise > 0.0 && vp > 0.0 {
        segs.push((cruise / vp, 0.0));
    }
    if vp > 0.0 {
        segs.push((vp / a, -s * a));
    }
    segs
}

#[derive(Debug)]
pub(crate) struct SimState {
    alive: bool,
    enabled: bool,
    homed: bool,
    position: f64,
    motion: Option<Motion>,
}

impl SimState {
    /// Folds a finished motion into the state; returns (position, velocity, moving).
    fn update(&mut self, now: Instant) -> (f64, f64, bool) {
        let Some(m) = &self.motion else { return (self.position, 0.0, false) };
        let (x, v, done) = m.at(now);
        if done {
            self.homed |= m.homing;
            self.position = x;
            self.motion = None;
            return (x, 0.0, false);
        }
        (x, v, true)
    }

    /// Freezes the axis where it is now (power loss, disable).
    fn freeze(&mut self, now: Instant) {
        let (x, _, _) = self.update(now);
        self.position = x;
        self.motion = None;
    }
}

/// Shared state of one simulated axis.
pub(crate) type Shared = Arc<Mutex<SimState>>;

fn lock(s: &Shared) -> MutexGuard<'_, SimState> {
    s.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A new simulated axis at 0 (clamped into the limits), disabled and not homed.
pub(crate) fn new_shared(config: &AxisConfig) -> Shared {
    let position = 0.0f64.clamp(config.limits.min, config.limits.max);
    Arc::new(Mutex::new(SimState { alive: true, enabled: false, homed: false, position, motion: None }))
}

/// The axis (see the module documentation).
pub struct SimAxis {
    config: AxisConfig,
    state: Shared,
}

impl SimAxis {
    pub(crate) fn new(config: AxisConfig, state: Shared) -> Self {
        Self { config, state }
    }

    fn err_down(&self) -> AxisError {
        AxisError::Communication {
            axis: self.config.name.clone(),
            reason: "simulated axis is not running".into(),
        }
    }

    /// Starts a move to `target` (SI) from rest.
    fn start_move(
        &self,
        s: &mut SimState,
        now: Instant,
        target: f64,
        p: &MotionProfile,
        homing: bool,
    ) -> Result<(), AxisError> {
        let (x, v, _) = s.update(now);
        let vmax = p.velocity.unwrap_or(self.config.max_velocity).min(self.config.max_velocity).abs();
        // A zero profile velocity (the last set-point of a streamed path) means "the default".
        let vmax = if vmax > 0.0 { vmax } else { self.config.max_velocity.abs() };
        let vmax = if homing { vmax / 2.0 } else { vmax };
        let a =
            p.acceleration.unwrap_or(self.config.max_acceleration).min(self.config.max_acceleration).abs();
        // A new target while moving re-plans from the current velocity, like a servo drive
        // taking a set-point immediately (streamed paths send one every cycle).
        s.motion = Some(Motion { t0: now, x0: x, v0: v, segments: retarget(target - x, v, vmax, a), homing });
        Ok(())
    }

    /// Decelerates from the current state with `a`.
    fn stop_with(s: &mut SimState, now: Instant, a: f64) {
        let (x, v, moving) = s.update(now);
        if !moving {
            return;
        }
        let segments = if a > 0.0 && v != 0.0 { vec![(v.abs() / a, -v.signum() * a)] } else { Vec::new() };
        s.motion = Some(Motion { t0: now, x0: x, v0: v, segments, homing: false });
    }
}

impl Axis for SimAxis {
    fn name(&self) -> &str {
        &self.config.name
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities { reports_velocity: true, ..Capabilities::POSITIONING }
    }

    fn scale(&self) -> &Scale {
        &self.config.scale
    }

    fn read_state(&mut self) -> Result<AxisState, AxisError> {
        let mut s = lock(&self.state);
        if !s.alive {
            return Err(self.err_down());
        }
        let (x, v, moving) = s.update(Instant::now());
        Ok(AxisState {
            position: x,
            position_raw: self.config.scale.position_from_si(x).round() as i64,
            velocity: Some(v),
            current: None,
            following_error: None,
            flags: AxisFlags {
                enabled: s.enabled,
                homed: s.homed,
                moving,
                target_reached: !moving,
                limit_negative: x <= self.config.limits.min,
                limit_positive: x >= self.config.limits.max,
                brake_engaged: None,
            },
            faults: Vec::new(),
        })
    }

    fn execute(&mut self, command: &AxisCommand) -> Result<(), AxisError> {
        let state = Arc::clone(&self.state);
        let mut s = lock(&state);
        if !s.alive {
            return Err(self.err_down());
        }
        let now = Instant::now();
        let name = self.config.name.clone();
        let needs_enable = command.starts_motion();
        if needs_enable && !s.enabled {
            return Err(AxisError::NotEnabled { axis: name });
        }
        let l = self.config.limits;
        match command {
            AxisCommand::Enable => s.enabled = true,
            AxisCommand::Disable => {
                s.freeze(now);
                s.enabled = false;
            }
            AxisCommand::Home => {
                s.homed = false;
                self.start_move(&mut s, now, 0.0f64.clamp(l.min, l.max), &MotionProfile::default(), true)?;
            }
            AxisCommand::MoveAbsolute { target, profile } => {
                if !s.homed {
                    return Err(AxisError::NotHomed { axis: name, detail: String::new() });
                }
                if !(l.min..=l.max).contains(target) {
                    return Err(AxisError::BeyondLimit {
                        axis: name,
                        target: *target,
                        min: l.min,
                        max: l.max,
                        unit: self.config.unit.symbol().into(),
                    });
                }
                self.start_move(&mut s, now, *target, profile, false)?;
            }
            AxisCommand::MoveRelative { distance, profile } => {
                if !s.homed {
                    return Err(AxisError::NotHomed { axis: name, detail: String::new() });
                }
                let (x, _, _) = s.update(now);
                let target = x + distance;
                if !(l.min..=l.max).contains(&target) {
                    return Err(AxisError::BeyondLimit {
                        axis: name,
                        target,
                        min: l.min,
                        max: l.max,
                        unit: self.config.unit.symbol().into(),
                    });
                }
                self.start_move(&mut s, now, target, profile, false)?;
            }
            AxisCommand::Jog { direction, profile } => {
                let target = if direction.sign() > 0.0 { l.max } else { l.min };
                self.start_move(&mut s, now, target, profile, false)?;
            }
            AxisCommand::Stop => Self::stop_with(&mut s, now, self.config.max_acceleration),
            AxisCommand::QuickStop => Self::stop_with(&mut s, now, 5.0 * self.config.max_acceleration),
            AxisCommand::FaultReset => {}
        }
        Ok(())
    }
}

/// The kill switch of one simulated axis.
pub(crate) struct SimAxisControl(pub(crate) Shared);

impl SimControl for SimAxisControl {
    fn kill(&mut self) {
        let mut s = lock(&self.0);
        s.freeze(Instant::now());
        s.alive = false;
    }

    fn restart(&mut self) -> Result<(), CellError> {
        let mut s = lock(&self.0);
        s.freeze(Instant::now());
        *s = SimState { alive: true, enabled: false, homed: false, position: s.position, motion: None };
        Ok(())
    }

    fn is_running(&self) -> bool {
        lock(&self.0).alive
    }
}

/// A `sim-axis` device: connected while its simulation runs.
pub(crate) struct SimAxisDevice {
    pub(crate) name: String,
    pub(crate) axis: String,
    pub(crate) state: Shared,
}

impl DeviceCtl for SimAxisDevice {
    fn name(&self) -> &str {
        &self.name
    }

    fn axes(&self) -> Vec<String> {
        vec![self.axis.clone()]
    }

    fn connect(&self) -> Result<(), DeviceError> {
        if lock(&self.state).alive {
            Ok(())
        } else {
            Err(DeviceError::NoAnswer(format!("simulated axis {} is not running", self.axis)))
        }
    }

    fn is_connected(&self) -> bool {
        lock(&self.state).alive
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use std::time::Duration;

    #[test]
    fn trapezoid_covers_the_distance_with_the_hand_computed_timing() {
        // d = 0.3 m, v = 0.1 m/s, a = 1 m/s^2: ramps of 0.1 s (0.005 m each), cruise
        // (0.3 - 0.01) / 0.1 = 2.9 s; total 3.1 s.
        let s = trapezoid(0.3, 0.1, 1.0);
        assert_eq!(s.len(), 3);
        assert!((s[0].0 - 0.1).abs() < 1e-12 && (s[1].0 - 2.9).abs() < 1e-12);
        let t0 = Instant::now();
        let m = Motion { t0, x0: 0.1, v0: 0.0, segments: s, homing: false };
        let (x, v, done) = m.at(t0 + Duration::from_millis(100));
        assert!((x - 0.105).abs() < 1e-9 && (v - 0.1).abs() < 1e-9 && !done);
        let (x, _, done) = m.at(t0 + Duration::from_millis(3100) + Duration::from_micros(1));
        assert!((x - 0.4).abs() < 1e-9 && done);
        // Triangle: d = 0.004, v = 0.1, a = 1: peak sqrt(0.004) = 0.0632 m/s at 0.0632 s.
        let s = trapezoid(-0.004, 0.1, 1.0);
        assert_eq!(s.len(), 2);
        assert!((s[0].0 - 0.004f64.sqrt()).abs() < 1e-12 && s[0].1 == -1.0);
    }
}
