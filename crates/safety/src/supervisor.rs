//! The per-cycle supervisor: samples in, `SafeToRun` (as a [`Lease`]), the interlock
//! outputs, `homeOK`, `paramsOK`, `allModulesOK` and a [`Diagnosis`] out.
//!
//! Each cycle, in this order (the first problem found is the diagnosis):
//! 1. `params_ok` (the last [`crate::integrity::Integrity::check`]) must be true.
//! 2. Every axis must have a sample that is present, not from the future, at most
//!    `max_sample_age` cycles old and finite (`allModulesOK`).
//! 3. Homing: in [`Mode::Normal`] every axis with `homing_required` must be homed
//!    (`homeOK`). In [`Mode::Homing`] un-homed axes are allowed, but each must move no faster
//!    than its `homing_speed_max`, and every rule leaf that reads an un-homed axis is
//!    skipped (its position is meaningless); leaves on homed axes still apply. Interlock
//!    outputs are false whenever any axis that needs homing is un-homed, in either mode.
//! 4. Rules in config order; the first that fails names the diagnosis.
//!
//! The prediction horizon of an axis is `reaction_time + age * cycle_time + lease_time`:
//! a lease granted now keeps the output true for at most `lease_time` even if the next
//! evaluations never come, and a stop decided at the next cycle takes effect within the
//! reaction time. There is no way to set SafeToRun: it only comes out of [`Supervisor::evaluate`],
//! and [`Lease`] has no public constructor.

use crate::model::AxisModel;
use crate::predict::{predict, Dynamics, Reach};
use crate::rules::{eval, explain, EvalContext, Finding, RuleSet};
use std::fmt;
use std::time::Duration;

/// Operating mode chosen by the station (never by a student program).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Normal operation: all axes that need homing must be homed.
    Normal,
    /// Homing procedure: see the module documentation for what it allows.
    Homing,
}

/// One axis sample, in the axis's units (see [`AxisModel::from_raw`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Actual position (units).
    pub position: f64,
    /// Actual speed (units/s).
    pub speed: f64,
    /// Supervisor cycle in which this value was received.
    pub cycle: u64,
    /// The drive reports the axis homed.
    pub homed: bool,
}

/// Inputs of one cycle.
#[derive(Debug, Clone, Copy)]
pub struct CycleInput<'a> {
    /// Monotonic time now (any fixed epoch), used for the lease.
    pub now: Duration,
    /// Current cycle number.
    pub cycle: u64,
    /// Mode.
    pub mode: Mode,
    /// Latest sample per axis, in the config's axis order (`None` = never received).
    pub samples: &'a [Option<Sample>],
    /// Outcome of the last integrity check (false until one passed).
    pub params_ok: bool,
}

/// Permission to run until `expires`. Only [`Supervisor::evaluate`] creates one; the
/// output driver must drop SafeToRun as soon as the newest decision carries no lease or
/// its lease is no longer valid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Lease {
    expires: Duration,
}

impl Lease {
    /// Expiry time.
    pub fn expires(&self) -> Duration {
        self.expires
    }
    /// True while `now < expires`.
    pub fn is_valid(&self, now: Duration) -> bool {
        now < self.expires
    }
}

/// Why sample data is unusable.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DataProblem {
    /// No sample yet (or the axis' slot is missing).
    Missing,
    /// Older than allowed.
    Stale {
        /// Age in cycles.
        age: u64,
        /// Allowed age.
        max: u32,
    },
    /// Sample stamped with a cycle after the current one.
    FromFuture {
        /// Its cycle.
        cycle: u64,
    },
    /// Position or speed is NaN or infinite.
    NotFinite,
}

/// Why SafeToRun is false (the first problem found).
#[derive(Debug, Clone, PartialEq)]
pub enum Diagnosis {
    /// Axis parameters or rules differ from the approved ones.
    ParamsNotApproved,
    /// Bad data for an axis.
    Data {
        /// Axis name.
        axis: String,
        /// Problem.
        problem: DataProblem,
    },
    /// Axes that need homing are not homed (normal mode).
    NotHomed {
        /// Axis names.
        axes: Vec<String>,
    },
    /// An un-homed axis moves too fast in homing mode.
    HomingTooFast {
        /// Axis name.
        axis: String,
        /// Its speed (units/s).
        speed: f64,
        /// Allowed magnitude.
        max: f64,
    },
    /// A rule fails.
    Rule {
        /// Rule name.
        rule: String,
        /// The leaves that make it fail, with the predicted figures.
        findings: Vec<Finding>,
    },
}

