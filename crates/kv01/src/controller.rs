//! The control thread: one message to every module per cycle. A moving joint gets a D2
//! fast message (speed command + position in one round trip) from a host-side position
//! loop following its profile; an idle joint gets D3 (position) — both keep the module's
//! 700 ms safety time-out from tripping.

use crate::arm::{ArmConfig, JointState};
use crate::bus::{Kv01Bus, Kv01Error};
use crate::joints::{normalise_deg, JointSpec};
use motus_axis::profile::Plan;
use motus_clock::Clock;
use motus_kv01_protocol::{Address, Command, JointStatus, ReplyBody};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// How far (degrees) a joint may overshoot a soft limit (servo settling) before the
/// controller stops it with a fault.
pub const SOFT_LIMIT_OVERSHOOT_DEG: f64 = 1.0;

/// The largest fraction of a joint's position error one sample of the position loop corrects
/// (the gain is capped at this over the loop's real sample period).
pub const MAX_CORRECTION_PER_SAMPLE: f64 = 0.5;

/// A joint following a (normalised, shared) profile: `x(t) = x0 + d * s(t)`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Motion {
    pub start: Instant,
    pub plan: Plan,
    pub x0: f64,
    pub d: f64,
    pub settled_at: Option<Instant>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Reading {
    pub raw: u16,
    pub angle: f64,
    pub status: JointStatus,
    pub at: Instant,
}

/// What the host knows of one joint.
#[derive(Debug, Clone, Default)]
pub(crate) struct JointRuntime {
    pub reading: Option<Reading>,
    pub enabled: bool,
    pub motion: Option<Motion>,
    pub override_rpm: Option<f64>,
    pub fault: Option<String>,
    pub timeout_latched: Option<String>,
    /// When this host first saw the module answer "TO", and when it last did.
    pub latched_at: Option<Instant>,
    pub last_latched_answer: Option<Instant>,
    pub last_ok: Option<Instant>,
    pub longest_gap: Duration,
    pub commanded_rpm: f64,
    /// A limit-switch recovery runs: LSSTOP does not abort its motion, and the soft-limit
    /// stop of jogs is off (the joint starts beyond it).
    pub recovering: bool,
    /// When a D1 reply last set the status bits: older resolver replies do not overwrite them.
    pub status_set_at: Option<Instant>,
    /// When the position loop last computed a correction for this joint: the loop's real
    /// sample period (retries and a loaded host stretch it well beyond the cycle).
    pub last_correction_at: Option<Instant>,
}

impl JointRuntime {
    /// The joint's state at `now` (the arm's clock).
    pub fn snapshot(&self, joint: u8, now: Instant) -> JointState {
        let r = self.reading;
        JointState {
            joint,
            angle_deg: r.map(|r| r.angle).unwrap_or(f64::NAN),
            raw: r.map(|r| r.raw).unwrap_or(0),
            status: r.map(|r| r.status).unwrap_or_default(),
            enabled: self.enabled,
            moving: self.motion.is_some() || self.override_rpm.is_some_and(|v| v != 0.0),
            fault: self.timeout_latched.clone().or_else(|| self.fault.clone()),
            age: r.map(|r| now.saturating_duration_since(r.at)).unwrap_or(Duration::MAX),
            longest_gap: self.longest_gap,
        }
    }

    /// Latches the module's "TO" answer seen at `now` (the arm's clock).
    pub fn latch_timeout(&mut self, e: &Kv01Error, now: Instant) {
        if self.timeout_latched.is_none() {
            tracing::error!("{e}");
            self.timeout_latched = Some(e.to_string());
            self.latched_at = Some(now);
        }
        self.last_latched_answer = Some(now);
        self.enabled = false;
        self.motion = None;
        self.override_rpm = None;
    }

    fn record_ok(&mut self, now: Instant) {
        if let Some(prev) = self.last_ok {
            self.longest_gap = self.longest_gap.max(now - prev);
        }
        self.last_ok = Some(now);
    }
}

pub(crate) struct State {
    pub config: ArmConfig,
    pub joints: [JointRuntime; 6],
}

