//! [`ProgramService`]: one program at a time on a thread, in real time, with hold, resume
//! (cycle start), stop, feed override, single block, MDI, the executed path and a status
//! snapshot for the station and its HMI.
//!
//! Each run is checked completely before it starts (an invalid program never moves an
//! axis), then stepped every [`CYCLE`] against the drilling technology on the simulated
//! machine; each set-point goes to the optional sink (the station's gantry axes), and a
//! sink that fails stops the run. The check runs on the service's thread, never in the
//! caller ([`ProgramService::run`]); a program its caller has checked already starts at
//! once ([`ProgramService::run_checked`]). A run starts where the machine is (`start`), or
//! where the last run ended. Override and single block are the service's settings: they
//! apply to the running program at once and to every later run.

use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_cnc_planner::Setpoint;
use motus_gcode::{Interpreter, InterpreterConfig};
use serde::Serialize;

use crate::executed::{ExecutedPath, PathBatch};
use crate::runner::{Limits3, ProgramRun, RunStatus};
use crate::technology::DrillingTechnology;
use crate::AXES;

/// Cycle of the service's executor.
pub const CYCLE: Duration = Duration::from_millis(1);

/// Where a program run is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ServiceState {
    /// Nothing running.
    Idle,
    /// Running (moving, dwelling or waiting for the technology).
    Running,
    /// Feed hold.
    Held,
    /// Single block: stopped after a block, waiting for cycle start ([`ProgramService::resume`]).
    BlockStop,
    /// Finished.
    Done,
    /// Stopped by a user or an error.
    Stopped,
}

/// A snapshot of the service.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ServiceStatus {
    /// State.
    pub state: ServiceState,
    /// Name of the program run last.
    pub program: Option<String>,
    /// Progress 0..=1 (by line).
    pub progress: f64,
    /// Current 1-based line.
    pub line: u32,
    /// Its text.
    pub line_text: String,
    /// Why it stopped (error or user).
    pub message: Option<String>,
    /// Tool position X, Y, Z (mm).
    pub xyz: [f64; AXES],
    /// Holes drilled in this run.
    pub holes: usize,
    /// The drilling technology's state.
    pub technology: String,
    /// Feed override, percent.
    pub override_percent: f64,
    /// Single-block mode.
    pub single_block: bool,
    /// Executed path speed, mm/min (with the override).
    pub feed: f64,
}

impl Default for ServiceStatus {
    fn default() -> Self {
        Self {
            state: ServiceState::Idle,
            program: None,
            progress: 0.0,
            line: 0,
            line_text: String::new(),
            message: None,
            xyz: [0.0; AXES],
            holes: 0,
            technology: "Idle".into(),
            override_percent: 100.0,
            single_block: false,
            feed: 0.0,
        }
    }
}

enum Cmd {
    Run { name: String, src: String, checked: bool, start: Option<[f64; AXES]> },
    Override(f64),
    SingleBlock(bool),
    Hold,
    Resume,
    Stop,
    Quit,
}

/// Receives every set-point of a run (e.g. to move the station's axes); an error stops the
/// run with its message (on doubt about motion, stop).
pub type SetpointSink = Box<dyn FnMut(&Setpoint<AXES>) -> Result<(), String> + Send>;

/// Reads a [`ProgramService`]'s status from another thread.
#[derive(Clone)]
pub struct StatusReader(Arc<Mutex<ServiceStatus>>);

impl StatusReader {
    /// The executed path speed, mm/min (0 at rest).
    pub fn feed(&self) -> f64 {
        self.0.lock().unwrap_or_else(PoisonError::into_inner).feed
    }
}

/// A feed override outside 0..=200 %.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("feed override {0} % is outside 0..=200 %")]
pub struct OverrideError(pub f64);

/// The program service (see the module documentation).
pub struct ProgramService {
    tx: Sender<Cmd>,
    status: Arc<Mutex<ServiceStatus>>,
    path: Arc<Mutex<ExecutedPath>>,
    thread: Option<JoinHandle<()>>,
}

impl ProgramService {
    /// Starts the service thread.
    pub fn start(
        limits: Limits3,
        config: InterpreterConfig,
        sink: Option<SetpointSink>,
    ) -> std::io::Result<Self> {
        let (tx, rx) = mpsc::channel();
        let status = Arc::new(Mutex::new(ServiceStatus::default()));
        let path = Arc::new(Mutex::new(ExecutedPath::default()));
        let shared = Shared { status: Arc::clone(&status), path: Arc::clone(&path) };
        let thread = std::thread::Builder::new()
            .name("motus-cnc".into())
            .spawn(move || service_loop(&rx, &shared, limits, config, sink))?;
        Ok(Self { tx, status, path, thread: Some(thread) })
    }

