//! The safety configuration (TOML) and the evaluation of its rules.
//!
//! A config has a `[supervisor]` table (timing), `[[axis]]` tables ([`AxisModel`]),
//! `[[rule]]` tables whose conjunction, in file order, is `SafeToRun`, and `[[interlock]]`
//! tables that each drive one extra output (the juggler's `FeederEnable`). Rule and
//! interlock expressions use the grammar of [`crate::expr`]. Example:
//! `crates/safety/examples/juggler.toml` (the seed's rule set).
//!
//! Every leaf yields a signed *margin* in axis units; the leaf holds iff margin > 0:
//! limits `min(lo - min, max - hi)`; region `max(min - hi, lo - max)`; collision
//! `max(lo_a - down_a - hi_b - up_b, lo_b - down_b - hi_a - up_a)` (reaches grown by
//! the oversizes); below `value - hi`; above `lo - value`; within `min(lo - min, max - hi)`;
//! position `value - s0` / `s0 - value`.

use crate::expr::{self, Canonical, Expr, ExprError, Leaf};
use crate::model::{validate_axes, AxisModel, ModelError};
use crate::predict::Reach;
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Timing of the supervisor (`[supervisor]` table).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Timing {
    /// Reaction time Tp (s): from a sample's arrival to the stop taking effect
    /// (network + CPU + output); 0.0096 s measured on the juggler.
    pub reaction_time: f64,
    /// Supervisor cycle (s); 0.0004 s (the POWERLINK cycle) on the juggler.
    pub cycle_time: f64,
    /// A sample older than this many cycles is stale (SafeToRun false).
    pub max_sample_age: u32,
    /// Validity of a SafeToRun lease (s) after the evaluation that granted it.
    pub lease_time: f64,
}

/// One named rule or interlock (`[[rule]]` / `[[interlock]]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RuleText {
    /// Name shown in diagnoses.
    pub name: String,
    /// Expression text (see [`crate::expr`]).
    pub expr: String,
    /// Free text for the administrator.
    #[serde(default)]
    pub description: String,
}

/// The configuration file as written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SafetyConfig {
    /// Timing.
    pub supervisor: Timing,
    /// Axis models.
    #[serde(rename = "axis")]
    pub axes: Vec<AxisModel>,
    /// Rules whose conjunction is SafeToRun (evaluated in this order).
    #[serde(rename = "rule")]
    pub rules: Vec<RuleText>,
    /// Extra outputs (e.g. `feeder_enable`).
    #[serde(rename = "interlock", default)]
    pub interlocks: Vec<RuleText>,
}

/// A configuration problem.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ConfigError {
    /// TOML syntax or a field of the wrong type / unknown field.
    #[error("config syntax: {0}")]
    Toml(String),
    /// An invalid axis model.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// A rule whose expression is wrong.
    #[error("rule {rule:?}: {error}")]
    Rule {
        /// Rule or interlock name.
        rule: String,
        /// Problem.
        error: ExprError,
    },
    /// Two rules/interlocks share a name, or a name is empty.
    #[error("bad or duplicate rule name {0:?}")]
    RuleName(String),
    /// No `[[rule]]` at all.
    #[error("the config has no [[rule]]")]
    NoRules,
    /// More than 64 axes.
    #[error("at most 64 axes are supported (got {0})")]
    TooManyAxes(usize),
    /// Impossible timing.
    #[error("supervisor timing: {0}")]
    Timing(String),
}

/// A compiled, named rule.
#[derive(Debug, Clone, PartialEq)]
pub struct Rule {
    /// Name.
    pub name: String,
    /// Compiled expression.
    pub expr: Expr,
}

/// A validated configuration with compiled rules.
#[derive(Debug, Clone, PartialEq)]
pub struct RuleSet {
    config: SafetyConfig,
    rules: Vec<Rule>,
    interlocks: Vec<Rule>,
}

impl RuleSet {
    /// Parses and validates a TOML config.
    pub fn from_toml(text: &str) -> Result<RuleSet, ConfigError> {
        let config: SafetyConfig = toml::from_str(text).map_err(|e| ConfigError::Toml(e.to_string()))?;
        RuleSet::new(config)
    }