pub(crate) struct Shared(Mutex<State>);

impl Shared {
    pub fn new(config: ArmConfig) -> Self {
        Shared(Mutex::new(State { config, joints: Default::default() }))
    }
    pub fn lock(&self) -> MutexGuard<'_, State> {
        self.0.lock().unwrap_or_else(|p| p.into_inner())
    }
}

/// The speed command for one joint this cycle, or `None` to just read it.
fn speed_command(spec: &JointSpec, r: &mut JointRuntime, config: &ArmConfig, now: Instant) -> Option<f64> {
    let reading = r.reading?;
    let angle = reading.angle;
    if let Some(rpm) = r.override_rpm {
        if r.recovering {
            return Some(rpm);
        }
        // Jog at a fixed speed: stop at the soft limit before the switch.
        let deg_s = rpm * spec.deg_s_per_rpm();
        // Stopping distance at the configured deceleration plus a few cycles of reaction:
        // from there on, a planned deceleration ends the run exactly at the soft limit.
        let v = deg_s.abs();
        let a = config.acceleration_deg_s2;
        let margin = v * v / (2.0 * a) + v * 3.0 * config.cycle.as_secs_f64();
        if let Some((lo, hi)) = spec.soft_limits_deg {
            let limit = if deg_s > 0.0 { hi } else { lo };
            if (deg_s > 0.0 && angle >= hi - margin) || (deg_s < 0.0 && angle <= lo + margin) {
                r.override_rpm = None;
                let d = limit - angle;
                if d * deg_s <= 0.0 || d.abs() < 1e-6 {
                    return Some(0.0);
                }
                let plan = Plan::to_target(0.0, deg_s / d, 1.0, v / d.abs(), a / d.abs());
                r.motion = Some(Motion { start: now, plan, x0: angle, d, settled_at: None });
                return Some(rpm);
            }
        }
        return Some(rpm);
    }
    let period = r
        .last_correction_at
        .map_or(config.cycle, |t| now.saturating_duration_since(t))
        .max(config.cycle)
        .as_secs_f64();
    let m = r.motion.as_mut()?;
    r.last_correction_at = Some(now);
    let t = now.saturating_duration_since(m.start).as_secs_f64();
    let (s, sv) = m.plan.sample(t);
    let x_ref = m.x0 + m.d * s;
    let v_ref = m.d * sv;
    let err = if spec.soft_limits_deg.is_none() { normalise_deg(x_ref - angle) } else { x_ref - angle };
    if t >= m.plan.duration() {
        if err.abs() <= config.tolerance_deg {
            r.motion = None;
            return Some(0.0);
        }
        let since = *m.settled_at.get_or_insert(now);
        if now - since > config.settle_timeout {
            r.motion = None;
            r.fault = Some(format!("did not reach {x_ref:.3} deg (stopped at {angle:.3} deg)"));
            return Some(0.0);
        }
    }
    // A sampled proportional loop overshoots once gain x period passes 1 and oscillates
    // around the target beyond 2: the gain is capped so one period corrects at most half the
    // error, however late this sample came.
    let kp = config.kp.min(MAX_CORRECTION_PER_SAMPLE / period);
    let mut deg_s = (v_ref + kp * err).clamp(-spec.max_deg_s(), spec.max_deg_s());
    if let Some((lo, hi)) = spec.soft_limits_deg {
        if angle > hi + SOFT_LIMIT_OVERSHOOT_DEG || angle < lo - SOFT_LIMIT_OVERSHOOT_DEG {
            r.motion = None;
            r.fault = Some(format!("stopped at {angle:.3} deg: beyond the soft limits {lo} .. {hi} deg"));
            return Some(0.0);
        }
        // Never push further out past a soft limit.
        if (angle > hi && deg_s > 0.0) || (angle < lo && deg_s < 0.0) {
            deg_s = 0.0;
        }
    }
    Some(spec.rpm_for(deg_s))
}