impl fmt::Display for Diagnosis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Diagnosis::ParamsNotApproved => {
                f.write_str("axis parameters or rules differ from the approved configuration")
            }
            Diagnosis::Data { axis, problem } => match problem {
                DataProblem::Missing => write!(f, "axis {axis}: no data"),
                DataProblem::Stale { age, max } => {
                    write!(f, "axis {axis}: data {age} cycles old (max {max})")
                }
                DataProblem::FromFuture { cycle } => {
                    write!(f, "axis {axis}: sample stamped with future cycle {cycle}")
                }
                DataProblem::NotFinite => write!(f, "axis {axis}: position or speed not a number"),
            },
            Diagnosis::NotHomed { axes } => write!(f, "axes not homed: {}", axes.join(", ")),
            Diagnosis::HomingTooFast { axis, speed, max } => {
                write!(f, "homing mode: un-homed axis {axis} moves at {speed:.1}/s (max {max:.1}/s)")
            }
            Diagnosis::Rule { rule, findings } => {
                write!(f, "rule {rule} failed:")?;
                for (i, x) in findings.iter().enumerate() {
                    let sep = if i == 0 { " " } else { "; " };
                    let not = if x.negated { "!" } else { "" };
                    write!(f, "{sep}{not}{} margin {:.1}", x.condition, x.margin)?;
                    for (name, pos, r) in &x.axes {
                        write!(f, " [{name} at {pos:.1}, reach {:.1}..{:.1}]", r.lo, r.hi)?;
                    }
                }
                Ok(())
            }
        }
    }
}

/// Outputs of one cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct Decision {
    safe_to_run: bool,
    lease: Option<Lease>,
    home_ok: bool,
    params_ok: bool,
    all_modules_ok: bool,
    interlocks: Vec<(String, bool)>,
    diagnosis: Option<Diagnosis>,
}

impl Decision {
    /// SafeToRun of this evaluation (the output driver should use [`Decision::lease`]).
    pub fn safe_to_run(&self) -> bool {
        self.safe_to_run
    }
    /// The lease granted by this evaluation (`Some` iff safe to run).
    pub fn lease(&self) -> Option<Lease> {
        self.lease
    }
    /// All axes that need homing are homed.
    pub fn home_ok(&self) -> bool {
        self.home_ok
    }
    /// Integrity input was OK.
    pub fn params_ok(&self) -> bool {
        self.params_ok
    }
    /// Every axis delivered fresh, finite data.
    pub fn all_modules_ok(&self) -> bool {
        self.all_modules_ok
    }
    /// Interlock outputs (name, value), in config order.
    pub fn interlocks(&self) -> &[(String, bool)] {
        &self.interlocks
    }
    /// One interlock by name.
    pub fn interlock(&self, name: &str) -> Option<bool> {
        self.interlocks.iter().find(|(n, _)| n == name).map(|(_, v)| *v)
    }
    /// Why SafeToRun is false (`None` when true).
    pub fn diagnosis(&self) -> Option<&Diagnosis> {
        self.diagnosis.as_ref()
    }
}

/// The supervisor: a validated rule set and reusable buffers.
#[derive(Debug, Clone)]
pub struct Supervisor {
    rules: RuleSet,
    dynamics: Vec<Dynamics>,
    reaches: Vec<Reach>,
    positions: Vec<f64>,
    decision: Decision,
}

impl Supervisor {
    /// Creates a supervisor for a validated rule set.
    pub fn new(rules: RuleSet) -> Supervisor {
        let dynamics = rules
            .axes()
            .iter()
            .map(|a: &AxisModel| Dynamics {
                accel_up: a.acceleration.up,
                accel_down: a.acceleration.down,
                brake_up: a.braking.up,
                brake_down: a.braking.down,
            })
            .collect();
        let n = rules.axes().len();
        let interlocks = rules.interlocks().iter().map(|r| (r.name.clone(), false)).collect();
        Supervisor {
            dynamics,
            reaches: vec![Reach::default(); n],
            positions: vec![0.0; n],
            decision: Decision {
                safe_to_run: false,
                lease: None,
                home_ok: false,
                params_ok: false,
                all_modules_ok: false,
                interlocks,
                diagnosis: None,
            },
            rules,
        }
    }

    /// The rule set.
    pub fn rules(&self) -> &RuleSet {
        &self.rules
    }

