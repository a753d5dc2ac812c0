//! Virtual-to-real axis coupling.
//!
//! The executor drives virtual axes; each real axis follows its virtual axis 1:1 plus an
//! offset. During a pause the coupling can be released, the real axes jogged, and then
//! either recoupled with the new offset kept (the source's M63 tool-offset shift) or brought
//! back to the virtual position along a straight line within the axis limits before the
//! program continues.

use crate::config::AxisLimits;
use crate::error::CommandError;
use crate::ramp::brake_speed;
use crate::vector::{add_scaled, norm, scale, sub};

/// State of the coupling.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CouplingState {
    /// Real axes follow the virtual ones (plus the offset).
    Coupled,
    /// Real axes move on their own (jog).
    Released,
    /// Real axes are travelling back to the virtual position.
    Recoupling,
}

impl CouplingState {
    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            CouplingState::Coupled => "coupled",
            CouplingState::Released => "released",
            CouplingState::Recoupling => "recoupling",
        }
    }
}

/// How to recouple.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Recouple {
    /// Move the real axes back to virtual + previous offset, then couple.
    ReturnToPath,
    /// Couple where the real axes are now: the offset becomes real - virtual.
    KeepOffset,
}

#[derive(Debug, Clone, Copy)]
struct Approach<const N: usize> {
    start: [f64; N],
    dir: [f64; N],
    length: f64,
    s: f64,
    v: f64,
    cap: f64,
    accel: f64,
}

/// The coupling of `N` real axes to the virtual ones.
#[derive(Debug, Clone)]
pub struct Coupling<const N: usize> {
    limits: [AxisLimits; N],
    state: CouplingState,
    offset: [f64; N],
    real: [f64; N],
    real_vel: [f64; N],
    jog: [f64; N],
    approach: Option<Approach<N>>,
}

impl<const N: usize> Coupling<N> {
    /// Coupled, zero offset, real axes at `start`.
    pub fn new(limits: [AxisLimits; N], start: [f64; N]) -> Self {
        Self {
            limits,
            state: CouplingState::Coupled,
            offset: [0.0; N],
            real: start,
            real_vel: [0.0; N],
            jog: [0.0; N],
            approach: None,
        }
    }

    /// Current state.
    pub fn state(&self) -> CouplingState {
        self.state
    }

    /// Offset real - virtual used while coupled.
    pub fn offset(&self) -> [f64; N] {
        self.offset
    }

    /// Real axis positions.
    pub fn real_positions(&self) -> [f64; N] {
        self.real
    }

    /// Real axis velocities.
    pub fn real_velocities(&self) -> [f64; N] {
        self.real_vel
    }

    /// Releases the coupling (the caller checks that the path is at rest).
    pub(crate) fn release(&mut self) -> Result<(), CommandError> {
        if self.state != CouplingState::Coupled {
            return Err(CommandError::NotCoupled { command: "release", coupling: self.state.name() });
        }
        self.state = CouplingState::Released;
        self.jog = [0.0; N];
        Ok(())
    }

    /// Jogs real axis `axis` at `velocity` (clamped to its limit; 0 stops it).
    pub(crate) fn jog(&mut self, axis: usize, velocity: f64) -> Result<(), CommandError> {
        if self.state != CouplingState::Released {
            return Err(CommandError::NotReleased { command: "jog" });
        }
        if !velocity.is_finite() {
            return Err(CommandError::Value { what: "jog velocity", value: velocity });
        }
        let lim = self.limits.get(axis).ok_or(CommandError::Axis(axis))?.velocity;
        let slot = self.jog.get_mut(axis).ok_or(CommandError::Axis(axis))?;
        *slot = velocity.clamp(-lim, lim);
        Ok(())
    }

    /// Starts recoupling; `virtual_pos` is where the (resting) virtual axes are.
    pub(crate) fn recouple(&mut self, how: Recouple, virtual_pos: &[f64; N]) -> Result<(), CommandError> {
        if self.state != CouplingState::Released {
            return Err(CommandError::NotReleased { command: "recouple" });
        }
        if self.real_vel.iter().chain(&self.jog).any(|v| *v != 0.0) {
            return Err(CommandError::NotAtRest { command: "recouple", state: "jogging" });
        }
        match how {
            Recouple::KeepOffset => {
                self.offset = sub(&self.real, virtual_pos);
                self.state = CouplingState::Coupled;
            }
            Recouple::ReturnToPath => {
                let target = add_scaled(virtual_pos, 1.0, &self.offset);
                let delta = sub(&target, &self.real);
                let length = norm(&delta);
                if length < 1e-12 {
                    self.state = CouplingState::Coupled;
                    return Ok(());
                }
                let dir = scale(1.0 / length, &delta);
                let (mut cap, mut accel) = (f64::INFINITY, f64::INFINITY);
                for (u, l) in dir.iter().zip(&self.limits) {
                    if u.abs() > 1e-12 {
                        cap = cap.min(l.velocity / u.abs());
                        accel = accel.min(l.acceleration / u.abs());
                    }
                }
                self.approach = Some(Approach { start: self.real, dir, length, s: 0.0, v: 0.0, cap, accel });
                self.state = CouplingState::Recoupling;
            }
        }
        Ok(())
    }

    /// Advances one cycle; returns real positions and velocities.
    pub(crate) fn tick(&mut self, virt: &[f64; N], virt_vel: &[f64; N], dt: f64) -> ([f64; N], [f64; N]) {
        match self.state {
            CouplingState::Coupled => {
                self.real = add_scaled(virt, 1.0, &self.offset);
                self.real_vel = *virt_vel;
            }
            CouplingState::Released => {
                for (((p, v), target), l) in
                    self.real.iter_mut().zip(self.real_vel.iter_mut()).zip(&self.jog).zip(&self.limits)
                {
                    let step = l.acceleration * dt;
                    let nv = if *v < *target { (*v + step).min(*target) } else { (*v - step).max(*target) };
                    *p += 0.5 * (*v + nv) * dt;
                    *v = nv;
                }
            }
            CouplingState::Recoupling => {
                if let Some(a) = self.approach.as_mut() {
                    let rem = a.length - a.s;
                    let nv = (a.v + a.accel * dt).min(a.cap).min(brake_speed(0.0, a.accel, rem, a.v, dt));
                    let ds = 0.5 * (a.v + nv) * dt;
                    if ds >= rem - 1e-9 {
                        self.real = add_scaled(&a.start, a.length, &a.dir);
                        self.real_vel = [0.0; N];
                        self.approach = None;
                        self.state = CouplingState::Coupled;
                    } else {
                        a.s += ds;
                        a.v = nv;
                        self.real = add_scaled(&a.start, a.s, &a.dir);
                        self.real_vel = scale(nv, &a.dir);
                    }
                }
            }
        }
        (self.real, self.real_vel)
    }
}