    /// Validates a config: axes, timing, rule names, expressions (unknown axes, impossible
    /// bounds, unit mismatches).
    pub fn new(config: SafetyConfig) -> Result<RuleSet, ConfigError> {
        validate_axes(&config.axes)?;
        if config.axes.len() > 64 {
            return Err(ConfigError::TooManyAxes(config.axes.len()));
        }
        let t = &config.supervisor;
        for (n, v) in
            [("reaction_time", t.reaction_time), ("cycle_time", t.cycle_time), ("lease_time", t.lease_time)]
        {
            if !(v.is_finite() && v > 0.0) {
                return Err(ConfigError::Timing(format!("{n} must be > 0 s (got {v})")));
            }
        }
        if t.lease_time < t.cycle_time || t.lease_time >= t.reaction_time {
            return Err(ConfigError::Timing(format!(
                "lease_time {} must be >= cycle_time {} (renewed every cycle) and < reaction_time {}",
                t.lease_time, t.cycle_time, t.reaction_time
            )));
        }
        if config.rules.is_empty() {
            return Err(ConfigError::NoRules);
        }
        let mut names: Vec<String> = Vec::new();
        let mut compile = |list: &[RuleText]| -> Result<Vec<Rule>, ConfigError> {
            let mut out = Vec::new();
            for r in list {
                if r.name.is_empty() || names.contains(&r.name) {
                    return Err(ConfigError::RuleName(r.name.clone()));
                }
                let expr = expr::parse(&r.expr, &config.axes)
                    .map_err(|error| ConfigError::Rule { rule: r.name.clone(), error })?;
                out.push(Rule { name: r.name.clone(), expr });
                names.push(r.name.clone());
            }
            Ok(out)
        };
        let rules = compile(&config.rules)?;
        let interlocks = compile(&config.interlocks)?;
        Ok(RuleSet { rules, interlocks, config })
    }

    /// The config as loaded.
    pub fn config(&self) -> &SafetyConfig {
        &self.config
    }
    /// Axis models.
    pub fn axes(&self) -> &[AxisModel] {
        &self.config.axes
    }
    /// Compiled rules (SafeToRun = all of them).
    pub fn rules(&self) -> &[Rule] {
        &self.rules
    }
    /// Compiled interlocks.
    pub fn interlocks(&self) -> &[Rule] {
        &self.interlocks
    }
    /// Index of an axis by name.
    pub fn axis_index(&self, name: &str) -> Option<usize> {
        self.config.axes.iter().position(|a| a.name == name)
    }

    /// Canonical `key = value` lines of everything the rules rely on (sorted by key
    /// within each group; numbers in Rust's shortest round-trip form). Comments,
    /// whitespace and expression spelling do not change it; any value does.
    pub fn canonical_lines(&self) -> Vec<(String, String)> {
        let mut v = Vec::new();
        let t = &self.config.supervisor;
        v.push(("supervisor.reaction_time".into(), format!("{:?}", t.reaction_time)));
        v.push(("supervisor.cycle_time".into(), format!("{:?}", t.cycle_time)));
        v.push(("supervisor.max_sample_age".into(), t.max_sample_age.to_string()));
        v.push(("supervisor.lease_time".into(), format!("{:?}", t.lease_time)));
        for a in &self.config.axes {
            let k = |f: &str| format!("axis[{}].{f}", a.name);
            v.push((k("id"), a.id.to_string()));
            v.push((k("unit"), a.unit.clone()));
            v.push((k("raw_per_unit"), format!("{:?}", a.raw_per_unit)));
            v.push((k("limits.min"), format!("{:?}", a.limits.min)));
            v.push((k("limits.max"), format!("{:?}", a.limits.max)));
            v.push((k("acceleration.up"), format!("{:?}", a.acceleration.up)));
            v.push((k("acceleration.down"), format!("{:?}", a.acceleration.down)));
            v.push((k("braking.up"), format!("{:?}", a.braking.up)));
            v.push((k("braking.down"), format!("{:?}", a.braking.down)));
            v.push((k("oversize.up"), format!("{:?}", a.oversize.up)));
            v.push((k("oversize.down"), format!("{:?}", a.oversize.down)));
            v.push((k("homing_required"), a.homing_required.to_string()));
            v.push((k("homing_speed_max"), format!("{:?}", a.homing_speed_max)));
        }
        let axes = &self.config.axes;
        for (i, r) in self.rules.iter().enumerate() {
            let e = Canonical { expr: &r.expr, axes };
            v.push((format!("rule[{i}].{}", r.name), e.to_string()));
        }
        for r in &self.interlocks {
            let e = Canonical { expr: &r.expr, axes };
            v.push((format!("interlock.{}", r.name), e.to_string()));
        }
        v
    }
}

