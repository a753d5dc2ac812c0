//! Runs the demo cell's task classes (1 ms, 10 ms, 20 ms, 100 ms) with stand-in tasks
//! that compute set-points for their group's axes and record position and velocity of
//! every axis into the trace recorder, then prints each class's start-lateness jitter
//! (p50/p99/max), execution time and CPU load.
//!
//! `cargo run --release -p motus-station --example jitter -- [seconds=10] [cell.toml]`
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use motus_station::alarm::MemoryAlarms;
use motus_station::config::{self, Cell};
use motus_station::scheduler::{CyclicTask, Scheduler, TaskClass, TaskError};
use motus_station::trace::{Recorder, SignalId};

/// A stand-in for a group's control cycle: a sine set-point per axis, recorded.
struct StandIn {
    name: String,
    recorder: Arc<Mutex<Recorder>>,
    epoch: Instant,
    signals: Vec<(SignalId, SignalId, f64)>,
}

impl CyclicTask for StandIn {
    fn name(&self) -> &str {
        &self.name
    }

    fn cycle(&mut self, now: Instant, _cycle: u64) -> Result<(), TaskError> {
        let t = now.duration_since(self.epoch);
        let ts = t.as_secs_f64();
        let mut rec = self.recorder.lock().map_err(|_| TaskError::new("poisoned"))?;
        for (k, (pos, vel, amp)) in self.signals.iter().enumerate() {
            let w = 1.0 + k as f64 * 0.1;
            rec.record(*pos, t, amp * (w * ts).sin()).map_err(|e| TaskError::new(e.to_string()))?;
            rec.record(*vel, t, amp * w * (w * ts).cos()).map_err(|e| TaskError::new(e.to_string()))?;
        }
        Ok(())
    }
}

fn build(cell: &Cell, recorder: &Arc<Mutex<Recorder>>, epoch: Instant) -> Vec<TaskClass> {
    let mut classes = Vec::new();
    for class in cell.task_classes() {
        let name = format!("{}ms", class.period.as_secs_f64() * 1000.0);
        let mut tc = TaskClass::new(name, class.period).with_overrun_limit(class.overrun_limit);
        for task in &class.tasks {
            let Some(t) = cell.tasks.iter().find(|t| &t.name == task) else { continue };
            // Motion tasks record their group's axes; other tasks get the first 4 axes.
            let axes: Vec<&config::AxisConfig> = match t.group.as_deref().and_then(|g| cell.group(g)) {
                Some(g) => g.axes.iter().filter_map(|a| cell.axis(a)).collect(),
                None => cell.axes.iter().take(4).collect(),
            };
            let mut rec = recorder.lock().unwrap();
            let signals = axes
                .iter()
                .map(|a| {
                    let p =
                        rec.register(&format!("{}.{}.position", t.name, a.name), a.unit.symbol()).unwrap();
                    let v = rec
                        .register(
                            &format!("{}.{}.velocity", t.name, a.name),
                            &format!("{}/s", a.unit.symbol()),
                        )
                        .unwrap();
                    (p, v, (a.limits.max - a.limits.min).min(10.0) / 2.0)
                })
                .collect();
            tc.add(Box::new(StandIn {
                name: t.name.clone(),
                recorder: Arc::clone(recorder),
                epoch,
                signals,
            }));
        }
        classes.push(tc);
    }
    classes
}

fn main() {
    let mut args = std::env::args().skip(1);
    let seconds: f64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(10.0);
    let path = args
        .next()
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/demo-cell.toml"));
    let cell = match config::load(&path) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    let recorder = Arc::new(Mutex::new(Recorder::new(20_000)));
    let epoch = Instant::now();
    let classes = build(&cell, &recorder, epoch);
    let alarms = Arc::new(MemoryAlarms::new());
    let sched = Scheduler::start(classes, alarms.clone()).unwrap();
    // Warm-up (first cycles fault in pages), then measure.
    std::thread::sleep(Duration::from_millis(500));
    sched.reset_stats(None).unwrap();
    std::thread::sleep(Duration::from_secs_f64(seconds));
    let stats = sched.stop();
    println!(
        "cell {} ({} signals recorded), {seconds} s:",
        path.display(),
        recorder.lock().unwrap().signals().len()
    );
    for s in &stats {
        println!("  {}", s.summary());
    }
    if let Some(fast) = stats.iter().find(|s| s.period == Duration::from_millis(1)) {
        println!(
            "1 kHz: jitter p50 {} us, p99 {} us, p99.9 {} us, max {} us; exec p99 {} us; CPU {:.1} %; overruns {}",
            fast.lateness.p50.as_micros(),
            fast.lateness.p99.as_micros(),
            fast.lateness.p999.as_micros(),
            fast.lateness.max.as_micros(),
            fast.execution.p99.as_micros(),
            fast.cpu_percent(),
            fast.overruns
        );
    }
    let raised = alarms.raised();
    println!("alarms raised: {}", raised.len());
    for a in raised {
        println!("  {:?} {}: {}", a.code, a.source, a.message);
    }
}
