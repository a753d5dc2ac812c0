//! A simulated machine with the supervisor in the loop, for tests and benchmarks.
//!
//! Each axis follows a set-point with a bounded speed and acceleration (never more than the
//! model's worst-case acceleration), and on quick stop brakes at exactly the model's braking
//! deceleration. The loop has the data path of the seed: the supervisor sees the state of
//! `input_delay` cycles ago and its output reaches the amplifiers `output_delay` cycles later
//! (`input_delay + output_delay` cycles = the reaction time). Samples can be dropped (they
//! age) and evaluations skipped (the output driver then relies on the last [`Lease`]).
//!
//! [`Lease`]: crate::supervisor::Lease

use crate::model::AxisModel;
use crate::rules::RuleSet;
use crate::supervisor::{CycleInput, Lease, Mode, Sample, Supervisor};
use std::collections::VecDeque;
use std::time::Duration;

/// State of one simulated axis.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AxisState {
    /// Position (units).
    pub position: f64,
    /// Speed (units/s).
    pub speed: f64,
}

/// Set-point of one axis for a program segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SetPoint {
    /// Target position (units).
    pub target: f64,
    /// Speed limit (units/s, > 0).
    pub speed: f64,
    /// Acceleration asked for (units/s^2); capped at the model's worst case.
    pub accel: f64,
}

/// One segment of a motion program: set-points for every axis held for `cycles` cycles.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// One set-point per axis (config order).
    pub set_points: Vec<SetPoint>,
    /// Duration in cycles.
    pub cycles: u32,
}

/// A motion program and the disturbances of its run.
#[derive(Debug, Clone, PartialEq)]
pub struct Program {
    /// Start positions (axes at rest), config order.
    pub start: Vec<f64>,
    /// Segments.
    pub segments: Vec<Segment>,
    /// Cycles in which no new sample reaches the supervisor (sorted or not).
    pub dropped_samples: Vec<u64>,
    /// Cycles in which the supervisor does not evaluate.
    pub skipped_evaluations: Vec<u64>,
}

/// Delays of the loop, in cycles.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoopDelays {
    /// Age of the machine state when the supervisor receives it.
    pub input_delay: usize,
    /// Cycles from the supervisor's output to the amplifiers' quick-stop input.
    pub output_delay: usize,
}

/// Advances one axis by `dt` toward its set-point, or braking when `stop`.
pub fn step_axis(s: &mut AxisState, m: &AxisModel, sp: &SetPoint, stop: bool, dt: f64) {
    let v = s.speed;
    if stop {
        let b = if v > 0.0 { m.braking.up } else { m.braking.down };
        if v.abs() <= b * dt {
            s.position += v * v.abs() / (2.0 * b);
            s.speed = 0.0;
        } else {
            let a = -v.signum() * b;
            s.position += v * dt + a * dt * dt / 2.0;
            s.speed = v + a * dt;
        }
        return;
    }
    let e = sp.target - s.position;
    let a_up = sp.accel.min(m.acceleration.up).max(0.0);
    let a_down = sp.accel.min(m.acceleration.down).max(0.0);
    let a_brake = if e > 0.0 { a_down } else { a_up };
    let want = e.signum() * sp.speed.min((2.0 * a_brake * e.abs()).sqrt());
    let a = ((want - v) / dt).clamp(-a_down, a_up);
    s.position += v * dt + a * dt * dt / 2.0;
    s.speed = v + a * dt;
}

/// Cycles simulated after the last segment, holding its set-points.
pub const TAIL_CYCLES: u64 = 250;
/// Cycles after which a run that never got SafeToRun gives up.
pub const START_LIMIT: u64 = 1_000;

/// Outcome of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunResult {
    /// Cycle at which the amplifiers received the quick stop (after motion had started).
    pub stopped_at: Option<u64>,
    /// Diagnosis text of the decision that caused the stop.
    pub stop_reason: Option<String>,
    /// First hazard found by the caller's check: (cycle, description).
    pub hazard: Option<(u64, String)>,
    /// States of every cycle (only when asked for).
    pub history: Vec<Vec<AxisState>>,
    /// Cycles simulated.
    pub cycles: u64,
    /// The supervisor granted SafeToRun at least once (motion started).
    pub started: bool,
}