/// The control loop, cycling on `clock`; returns when `stop` is set.
pub(crate) fn run(bus: &Kv01Bus, shared: &Shared, stop: &AtomicBool, clock: &dyn Clock) {
    let mut next = clock.now();
    while !stop.load(Ordering::Relaxed) {
        for joint in 1u8..=6 {
            let Some(addr) = Address::joint(joint) else { continue };
            let i = usize::from(joint - 1);
            let (command, spec) = {
                let mut st = shared.lock();
                let config = st.config.clone();
                let Some(spec) = config.joints.get(i).copied() else { continue };
                let Some(r) = st.joints.get_mut(i) else { continue };
                let cmd = if r.enabled && r.timeout_latched.is_none() {
                    speed_command(&spec, r, &config, clock.now())
                } else {
                    None
                };
                if let Some(rpm) = cmd {
                    r.commanded_rpm = rpm;
                }
                (cmd, spec)
            };
            let request = match command {
                Some(rpm) => Command::Fast { text: format!("V{}", rpm.round() as i64) },
                None => Command::ReadResolver,
            };
            let sent_at = clock.now();
            let result = bus.transact(addr, request);
            let now = clock.now();
            let mut st = shared.lock();
            let Some(r) = st.joints.get_mut(i) else { continue };
            match result {
                Ok(body) => {
                    r.record_ok(now);
                    if let Some(res) = body.resolver() {
                        // A D1 answered while this request was on the line is newer.
                        let status = match (r.status_set_at, r.reading) {
                            (Some(t), Some(old)) if t > sent_at => old.status,
                            _ => res.status,
                        };
                        r.reading = Some(Reading {
                            raw: res.position,
                            angle: spec.angle_deg(res.position),
                            status,
                            at: now,
                        });
                        if res.status.lsstop
                            && !r.recovering
                            && (r.motion.is_some() || r.override_rpm.is_some())
                        {
                            r.motion = None;
                            r.override_rpm = None;
                            r.fault =
                                Some("the module stopped the joint on its limit switch (LSSTOP)".into());
                        }
                    }
                    if let ReplyBody::Faulhaber { answer } = &body {
                        tracing::warn!(joint, %answer, "speed command answered instead of a resolver reading");
                    }
                }
                Err(e @ Kv01Error::SafetyTimeout { .. }) => r.latch_timeout(&e, now),
                Err(e) => tracing::debug!(joint, error = %e, "cycle transaction failed"),
            }
        }
        let cycle = shared.lock().config.cycle;
        next += cycle;
        let now = clock.now();
        if next > now {
            clock.sleep_until_precise(next);
        } else {
            next = now;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use motus_kv01_protocol::JointStatus;

    /// A joint whose move has ended 0.1 deg short, sampled `late` after its last correction.
    fn settle_command(late: Duration) -> f64 {
        let config = ArmConfig::default();
        let spec = JointSpec::kv01(1);
        let t0 = Instant::now();
        let now = t0 + Duration::from_secs(5);
        let mut r = JointRuntime {
            reading: Some(Reading { raw: 0, angle: 9.9, status: JointStatus::default(), at: now }),
            enabled: true,
            motion: Some(Motion {
                start: t0,
                plan: Plan::to_target(0.0, 0.0, 1.0, 1.0, 1.0),
                x0: 0.0,
                d: 10.0,
                settled_at: None,
            }),
            last_correction_at: Some(now - late),
            ..JointRuntime::default()
        };
        let rpm = speed_command(&spec, &mut r, &config, now).unwrap_or_default();
        rpm * spec.deg_s_per_rpm()
    }

    #[test]
    fn a_late_sample_corrects_at_most_half_the_error_over_its_period() {
        // On time (one cycle): the configured gain, 4/s x 0.1 deg.
        let on_time = settle_command(ArmConfig::default().cycle);
        assert!((on_time - 0.4).abs() < 0.02, "{on_time} deg/s");
        // 400 ms late (retries on a noisy line, a loaded host): 0.4 s x 4/s would overshoot
        // by 60 %; at most half the error per period instead.
        let late = settle_command(Duration::from_millis(400));
        assert!(late > 0.0 && late * 0.4 <= 0.05 + 1e-3, "{late} deg/s");
    }
}