    /// Predicted reaches of the last evaluation (config axis order).
    pub fn reaches(&self) -> &[Reach] {
        &self.reaches
    }

    /// Evaluates one cycle. Allocates only when SafeToRun is false (diagnosis).
    pub fn evaluate(&mut self, input: &CycleInput<'_>) -> &Decision {
        let timing = &self.rules.config().supervisor;
        let axes = self.rules.axes();
        let d = &mut self.decision;
        d.params_ok = input.params_ok;
        d.safe_to_run = false;
        d.lease = None;
        d.diagnosis = None;
        d.interlocks.iter_mut().for_each(|(_, v)| *v = false);

        // 2. data, 3. homing; predictions computed on the way.
        let mut bad: Option<Diagnosis> = None;
        let mut unhomed: u64 = 0;
        for (i, m) in axes.iter().enumerate() {
            let s = input.samples.get(i).copied().flatten();
            let problem = match s {
                None => Some(DataProblem::Missing),
                Some(s) if s.cycle > input.cycle => Some(DataProblem::FromFuture { cycle: s.cycle }),
                Some(s) if input.cycle - s.cycle > u64::from(timing.max_sample_age) => {
                    Some(DataProblem::Stale { age: input.cycle - s.cycle, max: timing.max_sample_age })
                }
                Some(s) if !(s.position.is_finite() && s.speed.is_finite()) => Some(DataProblem::NotFinite),
                Some(_) => None,
            };
            match (s, problem) {
                (Some(s), None) => {
                    if m.homing_required && !s.homed {
                        unhomed |= 1u64 << (i % 64);
                    }
                    let age = (input.cycle - s.cycle) as f64 * timing.cycle_time;
                    let horizon = timing.reaction_time + age + timing.lease_time;
                    let dynamics = self.dynamics.get(i).copied().unwrap_or(Dynamics {
                        accel_up: f64::INFINITY,
                        accel_down: f64::INFINITY,
                        brake_up: 1.0,
                        brake_down: 1.0,
                    });
                    if let Some(r) = self.reaches.get_mut(i) {
                        *r = predict(s.position, s.speed, horizon, &dynamics);
                    }
                    if let Some(p) = self.positions.get_mut(i) {
                        *p = s.position;
                    }
                }
                (_, problem) => {
                    if bad.is_none() {
                        bad = Some(Diagnosis::Data {
                            axis: m.name.clone(),
                            problem: problem.unwrap_or(DataProblem::Missing),
                        });
                    }
                }
            }
        }
        d.all_modules_ok = bad.is_none();
        d.home_ok = unhomed == 0;
        if !input.params_ok {
            d.diagnosis = Some(Diagnosis::ParamsNotApproved);
            return d;
        }
        if let Some(b) = bad {
            d.diagnosis = Some(b);
            return d;
        }
        let cx = EvalContext { axes, reaches: &self.reaches, positions: &self.positions, ignore: unhomed };
        if unhomed != 0 {
            match input.mode {
                Mode::Normal => {
                    let names = axes
                        .iter()
                        .enumerate()
                        .filter(|(i, _)| unhomed & (1u64 << (i % 64)) != 0)
                        .map(|(_, a)| a.name.clone())
                        .collect();
                    d.diagnosis = Some(Diagnosis::NotHomed { axes: names });
                    return d;
                }
                Mode::Homing => {
                    for (i, m) in axes.iter().enumerate() {
                        let speed = input.samples.get(i).copied().flatten().map_or(f64::NAN, |s| s.speed);
                        if unhomed & (1u64 << (i % 64)) != 0 && speed.abs() > m.homing_speed_max {
                            d.diagnosis = Some(Diagnosis::HomingTooFast {
                                axis: m.name.clone(),
                                speed,
                                max: m.homing_speed_max,
                            });
                            return d;
                        }
                    }
                }
            }
        } else {
            for ((_, v), r) in d.interlocks.iter_mut().zip(self.rules.interlocks()) {
                *v = eval(&r.expr, &cx);
            }
        }
        for r in self.rules.rules() {
            if !eval(&r.expr, &cx) {
                let mut findings = Vec::new();
                explain(&r.expr, &cx, false, &mut findings);
                d.diagnosis = Some(Diagnosis::Rule { rule: r.name.clone(), findings });
                return d;
            }
        }
        d.safe_to_run = true;
        d.lease = Some(Lease { expires: input.now + Duration::from_secs_f64(timing.lease_time) });
        d
    }
}