/// What a leaf sees: models, predicted reaches and current positions (same indexes).
#[derive(Debug, Clone, Copy)]
pub struct EvalContext<'a> {
    /// Axis models.
    pub axes: &'a [AxisModel],
    /// Predicted reach per axis.
    pub reaches: &'a [Reach],
    /// Current position per axis (units).
    pub positions: &'a [f64],
    /// Bit `i` set: axis `i` is un-homed in homing mode; leaves reading it hold.
    pub ignore: u64,
}

/// Signed margin of a leaf (units); the leaf holds iff it is > 0. NaN (missing axis) fails.
pub fn margin(leaf: &Leaf, cx: &EvalContext<'_>) -> f64 {
    let r = |i: usize| cx.reaches.get(i).copied();
    let m = |i: usize| cx.axes.get(i);
    let p = |i: usize| cx.positions.get(i).copied().unwrap_or(f64::NAN);
    let nan = f64::NAN;
    if cx.ignore != 0 {
        let (a, b) = leaf.axes();
        let bit = |i: usize| cx.ignore & (1u64 << (i % 64)) != 0;
        if bit(a) || b.is_some_and(bit) {
            return f64::INFINITY;
        }
    }
    match *leaf {
        Leaf::Limits { axis } => match (r(axis), m(axis)) {
            (Some(r), Some(m)) => (r.lo - m.limits.min).min(m.limits.max - r.hi),
            _ => nan,
        },
        Leaf::Region { axis, min, max } => r(axis).map_or(nan, |r| (min - r.hi).max(r.lo - max)),
        Leaf::Within { axis, min, max } => r(axis).map_or(nan, |r| (r.lo - min).min(max - r.hi)),
        Leaf::Below { axis, value } => r(axis).map_or(nan, |r| value - r.hi),
        Leaf::Above { axis, value } => r(axis).map_or(nan, |r| r.lo - value),
        Leaf::PositionBelow { axis, value } => value - p(axis),
        Leaf::PositionAbove { axis, value } => p(axis) - value,
        Leaf::Collision { a, b } => match (r(a), r(b), m(a), m(b)) {
            (Some(ra), Some(rb), Some(ma), Some(mb)) => {
                let a_below = rb.lo - mb.oversize.down - (ra.hi + ma.oversize.up);
                let a_above = ra.lo - ma.oversize.down - (rb.hi + mb.oversize.up);
                a_below.max(a_above)
            }
            _ => nan,
        },
    }
}

/// Evaluates an expression (no allocation).
pub fn eval(e: &Expr, cx: &EvalContext<'_>) -> bool {
    match e {
        Expr::And(v) => v.iter().all(|e| eval(e, cx)),
        Expr::Or(v) => v.iter().any(|e| eval(e, cx)),
        Expr::Not(e) => !eval(e, cx),
        Expr::Leaf(l) => margin(l, cx) > 0.0,
    }
}

/// A leaf that made a rule fail, with the figures the administrator needs.
#[derive(Debug, Clone, PartialEq)]
pub struct Finding {
    /// The leaf in canonical form (`collision(vertical_left, vertical_right)`).
    pub condition: String,
    /// Its margin (units; <= 0 means it failed; > 0 under a `!`).
    pub margin: f64,
    /// True when the leaf failed by holding (it was under a `!`).
    pub negated: bool,
    /// The axes involved: (name, current position, predicted reach).
    pub axes: Vec<(String, f64, Reach)>,
}

/// Collects the leaves that explain why `e` is false (first failing child of an `&&`,
/// every child of an `||`).
pub fn explain(e: &Expr, cx: &EvalContext<'_>, negated: bool, out: &mut Vec<Finding>) {
    match e {
        Expr::And(v) if !negated => {
            if let Some(c) = v.iter().find(|c| !eval(c, cx)) {
                explain(c, cx, negated, out);
            }
        }
        Expr::Or(v) if negated => {
            if let Some(c) = v.iter().find(|c| eval(c, cx)) {
                explain(c, cx, negated, out);
            }
        }
        Expr::And(v) | Expr::Or(v) => v.iter().for_each(|c| explain(c, cx, negated, out)),
        Expr::Not(inner) => explain(inner, cx, !negated, out),
        Expr::Leaf(l) => {
            let (a, b) = l.axes();
            let axes = std::iter::once(a)
                .chain(b)
                .filter_map(|i| {
                    let m = cx.axes.get(i)?;
                    Some((
                        m.name.clone(),
                        cx.positions.get(i).copied().unwrap_or(f64::NAN),
                        cx.reaches.get(i).copied().unwrap_or_default(),
                    ))
                })
                .collect();
            out.push(Finding {
                condition: Canonical { expr: e, axes: cx.axes }.to_string(),
                margin: margin(l, cx),
                negated,
                axes,
            });
        }
    }
}