/// Runs `program` on the simulated machine. With `supervised`, the supervisor gates
/// the motion (quick stop latches until the end); without, it is ignored. `hazard`
/// is called on every cycle's positions.
pub fn run(
    rules: &RuleSet,
    program: &Program,
    delays: LoopDelays,
    supervised: bool,
    keep_history: bool,
    hazard: &dyn Fn(&[f64]) -> Option<String>,
) -> RunResult {
    let axes = rules.axes();
    let timing = &rules.config().supervisor;
    let dt = timing.cycle_time;
    let mut sup = Supervisor::new(rules.clone());
    let mut state: Vec<AxisState> =
        program.start.iter().map(|p| AxisState { position: *p, speed: 0.0 }).collect();
    state.resize(axes.len(), AxisState::default());
    let mut past: VecDeque<Vec<AxisState>> = VecDeque::new();
    let mut samples: Vec<Option<Sample>> = vec![None; axes.len()];
    let mut outputs: VecDeque<bool> = VecDeque::from(vec![false; delays.output_delay]);
    let mut lease: Option<Lease> = None;
    let mut last_reason: Option<String> = None;
    let mut started = !supervised;
    let mut res = RunResult {
        stopped_at: None,
        stop_reason: None,
        hazard: None,
        history: Vec::new(),
        cycles: 0,
        started: false,
    };
    let total: u64 = program.segments.iter().map(|s| u64::from(s.cycles)).sum();
    let idle = SetPoint { target: 0.0, speed: 0.0, accel: 0.0 };
    let mut seg_iter = program.segments.iter();
    let mut seg = seg_iter.next();
    let mut seg_left = seg.map_or(0, |s| s.cycles);
    let mut k: u64 = 0;
    let mut tail_from: Option<u64> = None;
    if program.segments.is_empty() {
        tail_from = Some(0);
    }
    loop {
        // Supervisor side.
        past.push_back(state.clone());
        while past.len() > delays.input_delay + 1 {
            past.pop_front();
        }
        let seen = past.front().cloned().unwrap_or_default();
        let now = Duration::from_secs_f64(k as f64 * dt);
        let mut out = false;
        if supervised {
            if !program.dropped_samples.contains(&k) {
                for (slot, st) in samples.iter_mut().zip(&seen) {
                    *slot = Some(Sample { position: st.position, speed: st.speed, cycle: k, homed: true });
                }
            }
            if program.skipped_evaluations.contains(&k) {
                out = lease.is_some_and(|l| l.is_valid(now));
            } else {
                let d = sup.evaluate(&CycleInput {
                    now,
                    cycle: k,
                    mode: Mode::Normal,
                    samples: &samples,
                    params_ok: true,
                });
                lease = d.lease();
                out = d.safe_to_run() && lease.is_some_and(|l| l.is_valid(now));
                if !out && last_reason.is_none() && started {
                    last_reason = d.diagnosis().map(ToString::to_string);
                }
            }
        }
        outputs.push_back(out);
        let enable = if supervised { outputs.pop_front().unwrap_or(false) } else { true };
        // Machine side.
        if enable && !started {
            started = true;
        }
        let stop = supervised && (!enable || res.stopped_at.is_some());
        if stop && started && res.stopped_at.is_none() {
            res.stopped_at = Some(k);
            res.stop_reason = last_reason.clone();
        }
        let moving = started && res.stopped_at.is_none();
        for (i, (s, m)) in state.iter_mut().zip(axes).enumerate() {
            let sp =
                if moving { seg.and_then(|g| g.set_points.get(i)).copied().unwrap_or(idle) } else { idle };
            if moving || stop {
                step_axis(s, m, &sp, stop, dt);
            }
        }
        if moving {
            seg_left = seg_left.saturating_sub(1);
            while seg_left == 0 {
                match seg_iter.next() {
                    Some(s) => {
                        seg = Some(s);
                        seg_left = s.cycles;
                    }
                    None => {
                        // Hold the last set-points for the tail.
                        seg_left = u32::MAX;
                        tail_from.get_or_insert(k);
                    }
                }
            }
        }
        k += 1;
        let positions: Vec<f64> = state.iter().map(|s| s.position).collect();
        if res.hazard.is_none() {
            if let Some(h) = hazard(&positions) {
                res.hazard = Some((k, h));
            }
        }
        if keep_history {
            res.history.push(state.clone());
        }
        let at_rest = state.iter().all(|s| s.speed == 0.0);
        let tail_done = tail_from.is_some_and(|t| k > t + TAIL_CYCLES);
        if (res.stopped_at.is_some() && at_rest) || tail_done || k > total + START_LIMIT {
            break;
        }
    }
    res.cycles = k;
    res.started = started;
    res
}