    /// Runs `src` after the last run ends: the service's thread first checks it completely
    /// (with the service's [`InterpreterConfig`], so its step limit and cancel flag bound
    /// the check) and ends the run [`ServiceState::Stopped`] with the error, without moving,
    /// if it is invalid. Returns at once; the status says `Running` from now on.
    pub fn run(&self, name: &str, src: &str) {
        self.send_run(name, src, false, None);
    }

    /// Runs `src`, which the caller has checked completely with the same interpreter
    /// settings (e.g. the station's bounded program checker): it starts at once. Should
    /// an error appear anyway, the path stops within the limits before the invalid line.
    pub fn run_checked(&self, name: &str, src: &str) {
        self.send_run(name, src, true, None);
    }

    /// [`ProgramService::run_checked`] from `start` (X, Y, Z in mm: where the machine's axes
    /// are), not from where the last run ended.
    pub fn run_checked_from(&self, name: &str, src: &str, start: [f64; AXES]) {
        self.send_run(name, src, true, Some(start));
    }

    fn send_run(&self, name: &str, src: &str, checked: bool, start: Option<[f64; AXES]>) {
        set(&self.status, |s| {
            *s = ServiceStatus {
                state: ServiceState::Running,
                program: Some(name.to_owned()),
                xyz: start.unwrap_or(s.xyz),
                override_percent: s.override_percent,
                single_block: s.single_block,
                ..ServiceStatus::default()
            }
        });
        let _ = self.tx.send(Cmd::Run { name: name.into(), src: src.into(), checked, start });
    }

    /// Feed override in percent (0..=200), now and for later runs.
    ///
    /// # Errors
    /// [`OverrideError`] outside 0..=200 (nothing changes).
    pub fn set_override(&self, percent: f64) -> Result<(), OverrideError> {
        if !(0.0..=200.0).contains(&percent) {
            return Err(OverrideError(percent));
        }
        set(&self.status, |s| s.override_percent = percent);
        let _ = self.tx.send(Cmd::Override(percent));
        Ok(())
    }

    /// Single-block mode, now and for later runs: the path stops after each block until
    /// [`ProgramService::resume`] (cycle start).
    pub fn set_single_block(&self, on: bool) {
        set(&self.status, |s| s.single_block = on);
        let _ = self.tx.send(Cmd::SingleBlock(on));
    }

    /// The executed path of run `run` from `cursor` on (see [`ExecutedPath::since`]).
    pub fn executed_path(&self, run: u64, cursor: u64) -> PathBatch {
        self.path.lock().unwrap_or_else(PoisonError::into_inner).since(run, cursor)
    }

    /// Feed hold.
    pub fn hold(&self) {
        let _ = self.tx.send(Cmd::Hold);
    }

    /// Resume after a hold, or cycle start after a single-block stop.
    pub fn resume(&self) {
        let _ = self.tx.send(Cmd::Resume);
    }

    /// Stop (decelerate within the limits, end the run).
    pub fn stop(&self) {
        let _ = self.tx.send(Cmd::Stop);
    }

    /// The latest status.
    pub fn status(&self) -> ServiceStatus {
        self.status.lock().unwrap_or_else(PoisonError::into_inner).clone()
    }

    /// A reader of the status for another thread (e.g. a poller tracing the feed).
    pub fn status_reader(&self) -> StatusReader {
        StatusReader(Arc::clone(&self.status))
    }
}

