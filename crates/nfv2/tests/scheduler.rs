//! The bus scheduler against two simulated 1209A served in process on virtual time: the
//! warning for a physically impossible cycle (the source's 2 ms at 57600 Bd) and the
//! achieved cycle at the wire limit, one packed frame per slave per cycle against the
//! unpacked mode, raw frames between cycles, and a missing slave (missed samples counted,
//! a communication fault, the others unaffected). On virtual time the cycle figures are
//! exact: they are asserted tightly.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::*;
use motus_nfv2::{DriveConfig, Packing, Scheduler, SchedulerConfig};
use motus_nfv2_protocol::{Command, CommandCode as C, Frame};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// A minimal tracing subscriber keeping the WARN messages.
#[derive(Clone, Default)]
struct Warnings(Arc<Mutex<Vec<String>>>);

struct Message<'a>(&'a mut String);

impl tracing::field::Visit for Message<'_> {
    fn record_debug(&mut self, _field: &tracing::field::Field, value: &dyn std::fmt::Debug) {
        self.0.push_str(&format!("{value:?}"));
    }
}

impl tracing::Subscriber for Warnings {
    fn enabled(&self, metadata: &tracing::Metadata<'_>) -> bool {
        *metadata.level() <= tracing::Level::WARN
    }
    fn new_span(&self, _: &tracing::span::Attributes<'_>) -> tracing::span::Id {
        tracing::span::Id::from_u64(1)
    }
    fn record(&self, _: &tracing::span::Id, _: &tracing::span::Record<'_>) {}
    fn record_follows_from(&self, _: &tracing::span::Id, _: &tracing::span::Id) {}
    fn event(&self, event: &tracing::Event<'_>) {
        let mut text = String::new();
        event.record(&mut Message(&mut text));
        self.0.lock().unwrap().push(text);
    }
    fn enter(&self, _: &tracing::span::Id) {}
    fn exit(&self, _: &tracing::span::Id) {}
}

#[test]
fn an_impossible_cycle_is_warned_and_runs_at_the_wire_limit() {
    let sim = Sim::start(paced());
    let config = SchedulerConfig { cycle: Duration::from_millis(2), ..SchedulerConfig::default() };
    let warnings = Warnings::default();
    let sched = tracing::subscriber::with_default(warnings.clone(), || {
        Scheduler::start(
            sim.bus(Duration::from_millis(3)),
            vec![DriveConfig::new(1), DriveConfig::new(2)],
            config,
        )
        .unwrap()
    });
    let plan = sched.plan().clone();
    assert!(!plan.feasible);
    // Per slave 15 B request (position set-point, two queries) and 15 B answer at 57600 Bd
    // plus 0.2 ms turnaround: 5.41 ms, 10.82 ms for two.
    assert_eq!(plan.min_cycle.as_micros(), 10_816);
    let logged = warnings.0.lock().unwrap().clone();
    assert!(
        logged.iter().any(|w| w.contains("physically impossible") && w.contains("10.817 ms")),
        "{logged:?}"
    );
    sim.sleep(Duration::from_millis(200));
    sched.reset_stats();
    sim.sleep(Duration::from_secs(2));
    let stats = sched.stats();
    eprintln!("{plan}\n{stats}");
    assert!(!stats.feasible && stats.cycles > 100, "{stats}");
    // It runs at the wire limit, on its grid: every cycle takes exactly the computed
    // minimum. (The drives hold no set-point here, so their frames carry only queries and
    // fit in it with room to spare: the current and inputs queries of every tenth and
    // fiftieth cycle fit too.)
    assert_eq!(plan.effective_cycle(), plan.min_cycle);
    assert_eq!((stats.p99, stats.max), (plan.min_cycle, plan.min_cycle), "{stats}");
    assert!(stats.mean.abs_diff(plan.min_cycle) < Duration::from_micros(1), "{stats}");
    assert_eq!((stats.missed_answers, stats.overruns), (0, 0), "{stats}");
    assert!(stats.utilisation > 0.75, "{stats}");
    for d in sched.drives() {
        assert!(d.samples().len() > 100);
    }
}

#[test]
fn unpacked_mode_sends_one_command_per_frame() {
    let sim = Sim::start(paced());
    let config = SchedulerConfig {
        cycle: Duration::from_millis(25),
        packing: Packing::Unpacked,
        current_every: 0,
        inputs_every: 0,
        ..SchedulerConfig::default()
    };
    let sched = Scheduler::start(
        sim.bus(Duration::from_millis(3)),
        vec![DriveConfig::new(1), DriveConfig::new(2)],
        config,
    )
    .unwrap();
    // Per slave: 11 B set-point without answer, 7 + 11 B position, 7 + 9 B status.
    assert_eq!(sched.plan().bytes_per_cycle(), 2 * 45);
    assert!(sched.plan().feasible);
    let drive = sched.drive(1).unwrap();
    drive.enable().unwrap();
    drive.move_to(3_000, Some(2_000), None).unwrap();
    let s = drive.wait_idle(Duration::from_secs(3)).unwrap();
    assert!((s.position.unwrap().counts - 3_000).abs() <= 5, "{s:?}");
    assert!((sim.with(1, |c| c.true_state().counter) - 3_000).abs() <= 5);
    sched.reset_stats();
    sim.sleep(Duration::from_millis(500));
    let stats = sched.stats();
    // Drive 1 holds a position (set-point + 2 queries = 3 frames a cycle), drive 2 is idle
    // (2 query frames a cycle).
    let per_cycle = |i: usize| stats.slaves[i].exchanges as f64 / stats.cycles as f64;
    assert!((per_cycle(0) - 3.0).abs() < 0.2 && (per_cycle(1) - 2.0).abs() < 0.2, "{stats:?}");
    assert_eq!(stats.missed_answers, 0, "{stats}");
    assert_eq!((stats.mean, stats.max), (Duration::from_millis(25), Duration::from_millis(25)), "{stats}");
}

#[test]
fn raw_frames_go_between_cycles() {
    let sim = Sim::start(two_controllers());
    let sched = Scheduler::start(
        sim.bus(Duration::from_millis(3)),
        vec![DriveConfig::new(1), DriveConfig::new(2)],
        fast_scheduler(),
    )
    .unwrap();
    let query = Frame { address: 2, commands: vec![Command::query(C::ReadDeviceVitals)] };
    let answer = sched.transact(&query).unwrap().unwrap();
    let vitals = answer.int_values(C::ReadDeviceVitals).unwrap();
    assert_eq!(vitals.len(), 4);
    assert!((vitals[0] - 24_000).abs() < 100, "{vitals:?}");
    // A frame of set-points gets no answer.
    let outputs = Frame { address: 1, commands: vec![Command::values(C::SetDigitalOutputs, [0b101])] };
    assert_eq!(sched.transact(&outputs).unwrap(), None);
    assert!(sim.eventually(Duration::from_secs(1), || sim.with(1, |c| c.digital_outputs()) == 0b101));
    // Both went between cycles: the cycle kept its grid.
    let stats = sched.stats();
    assert_eq!((stats.missed_answers, stats.overruns), (0, 0), "{stats}");
}

#[test]
fn a_missing_slave_is_counted_and_reported_without_harm_to_the_others() {
    let sim = Sim::start(two_controllers());
    let drives = vec![DriveConfig::new(1), DriveConfig::new(3), DriveConfig::new(2)];
    let config = SchedulerConfig { cycle: Duration::from_millis(30), ..SchedulerConfig::default() };
    let sched = Scheduler::start(sim.bus(Duration::from_millis(3)), drives, config).unwrap();
    sim.sleep(Duration::from_millis(800));
    let stats = sched.stats();
    let missing = stats.slaves.iter().find(|s| s.address == 3).unwrap();
    assert!(missing.missed > 10 && missing.answers == 0, "{stats:?}");
    let ghost = sched.drive(3).unwrap().snapshot();
    assert!(ghost.faults.iter().any(|f| f.reason.contains("no valid answer")), "{ghost:?}");
    for a in [1, 2] {
        let s = stats.slaves.iter().find(|s| s.address == a).unwrap();
        assert!(s.missed == 0 && s.answers > 10, "{stats:?}");
        assert!(sched.drive(a).unwrap().snapshot().faults.is_empty());
    }
    // The missing slave's time-outs fit in the cycle: it keeps its grid exactly.
    assert!(stats.feasible && stats.overruns == 0, "{stats}");
    assert_eq!((stats.mean, stats.max), (Duration::from_millis(30), Duration::from_millis(30)), "{stats}");
}
