//! Streams set-points to real axes of the axis model ([`motus_axis::Axis`]).
//!
//! Each cycle, every mapped axis whose set-point moved gets a `MoveAbsolute` to the new
//! position with the set-point speed as the profile velocity and its CNC acceleration limit
//! as the profile acceleration, both converted to SI with the axis' factor (0.001 m per mm,
//! π/180 rad per degree); when the path comes to rest, the target is sent once more with
//! the axis's own speed (the last commands of a deceleration carry near-zero speeds). This suits drives that follow a stream of absolute targets
//! (position-increment or cyclic modes); the drive's own interpolation fills the cycle.

use crate::config::Config;
use crate::executor::Setpoint;
use motus_axis::{Axis, AxisCommand, AxisError, MotionProfile};
use thiserror::Error;

/// SI units per CNC unit for millimetres.
pub const METRES_PER_MM: f64 = 1e-3;
/// SI units per CNC unit for degrees.
pub const RADIANS_PER_DEGREE: f64 = std::f64::consts::PI / 180.0;

/// A command to a real axis failed.
#[derive(Debug, Error)]
pub enum SinkError {
    /// The axis refused or failed the command.
    #[error("CNC axis {index} ({name}): {source}")]
    Axis {
        /// CNC axis index.
        index: usize,
        /// The axis' name.
        name: String,
        /// What the axis said.
        source: AxisError,
    },
    /// The CNC axis index does not exist.
    #[error("CNC axis {0} does not exist")]
    Index(usize),
    /// Conversion factor not finite and positive.
    #[error("SI factor {0} must be finite and > 0")]
    Factor(f64),
}

struct Mapped {
    index: usize,
    axis: Box<dyn Axis>,
    si_per_unit: f64,
    last: Option<f64>,
    /// The last command sent was the one at rest (the axis's own profile).
    settled: bool,
}

/// A set of real axes fed from the executor's set-points.
pub struct AxisSink<const N: usize> {
    axes: Vec<Mapped>,
    acceleration: [f64; N],
    deadband: f64,
}

impl<const N: usize> AxisSink<N> {
    /// Empty sink; accelerations come from `cfg`. Targets that moved less than `deadband`
    /// CNC units since the last command are not re-sent.
    pub fn new(cfg: &Config<N>, deadband: f64) -> Self {
        Self { axes: Vec::new(), acceleration: cfg.axes.map(|l| l.acceleration), deadband: deadband.max(0.0) }
    }

    /// Maps CNC axis `index` to `axis`, with `si_per_unit` SI units per CNC unit.
    pub fn map(&mut self, index: usize, axis: Box<dyn Axis>, si_per_unit: f64) -> Result<(), SinkError> {
        if index >= N {
            return Err(SinkError::Index(index));
        }
        if !(si_per_unit.is_finite() && si_per_unit > 0.0) {
            return Err(SinkError::Factor(si_per_unit));
        }
        self.axes.push(Mapped { index, axis, si_per_unit, last: None, settled: false });
        Ok(())
    }

    /// Sends one set-point; returns how many commands went out.
    pub fn send(&mut self, sp: &Setpoint<N>) -> Result<usize, SinkError> {
        let mut sent = 0;
        for m in &mut self.axes {
            let (Some(p), Some(v), Some(a)) =
                (sp.positions.get(m.index), sp.velocities.get(m.index), self.acceleration.get(m.index))
            else {
                continue;
            };
            let k = m.si_per_unit;
            let speed = v.abs() * k;
            let at_rest = speed <= f64::EPSILON;
            // Unchanged targets are not re-sent, except once when the path comes to rest:
            // the commands of a deceleration carry ever smaller speeds, and the last one would
            // leave the axis crawling the last micrometres; at rest, the axis finishes at its
            // own speed.
            if m.last.is_some_and(|l| (l - p).abs() <= self.deadband) && (m.settled || !at_rest) {
                continue;
            }
            let command = AxisCommand::MoveAbsolute {
                target: p * k,
                profile: MotionProfile {
                    velocity: (!at_rest).then_some(speed),
                    acceleration: Some(a * k),
                    deceleration: Some(a * k),
                },
            };
            m.axis.execute(&command).map_err(|source| SinkError::Axis {
                index: m.index,
                name: m.axis.name().to_string(),
                source,
            })?;
            m.last = Some(*p);
            m.settled = at_rest;
            sent += 1;
        }
        Ok(sent)
    }