impl Drop for ProgramService {
    fn drop(&mut self) {
        let _ = self.tx.send(Cmd::Quit);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn set(status: &Mutex<ServiceStatus>, f: impl FnOnce(&mut ServiceStatus)) {
    f(&mut status.lock().unwrap_or_else(PoisonError::into_inner));
}

/// What the service's thread shares with its handle.
struct Shared {
    status: Arc<Mutex<ServiceStatus>>,
    path: Arc<Mutex<ExecutedPath>>,
}

fn service_loop(
    rx: &Receiver<Cmd>,
    shared: &Shared,
    limits: Limits3,
    config: InterpreterConfig,
    mut sink: Option<SetpointSink>,
) {
    let status = &*shared.status;
    let mut position = [0.0; AXES];
    let (mut override_percent, mut single_block) = (100.0, false);
    loop {
        let (name, src, checked) = match rx.recv() {
            Ok(Cmd::Run { name, src, checked, start }) => {
                position = start.unwrap_or(position);
                (name, src, checked)
            }
            Ok(Cmd::Override(p)) => {
                override_percent = p;
                continue;
            }
            Ok(Cmd::SingleBlock(on)) => {
                single_block = on;
                continue;
            }
            Ok(Cmd::Quit) | Err(_) => return,
            Ok(_) => continue,
        };
        let mut cfg = config.clone();
        cfg.require_program_end = false;
        if !checked {
            // The whole program, streamed (no list of calls kept), before anything moves.
            if let Some(Err(e)) = Interpreter::with_config(&src, cfg.clone()).find(Result::is_err) {
                set(status, |s| {
                    s.state = ServiceState::Stopped;
                    s.message = Some(e.to_string());
                });
                continue;
            }
        }
        let lines: Vec<&str> = src.lines().collect();
        let mut run = match ProgramRun::new(&src, cfg, limits, position) {
            Ok(r) => r,
            Err(e) => {
                set(status, |s| {
                    s.state = ServiceState::Stopped;
                    s.message = Some(e.to_string());
                });
                continue;
            }
        };
        let mut tech = DrillingTechnology::simulated();
        let _ = run.set_override(override_percent);
        run.set_single_block(single_block);
        shared.path.lock().unwrap_or_else(PoisonError::into_inner).restart(position);
        set(status, |s| {
            *s = ServiceStatus {
                state: ServiceState::Running,
                program: Some(name.clone()),
                xyz: position,
                override_percent,
                single_block,
                ..ServiceStatus::default()
            }
        });
        let mut next = Instant::now();
        let mut user_stop = false;
        loop {
            match rx.try_recv() {
                Ok(Cmd::Hold) => run.feed_hold(),
                Ok(Cmd::Resume) => {
                    let _ = run.resume();
                }
                Ok(Cmd::Stop) => {
                    run.stop();
                    user_stop = true;
                }
                Ok(Cmd::Override(p)) => {
                    if run.set_override(p).is_ok() {
                        override_percent = p;
                    }
                }
                Ok(Cmd::SingleBlock(on)) => {
                    single_block = on;
                    run.set_single_block(on);
                }
                Ok(Cmd::Quit) => return,
                Ok(Cmd::Run { .. }) | Err(_) => {}
            }
            let step = run.step(CYCLE.as_secs_f64(), &mut tech);
            let (sp, st) = match step {
                Ok(x) => x,
                Err(e) => {
                    set(status, |s| {
                        s.state = ServiceState::Stopped;
                        s.message = Some(e.to_string());
                    });
                    break;
                }
            };
            position = sp.positions;
            if let Some(Err(e)) = sink.as_mut().map(|f| f(&sp)) {
                // The machine did not take the set-point: stop the path (and the sink's
                // axes stop on their own error); the run ends with why.
                run.stop();
                set(status, |s| {
                    s.state = ServiceState::Stopped;
                    s.message = Some(e);
                    s.feed = 0.0;
                });
                break;
            }
            let report = run.report();
            let state = match st {
                RunStatus::Done => ServiceState::Done,
                RunStatus::Held => ServiceState::Held,
                RunStatus::BlockStop => ServiceState::BlockStop,
                RunStatus::Stopped if sp.path_speed == 0.0 => ServiceState::Stopped,
                _ => ServiceState::Running,
            };
            let end = matches!(state, ServiceState::Done | ServiceState::Stopped);
            shared.path.lock().unwrap_or_else(PoisonError::into_inner).record(sp.positions, end);
            set(status, |s| {
                s.state = state;
                s.progress = if state == ServiceState::Done { 1.0 } else { report.progress() };
                s.line = report.line;
                s.line_text = lines
                    .get(report.line.saturating_sub(1) as usize)
                    .map(|l| l.to_string())
                    .unwrap_or_default();
                s.xyz = sp.positions;
                s.holes = tech.holes().len();
                s.technology = tech.info().state.name().to_string();
                s.override_percent = override_percent;
                s.single_block = single_block;
                s.feed = sp.path_speed * 60.0;
                if state == ServiceState::Stopped && user_stop {
                    s.message = Some("stopped by the operator".into());
                }
            });
            if matches!(state, ServiceState::Done | ServiceState::Stopped) {
                break;
            }
            next += CYCLE;
            let now = Instant::now();
            if next > now {
                std::thread::sleep(next - now);
            } else {
                next = now; // late: never queue cycles
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::panic)]
    use super::*;

    /// The status once `done` holds for it, or the last one after `secs` (liveness).
    fn wait_for(svc: &ProgramService, secs: u64, done: impl Fn(&ServiceStatus) -> bool) -> ServiceStatus {
        let end = Instant::now() + Duration::from_secs(secs);
        loop {
            let s = svc.status();
            if done(&s) || Instant::now() > end {
                return s;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    fn wait(svc: &ProgramService, want: ServiceState, secs: u64) -> ServiceStatus {
        let end = Instant::now() + Duration::from_secs(secs);
        loop {
            let s = svc.status();
            if s.state == want || Instant::now() > end {
                return s;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    #[test]
    fn runs_holds_resumes_and_stops_in_real_time() {
        let svc = ProgramService::start(Limits3::default(), InterpreterConfig::default(), None).unwrap();
        // Zero feed on line 2, after a move: refused before anything moves.
        svc.run("bad", "G0 X5\nG1 X10\n");
        let bad = wait(&svc, ServiceState::Stopped, 5);
        assert_eq!(bad.state, ServiceState::Stopped, "{bad:?}");
        assert!(bad.message.as_deref().unwrap_or("").starts_with("2:"), "{bad:?}");
        assert_eq!(bad.xyz, [0.0; AXES], "nothing moved");
        svc.run("sq", "G21 G90 F3000\nG1 X20\nG1 Y20\nG1 X0\nG1 Y0\nM2\n");
        std::thread::sleep(Duration::from_millis(150));
        svc.hold();
        let held = wait(&svc, ServiceState::Held, 2);
        assert_eq!(held.state, ServiceState::Held, "{held:?}");
        std::thread::sleep(Duration::from_millis(300));
        let still = svc.status();
        assert_eq!(still.xyz, wait(&svc, ServiceState::Held, 1).xyz, "at rest while held");
        svc.resume();
        let done = wait(&svc, ServiceState::Done, 10);
        assert_eq!(done.state, ServiceState::Done, "{done:?}");
        assert!((done.progress - 1.0).abs() < 1e-9);
        svc.run_checked("again", "G21 G90 F3000\nG1 X50\nG1 X0\nM2\n");
        std::thread::sleep(Duration::from_millis(100));
        svc.stop();
        let stopped = wait(&svc, ServiceState::Stopped, 3);
        assert_eq!(stopped.state, ServiceState::Stopped, "{stopped:?}");
    }

    #[test]
    fn override_single_block_start_position_and_executed_path() {
        let svc = ProgramService::start(Limits3::default(), InterpreterConfig::default(), None).unwrap();
        assert_eq!(svc.set_override(250.0), Err(OverrideError(250.0)));
        assert_eq!(svc.status().override_percent, 100.0, "a refused override changes nothing");
        // 600 mm/min on a long line: the executed feed follows the override.
        svc.run_checked_from("feed", "G21 G90 F600\nG1 X100\nM2\n", [10.0, 0.0, 0.0]);
        let at_100 = wait_for(&svc, 5, |s| (s.feed - 600.0).abs() < 1.0);
        assert!((at_100.feed - 600.0).abs() < 1.0, "{at_100:?}");
        svc.set_override(50.0).unwrap();
        let at_50 = wait_for(&svc, 5, |s| (s.feed - 300.0).abs() < 1.0);
        assert!((at_50.feed - 300.0).abs() < 1.0, "{at_50:?}");
        assert_eq!(at_50.override_percent, 50.0);
        // On 2 mm along the line (at least ten points of the executed path), then stop.
        wait_for(&svc, 5, |s| s.xyz[0] > 12.0);
        svc.stop();
        let stopped = wait(&svc, ServiceState::Stopped, 3);
        let path = svc.executed_path(0, 0);
        assert_eq!(path.points.first(), Some(&[10.0, 0.0, 0.0]), "the run started where it was told");
        let last = path.points.last().copied().unwrap();
        assert!((last[0] - stopped.xyz[0]).abs() < 1e-9 && path.points.len() > 10, "{path:?}");
        // Single block: a stop after each block, cycle start for the next.
        svc.set_override(100.0).unwrap();
        svc.set_single_block(true);
        svc.run_checked("blocks", "G21 G90 F3000\nG1 X20\nG1 Y20\nM2\n");
        let first = wait(&svc, ServiceState::BlockStop, 5);
        assert_eq!(first.state, ServiceState::BlockStop, "{first:?}");
        std::thread::sleep(Duration::from_millis(200));
        assert_eq!(svc.status().state, ServiceState::BlockStop, "it waits for cycle start");
        let at = svc.status().xyz;
        svc.resume();
        std::thread::sleep(Duration::from_millis(50));
        let second = wait(&svc, ServiceState::BlockStop, 5);
        assert_ne!(second.xyz, at, "cycle start ran the next block: {second:?}");
        svc.set_single_block(false);
        svc.resume();
        assert_eq!(wait(&svc, ServiceState::Done, 5).state, ServiceState::Done);
    }

    #[test]
    fn a_sink_that_fails_stops_the_run_with_its_message() {
        let mut sent = 0;
        let sink: SetpointSink = Box::new(move |_| {
            sent += 1;
            if sent > 50 {
                Err("axis x: drive fault".into())
            } else {
                Ok(())
            }
        });
        let svc =
            ProgramService::start(Limits3::default(), InterpreterConfig::default(), Some(sink)).unwrap();
        svc.run_checked("fault", "G21 G90 F600\nG1 X100\nM2\n");
        let s = wait(&svc, ServiceState::Stopped, 5);
        assert_eq!(s.state, ServiceState::Stopped, "{s:?}");
        assert_eq!(s.message.as_deref(), Some("axis x: drive fault"));
    }
}
