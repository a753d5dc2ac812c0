#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! Quick-stop fan-out over axes of the axis model and other targets.

use motus_axis::{Axis, AxisCommand, AxisError, AxisState, Capabilities, Scale};
use motus_safety::*;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// An axis that records the commands it receives (a real driver maps QuickStop to its
/// protocol: tested in the driver crates).
struct RecordingAxis {
    name: String,
    log: Arc<Mutex<Vec<String>>>,
    fail: bool,
    scale: Scale,
}

impl Axis for RecordingAxis {
    fn name(&self) -> &str {
        &self.name
    }
    fn capabilities(&self) -> Capabilities {
        Capabilities::default()
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
            flags: Default::default(),
            faults: Vec::new(),
        })
    }
    fn execute(&mut self, command: &AxisCommand) -> Result<(), AxisError> {
        self.log.lock().unwrap().push(format!("{} {}", self.name, command.name()));
        if self.fail {
            Err(AxisError::Timeout {
                axis: self.name.clone(),
                timeout: Duration::from_millis(20),
                attempts: 3,
                detail: String::new(),
            })
        } else {
            Ok(())
        }
    }
}

fn samples(pos: [f64; 5], cycle: u64) -> Vec<Option<Sample>> {
    pos.iter().map(|p| Some(Sample { position: *p, speed: 0.0, cycle, homed: true })).collect()
}

const SAFE: [f64; 5] = [-500.0, 1000.0, -500.0, 10_000.0, -7100.0];
const BEYOND: [f64; 5] = [-500.0, 1000.0, -500.0, 10_000.0, 3500.0];

fn decide(s: &mut Supervisor, pos: [f64; 5], cycle: u64) -> Decision {
    let smp = samples(pos, cycle);
    let input = CycleInput {
        now: Duration::from_micros(400 * cycle),
        cycle,
        mode: Mode::Normal,
        samples: &smp,
        params_ok: true,
    };
    s.evaluate(&input).clone()
}

#[test]
fn every_axis_stops_once_when_safe_to_run_falls_even_if_one_fails() {
    let log = Arc::new(Mutex::new(Vec::new()));
    let axis = |name: &str, fail| {
        Box::new(AxisStop(RecordingAxis {
            name: name.into(),
            log: Arc::clone(&log),
            fail,
            scale: Scale::HUNDREDTH_MM,
        })) as Box<dyn StopTarget>
    };
    let mut fanout = Fanout::new(vec![axis("cia402#2", false), axis("ps1a#1", true), axis("nfv2#3", false)])
        .with_restart(Restart::Automatic);
    let mut sup = Supervisor::new(RuleSet::from_toml(JUGGLER_TOML).unwrap());
    let r = fanout.apply(&decide(&mut sup, SAFE, 1));
    assert!(!r.stopped && r.renewed == 3 && fanout.running());
    let r = fanout.apply(&decide(&mut sup, BEYOND, 2));
    assert!(r.stopped);
    assert_eq!(r.errors.len(), 1, "the failing axis is reported");
    assert_eq!(r.errors[0].target, "ps1a#1");
    assert_eq!(
        *log.lock().unwrap(),
        ["cia402#2 quick-stop", "ps1a#1 quick-stop", "nfv2#3 quick-stop"],
        "the failing axis did not keep the next one from stopping"
    );
    // Still unsafe: no repeated stop commands.
    let r = fanout.apply(&decide(&mut sup, BEYOND, 3));
    assert!(!r.stopped);
    assert_eq!(log.lock().unwrap().len(), 3);
    assert_eq!(fanout.stops(), 1);
}

#[test]
fn expired_lease_stops_without_a_new_decision() {
    let log = Arc::new(Mutex::new(Vec::new()));
    let target = Box::new(AxisStop(RecordingAxis {
        name: "a".into(),
        log: Arc::clone(&log),
        fail: false,
        scale: Scale::HUNDREDTH_MM,
    }));
    let mut fanout = Fanout::new(vec![target]);
    let mut sup = Supervisor::new(RuleSet::from_toml(JUGGLER_TOML).unwrap());
    // Decision at cycle 10 (t = 4 ms): lease 0.8 ms -> expires at 4.8 ms.
    fanout.apply(&decide(&mut sup, SAFE, 10));
    assert!(!fanout.check_expiry(Duration::from_micros(4799)).stopped);
    assert!(log.lock().unwrap().is_empty());
    assert!(fanout.check_expiry(Duration::from_micros(4800)).stopped);
    assert_eq!(*log.lock().unwrap(), ["a quick-stop"]);
    assert!(!fanout.check_expiry(Duration::from_micros(9000)).stopped, "stopped once");
}

#[test]
fn first_decision_unsafe_stops_drives_that_may_be_moving() {
    let log = Arc::new(Mutex::new(Vec::new()));
    let target = Box::new(AxisStop(RecordingAxis {
        name: "a".into(),
        log: Arc::clone(&log),
        fail: false,
        scale: Scale::HUNDREDTH_MM,
    }));
    let mut fanout = Fanout::new(vec![target]);
    let mut sup = Supervisor::new(RuleSet::from_toml(JUGGLER_TOML).unwrap());
    assert!(fanout.apply(&decide(&mut sup, BEYOND, 1)).stopped);
    assert_eq!(log.lock().unwrap().len(), 1);
}

#[test]
fn after_a_stop_the_drives_stay_stopped_until_the_operator_resets() {
    let log = Arc::new(Mutex::new(Vec::new()));
    let target = Box::new(AxisStop(RecordingAxis {
        name: "a".into(),
        log: Arc::clone(&log),
        fail: false,
        scale: Scale::HUNDREDTH_MM,
    }));
    let mut fanout = Fanout::new(vec![target]);
    let mut sup = Supervisor::new(RuleSet::from_toml(JUGGLER_TOML).unwrap());
    assert_eq!(fanout.apply(&decide(&mut sup, SAFE, 1)).renewed, 1);
    assert!(fanout.apply(&decide(&mut sup, BEYOND, 2)).stopped);
    // Safe again: no renewal (the drives' leases run out), until the reset.
    let r = fanout.apply(&decide(&mut sup, SAFE, 3));
    assert_eq!((r.renewed, r.stopped), (0, false));
    assert!(fanout.held() && !fanout.running());
    fanout.reset();
    assert_eq!(fanout.apply(&decide(&mut sup, SAFE, 4)).renewed, 1);
    assert!(fanout.running());
}