    /// Sends `Stop` to every mapped axis (all are tried; the first error is returned).
    pub fn stop_all(&mut self) -> Result<(), SinkError> {
        let mut first = None;
        for m in &mut self.axes {
            if let Err(source) = m.axis.execute(&AxisCommand::Stop) {
                first.get_or_insert(SinkError::Axis {
                    index: m.index,
                    name: m.axis.name().to_string(),
                    source,
                });
            }
            m.last = None;
            m.settled = false;
        }
        first.map_or(Ok(()), Err)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use crate::config::AxisLimits;
    use crate::executor::Executor;
    use crate::item::{PathItem, Segment};
    use motus_axis::{AxisFlags, AxisState, Capabilities, Scale};
    use std::sync::{Arc, Mutex};

    /// An axis that records the commands it gets.
    struct Recorder {
        name: String,
        log: Arc<Mutex<Vec<AxisCommand>>>,
        scale: Scale,
    }

    impl Axis for Recorder {
        fn name(&self) -> &str {
            &self.name
        }
        fn capabilities(&self) -> Capabilities {
            Capabilities::POSITIONING
        }
        fn scale(&self) -> &Scale {
            &self.scale
        }
        fn read_state(&mut self) -> Result<AxisState, AxisError> {
            Ok(AxisState {
                position: 0.0,
                position_raw: 0,
                velocity: None,
                current: None,
                following_error: None,
                flags: AxisFlags::default(),
                faults: Vec::new(),
            })
        }
        fn execute(&mut self, command: &AxisCommand) -> Result<(), AxisError> {
            self.log.lock().unwrap().push(command.clone());
            Ok(())
        }
    }

    #[test]
    fn streams_si_targets_with_profile_velocity() {
        let cfg = Config::new([
            AxisLimits { velocity: 200.0, acceleration: 2000.0 },
            AxisLimits { velocity: 150.0, acceleration: 1500.0 },
            AxisLimits { velocity: 50.0, acceleration: 500.0 },
        ]);
        let mut ex = Executor::new(cfg, [0.0; 3]).unwrap();
        ex.push(1, PathItem::Motion(Segment::Line { end: [10.0, 0.0, 0.0], feed: 50.0, rapid: false }))
            .unwrap();
        ex.finish();
        let log = Arc::new(Mutex::new(Vec::new()));
        let mut sink = AxisSink::new(&cfg, 1e-9);
        let x = Recorder { name: "x".into(), log: log.clone(), scale: Scale::HUNDREDTH_MM };
        sink.map(0, Box::new(x), METRES_PER_MM).unwrap();
        assert!(matches!(
            sink.map(
                3,
                Box::new(Recorder { name: "a".into(), log: log.clone(), scale: Scale::HUNDREDTH_MM }),
                1.0
            ),
            Err(SinkError::Index(3))
        ));
        let mut last = None;
        for _ in 0..1000 {
            let sp = ex.tick(0.001);
            sink.send(&sp).unwrap();
            last = Some(sp);
        }
        let last = last.unwrap();
        let log = log.lock().unwrap();
        // 10 mm at 50 mm/s with 2000 mm/s² ramps: 0.2 + 0.025 s, every cycle moves X.
        assert!(log.len() > 200 && log.len() < 260, "{}", log.len());
        match log.last().unwrap() {
            AxisCommand::MoveAbsolute { target, profile } => {
                assert!((target - 0.010).abs() < 1e-12); // 10 mm in metres
                assert_eq!(profile.acceleration, Some(2.0)); // 2000 mm/s² = 2 m/s²
                                                             // At rest: the target once more at the axis's own speed, not a crawl.
                assert_eq!(profile.velocity, None);
            }
            other => panic!("{other:?}"),
        }
        let settles = log
            .iter()
            .filter(|c| matches!(c, AxisCommand::MoveAbsolute { profile, .. } if profile.velocity.is_none()))
            .count();
        assert_eq!(settles, 1, "one settling command when the path comes to rest");
        let mid = &log[100];
        let AxisCommand::MoveAbsolute { profile, .. } = mid else { panic!() };
        assert!((profile.velocity.unwrap() - 0.050).abs() < 1e-9); // cruising at 50 mm/s
        assert_eq!(last.positions[0], 10.0);
    }
}
