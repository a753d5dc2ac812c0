//! [`ProgramService`]: one program at a time on a thread, in real time, with hold, resume,
//! stop and a status snapshot for the station and its HMI.
//!
//! Each run is checked completely before it starts (an invalid program never moves an
//! axis), then stepped every [`CYCLE`] against the drilling technology on the simulated
//! machine; each set-point goes to the optional sink (the station's gantry axes). The
//! check runs on the service's thread, never in the caller ([`ProgramService::run`]); a
//! program its caller has checked already starts at once ([`ProgramService::run_checked`]).

use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_cnc_planner::Setpoint;
use motus_gcode::{Interpreter, InterpreterConfig};
use serde::Serialize;

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
        }
    }
}

enum Cmd {
    Run { name: String, src: String, checked: bool },
    Hold,
    Resume,
    Stop,
    Quit,
}

/// Receives every set-point of a run (e.g. to move the station's axes).
pub type SetpointSink = Box<dyn FnMut(&Setpoint<AXES>) + Send>;

/// The program service (see the module documentation).
pub struct ProgramService {
    tx: Sender<Cmd>,
    status: Arc<Mutex<ServiceStatus>>,
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
        let shared = Arc::clone(&status);
        let thread = std::thread::Builder::new()
            .name("motus-cnc".into())
            .spawn(move || service_loop(&rx, &shared, limits, config, sink))?;
        Ok(Self { tx, status, thread: Some(thread) })
    }

    /// Runs `src` after the last run ends: the service's thread first checks it completely
    /// (with the service's [`InterpreterConfig`], so its step limit and cancel flag bound
    /// the check) and ends the run [`ServiceState::Stopped`] with the error, without moving,
    /// if it is invalid. Returns at once; the status says `Running` from now on.
    pub fn run(&self, name: &str, src: &str) {
        self.send_run(name, src, false);
    }

    /// Runs `src`, which the caller has checked completely with the same interpreter
    /// settings (e.g. the station's bounded program checker): it starts at once. Should
    /// an error appear anyway, the path stops within the limits before the invalid line.
    pub fn run_checked(&self, name: &str, src: &str) {
        self.send_run(name, src, true);
    }

    fn send_run(&self, name: &str, src: &str, checked: bool) {
        set(&self.status, |s| {
            *s = ServiceStatus {
                state: ServiceState::Running,
                program: Some(name.to_owned()),
                xyz: s.xyz,
                ..ServiceStatus::default()
            }
        });
        let _ = self.tx.send(Cmd::Run { name: name.into(), src: src.into(), checked });
    }

    /// Feed hold.
    pub fn hold(&self) {
        let _ = self.tx.send(Cmd::Hold);
    }

    /// Resume after a hold.
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

fn service_loop(
    rx: &Receiver<Cmd>,
    status: &Mutex<ServiceStatus>,
    limits: Limits3,
    config: InterpreterConfig,
    mut sink: Option<SetpointSink>,
) {
    let mut position = [0.0; AXES];
    loop {
        let (name, src, checked) = match rx.recv() {
            Ok(Cmd::Run { name, src, checked }) => (name, src, checked),
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
        set(status, |s| {
            *s = ServiceStatus {
                state: ServiceState::Running,
                program: Some(name.clone()),
                xyz: position,
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
            if let Some(f) = sink.as_mut() {
                f(&sp);
            }
            let report = run.report();
            let state = match st {
                RunStatus::Done => ServiceState::Done,
                RunStatus::Held => ServiceState::Held,
                RunStatus::Stopped if sp.path_speed == 0.0 => ServiceState::Stopped,
                _ => ServiceState::Running,
            };
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
}
