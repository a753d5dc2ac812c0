//! The station's machine: what `motus serve` and `motus demo` put behind the web layer.
//!
//! [`StationMachine::start`] opens a cell ([`motus_cell::open_cell`]: simulators, drivers,
//! the juggler's supervisor), then runs four threads: a poller that reads every axis every
//! [`StationOptions::poll`] (the HMI's view, the traced signals, the robot's path), the jog
//! watchdog that stops every jog not renewed within [`jog::JOG_LEASE`] (the dead-man), the
//! device reconnection ([`motus_station::devices::Reconnector`]: a device that disconnects
//! is retried with back-off while its axes are faulted and stopped; nothing else stops), and
//! the CNC program service ([`motus_cnc::ProgramService`]). Uploaded programs are checked
//! on a small pool of checker threads with a bounded queue, within a time and a step budget
//! ([`ProgramCheckOptions`]; busy: refused at once), never on the web server's threads; a
//! check measures the path's extent, speed and acceleration per gantry axis, for the machine
//! travel and the student limits. It implements [`motus_station_web::MachineBackend`] in
//! [`backend`].

#![forbid(unsafe_code)]

pub mod alarms;
pub mod backend;
mod checker;
pub mod demo;
mod gantry;
pub mod jog;
mod poller;
mod preview;
mod programs;
mod quick_stop;
mod robot;
mod rules;
mod stops;
pub mod tasks;

use std::collections::VecDeque;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError, RwLock};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_axis::Axis;
use motus_cell::{open_cell, CellOptions, RunningCell};
use motus_station::alarm::{AlarmSink, MemoryAlarms};
use motus_station::config::Cell;
use motus_station::devices::{Backoff, FaultTable, Reconnector};
use motus_station_web::{AxisLimits, AxisView};
use thiserror::Error;

pub use checker::ProgramCheckOptions;

/// Back-off of the device reconnection: 100 ms doubling to 1 s, so a device whose link
/// came back (a restarted CAN hub: its own back-off is at most 2 s) is brought up again
/// within a few seconds.
pub const DEVICE_BACKOFF: Backoff =
    Backoff { initial: Duration::from_millis(100), max: Duration::from_secs(1) };

/// Logs a device event, one line per state change: a device that stays away is reported
/// once (its alarm says the rest), not at every attempt.
fn log_device_event(e: &motus_station::devices::DeviceEvent) {
    use motus_station::devices::DeviceEvent;
    match e {
        DeviceEvent::Connected { device, after_failures } => {
            tracing::info!(device = %device, after_failures, "device connected");
        }
        DeviceEvent::Lost { .. } => {} // the reconnector's own warning
        DeviceEvent::AttemptFailed { device, failures: 1, error, .. } => {
            tracing::warn!(device = %device, %error, "device cannot be reached; retrying with back-off");
        }
        DeviceEvent::AttemptFailed { device, failures, error, retry_in } => {
            tracing::debug!(device = %device, failures, %error, ?retry_in, "device still unreachable");
        }
    }
}

/// Why the station could not start.
#[derive(Debug, Error)]
pub enum StationError {
    /// The cell file is invalid (every problem, with file:line:col).
    #[error("{0}")]
    Config(String),
    /// The cell could not be opened.
    #[error("{0}")]
    Cell(#[from] motus_cell::CellError),
    /// A thread could not be started.
    #[error("starting a thread: {0}")]
    Thread(#[from] std::io::Error),
    /// The cyclic tasks could not start.
    #[error("cyclic tasks: {0}")]
    Tasks(#[from] tasks::TasksError),
}

/// The laboratory configuration of a cell: student limits (position range, speed,
/// acceleration) from each axis's `student` table and none for an axis without one, so
/// students cannot move it (fail closed); `secure_cookies` for a station served over HTTPS or
/// beyond loopback.
#[must_use]
pub fn lab_config(cell: &Cell, secure_cookies: bool) -> motus_lab::LabConfig {
    let mut config = motus_lab::LabConfig::default();
    for a in &cell.axes {
        let Some(s) = &a.student else { continue };
        config.student_limits.axes.insert(
            a.name.clone(),
            motus_lab::MotionLimits::with_range(
                s.max_velocity,
                s.max_acceleration,
                s.limits.min,
                s.limits.max,
            ),
        );
    }
    config.student_limits.default = None;
    config.sessions.cookie.secure = secure_cookies;
    config
}

/// Options of the station.
#[derive(Clone)]
pub struct StationOptions {
    /// How the cell runs (by default without `require_devices`: the station starts with
    /// absent devices and connects them when they appear).
    pub cell: CellOptions,
    /// Period of the axis poller (HMI view and traces).
    pub poll: Duration,
    /// External camera URL shown in the HMI.
    pub camera_url: Option<String>,
    /// Where the runtime's alarms go besides [`StationMachine::alarms`] (the station's
    /// [`alarms::LabAlarmSink`], so the HMI lists them).
    pub alarm_sink: Option<Arc<dyn AlarmSink>>,
    /// The program checker: workers, queue, time and step budgets.
    pub program_checks: ProgramCheckOptions,
}

impl std::fmt::Debug for StationOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StationOptions")
            .field("cell", &self.cell)
            .field("poll", &self.poll)
            .field("camera_url", &self.camera_url)
            .field("alarm_sink", &self.alarm_sink.is_some())
            .field("program_checks", &self.program_checks)
            .finish()
    }
}

impl Default for StationOptions {
    fn default() -> Self {
        Self {
            // The station starts with absent devices: they are marked disconnected (axes
            // faulted, an alarm) and connected by the reconnection when they appear.
            cell: CellOptions { require_devices: false, ..CellOptions::default() },
            poll: Duration::from_millis(50),
            camera_url: None,
            alarm_sink: None,
            program_checks: ProgramCheckOptions::default(),
        }
    }
}

/// One axis of the station.
pub(crate) struct AxisEntry {
    pub(crate) view: AxisView,
    pub(crate) axis: Mutex<Box<dyn Axis + Send>>,
}

/// Traced samples: one value per axis position, at the poller's period.
#[derive(Default)]
pub(crate) struct Samples {
    pub(crate) first: u64,
    pub(crate) rows: VecDeque<(f64, Vec<f64>)>,
}

/// Capacity of the sample ring (rows).
pub(crate) const SAMPLE_ROWS: usize = 4096;

/// State shared by the threads and the backend.
pub(crate) struct Shared {
    /// The running cell (simulators); behind a lock: it is not `Sync`.
    pub(crate) running: Mutex<RunningCell>,
    /// The validated configuration.
    pub(crate) config: Cell,
    /// The groups of the cell.
    pub(crate) groups: Vec<motus_cell::CellGroup>,
    /// The juggler, if the cell has one.
    pub(crate) juggler: Option<Arc<motus_cell::JugglerHandle>>,
    /// Limits of the supervised axes in the rules' units (name, min, max).
    pub(crate) rule_limits: RwLock<Vec<(String, f64, f64)>>,
    /// Fingerprint of the rules file at start.
    pub(crate) rules_fingerprint: RwLock<String>,
    pub(crate) axes: Vec<AxisEntry>,
    pub(crate) views: RwLock<Vec<AxisView>>,
    /// Axis parameters an administrator set through the API (narrower than the cell file's).
    pub(crate) overrides: RwLock<std::collections::HashMap<String, motus_station_web::AxisParameters>>,
    pub(crate) samples: Mutex<Samples>,
    /// The cyclic tasks' traces (full rate); the poller adds their latest values to its rows.
    pub(crate) recorder: std::sync::OnceLock<Arc<Mutex<motus_station::trace::Recorder>>>,
    pub(crate) robot_path: Mutex<VecDeque<[f64; 2]>>,
    /// The omni group's pose estimate (wheel odometry), if the cell has one.
    pub(crate) robot: Option<Mutex<robot::RobotEstimate>>,
    pub(crate) estop: AtomicBool,
    /// The CNC runner's status, for the traced feed (`cnc.feed`, mm/min) of a cell with a
    /// gantry.
    pub(crate) cnc_status: std::sync::OnceLock<motus_cnc::StatusReader>,
    /// E-stop resets in progress whose release the juggler's supervisor has not yet decided
    /// (shown as the E-stop still held, see `Backend::reset`).
    pub(crate) estop_releasing: std::sync::atomic::AtomicUsize,
    /// Who pressed the E-stop since the last reset.
    pub(crate) estop_owners: Mutex<stops::EStopOwners>,
    /// Jog leases (the dead-man; [`jog`]).
    pub(crate) jogs: Mutex<jog::JogLeases>,
    pub(crate) faults: Arc<FaultTable>,
    pub(crate) alarms: Arc<MemoryAlarms>,
    pub(crate) epoch: Instant,
    pub(crate) stop: AtomicBool,
}

/// The running station machine (see the crate documentation).
pub struct StationMachine {
    pub(crate) shared: Arc<Shared>,
    pub(crate) programs: programs::Programs,
    pub(crate) camera_url: Option<String>,
    /// The E-stop's quick-stop workers.
    pub(crate) quick_stoppers: quick_stop::QuickStoppers,
    threads: Vec<JoinHandle<()>>,
    tasks: Option<tasks::Tasks>,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The pose estimate of the cell's omni group (its three wheel axes), if it has one.
fn robot_estimate(cell: &Cell, groups: &[motus_cell::CellGroup]) -> Option<Mutex<robot::RobotEstimate>> {
    let g = groups.iter().find(|g| matches!(g.handle, motus_cell::GroupHandle::Omni(_)))?;
    let mut scale = [0.0; 3];
    let mut speed = [0.0; 3];
    for (i, name) in g.axes.iter().enumerate().take(3) {
        let cfg = cell.axis(name)?;
        *scale.get_mut(i)? = cfg.scale.si_per_unit();
        *speed.get_mut(i)? = cfg.max_velocity;
    }
    (g.axes.len() == 3).then(|| Mutex::new(robot::RobotEstimate::new(scale, speed)))
}

impl StationMachine {
    /// Loads `cell_file` and starts the station.
    pub fn start_file(cell_file: &Path, options: StationOptions) -> Result<Self, StationError> {
        let cell = motus_station::config::load(cell_file).map_err(|e| StationError::Config(e.to_string()))?;
        Self::start(&cell, options)
    }

    /// Starts the station on a validated cell.
    pub fn start(cell: &Cell, options: StationOptions) -> Result<Self, StationError> {
        let running = open_cell(cell, options.cell)?;
        let mut axes = Vec::new();
        for dev in running.axes() {
            for axis in dev.axes {
                let name = axis.name().to_owned();
                let Some(cfg) = cell.axis(&name) else { continue };
                let group =
                    cell.groups.iter().find(|g| g.axes.iter().any(|a| a == &name)).map(|g| g.name.clone());
                let view = AxisView {
                    id: name.clone(),
                    name: name.clone(),
                    device: dev.device.clone(),
                    group,
                    unit: cfg.unit.symbol().to_owned(),
                    position: 0.0,
                    velocity: 0.0,
                    enabled: false,
                    homed: false,
                    moving: false,
                    fault: None,
                    limits: AxisLimits {
                        min: cfg.limits.min,
                        max: cfg.limits.max,
                        max_speed: cfg.max_velocity,
                        max_acceleration: cfg.max_acceleration,
                    },
                    acceleration: cfg.max_acceleration * 0.5,
                    default_speed: cfg.max_velocity * 0.25,
                };
                axes.push(AxisEntry { view, axis: Mutex::new(axis) });
            }
        }
        let views = axes.iter().map(|a| a.view.clone()).collect();
        let faults = Arc::new(FaultTable::default());
        let alarms = Arc::new(MemoryAlarms::default());
        let groups = running.groups().to_vec();
        let robot = robot_estimate(cell, &groups);
        let juggler = running.juggler();
        let handles = running.device_handles();
        let rules = cell
            .supervisor
            .as_ref()
            .and_then(|s| std::fs::read_to_string(&s.rules).ok())
            .and_then(|t| motus_safety::RuleSet::from_toml(&t).ok());
        let rule_limits = rules
            .as_ref()
            .map(|r| r.axes().iter().map(|a| (a.name.clone(), a.limits.min, a.limits.max)).collect())
            .unwrap_or_default();
        // What the approval covers: the rules and the cell's drive parameters.
        let rules_fingerprint = cell
            .supervisor
            .as_ref()
            .zip(rules.as_ref())
            .and_then(|(s, r)| motus_safety::config_files::snapshot_with_drives(r, s.drives.as_deref()).ok())
            .map(|snap| snap.fingerprint().to_string())
            .unwrap_or_default();
        let shared = Arc::new(Shared {
            rule_limits: RwLock::new(rule_limits),
            rules_fingerprint: RwLock::new(rules_fingerprint),
            running: Mutex::new(running),
            config: cell.clone(),
            groups,
            juggler,
            axes,
            views: RwLock::new(views),
            overrides: RwLock::new(std::collections::HashMap::new()),
            samples: Mutex::new(Samples::default()),
            recorder: std::sync::OnceLock::new(),
            robot_path: Mutex::new(VecDeque::new()),
            robot,
            estop: AtomicBool::new(false),
            cnc_status: std::sync::OnceLock::new(),
            estop_releasing: std::sync::atomic::AtomicUsize::new(0),
            estop_owners: Mutex::new(stops::EStopOwners::default()),
            jogs: Mutex::new(jog::JogLeases::default()),
            faults: Arc::clone(&faults),
            alarms: Arc::clone(&alarms),
            epoch: Instant::now(),
            stop: AtomicBool::new(false),
        });
        // The program runner first: the poller traces its feed from the first row on.
        let programs = programs::Programs::start(cell, &shared, options.program_checks)?;
        if gantry::gantry_axes(&shared).is_some() {
            let _ = shared.cnc_status.set(programs.service.status_reader());
        }
        let mut sinks: Vec<Arc<dyn AlarmSink>> = vec![alarms];
        sinks.extend(options.alarm_sink.clone());
        let sink: Arc<dyn AlarmSink> = Arc::new(alarms::Tee(sinks));
        // The cyclic tasks first: the poller shows their traced signals too.
        let tasks = tasks::start(cell, shared.juggler.as_ref(), Arc::clone(&sink))?;
        if let Some(t) = &tasks {
            let _ = shared.recorder.set(Arc::clone(&t.recorder));
        }
        let (quick_stoppers, mut threads) = quick_stop::QuickStoppers::start(&shared)?;
        {
            let s = Arc::clone(&shared);
            let poll = options.poll;
            threads.push(std::thread::Builder::new().name("motus-poller".into()).spawn(move || {
                motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Device);
                poller::run(&s, poll)
            })?);
        }
        {
            let s = Arc::clone(&shared);
            threads.push(std::thread::Builder::new().name("motus-jog-watchdog".into()).spawn(move || {
                // The dead-man of every jog: a device thread.
                motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Device);
                jog::run_watchdog(&s)
            })?);
        }
        {
            let s = Arc::clone(&shared);
            let mut rec = Reconnector::new(DEVICE_BACKOFF, sink, faults);
            for h in handles {
                rec.add(h);
            }
            threads.push(std::thread::Builder::new().name("motus-reconnect".into()).spawn(move || {
                // Health checks are bus transactions with time-outs: a device thread.
                motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Device);
                while !s.stop.load(Ordering::Relaxed) {
                    for e in rec.poll(Instant::now()) {
                        log_device_event(&e);
                    }
                    std::thread::sleep(Duration::from_millis(100));
                }
            })?);
        }
        Ok(Self { shared, programs, camera_url: options.camera_url, quick_stoppers, threads, tasks })
    }

    /// Runs `f` with the running cell (simulators: kill / restart for tests and demos).
    pub fn with_cell<R>(&self, f: impl FnOnce(&RunningCell) -> R) -> R {
        f(&lock(&self.shared.running))
    }

    /// Runs `f` with the running cell, mutably (kill or restart a simulator: chaos tests and
    /// demonstrations of the reconnection).
    pub fn with_cell_mut<R>(&self, f: impl FnOnce(&mut RunningCell) -> R) -> R {
        f(&mut lock(&self.shared.running))
    }

    /// Active alarms of the station's devices and tasks: (source, code).
    pub fn alarms(&self) -> Vec<(String, motus_station::alarm::AlarmCode)> {
        self.shared.alarms.active()
    }

    /// Statistics of the cyclic task classes (cycle time, jitter, overruns, CPU).
    pub fn task_stats(&self) -> Vec<motus_station::scheduler::ClassStats> {
        self.tasks.as_ref().map(|t| t.scheduler.stats()).unwrap_or_default()
    }

    /// Resumes every degraded task class and clears its alarms (the operator's reset).
    pub fn resume_tasks(&self) {
        if let Some(t) = &self.tasks {
            let _ = t.scheduler.resume(None);
            let _ = t.scheduler.reset_alarms(None);
        }
    }

    /// Resets the statistics of every task class.
    pub fn reset_task_stats(&self) {
        if let Some(t) = &self.tasks {
            let _ = t.scheduler.reset_stats(None);
        }
    }

    /// The latest traced value of `signal` (e.g. `trace-fast/thrower-drive.position`).
    pub fn traced(&self, signal: &str) -> Option<motus_station::trace::Sample> {
        let t = self.tasks.as_ref()?;
        let rec = lock(&t.recorder);
        rec.latest(rec.find(signal)?)
    }

    /// Every signal of the cyclic tasks at its full rate, as CSV (`None`: no cyclic trace).
    pub fn trace_csv(&self) -> Option<String> {
        let t = self.tasks.as_ref()?;
        let rec = lock(&t.recorder);
        let ids: Vec<_> = rec.signals().iter().map(|s| s.id).collect();
        let mut out = Vec::new();
        rec.write_csv(&ids, &mut out).ok()?;
        String::from_utf8(out).ok()
    }

    /// Stops the threads and the cell.
    pub fn stop(&mut self) {
        if let Some(t) = self.tasks.take() {
            for c in t.scheduler.stop() {
                tracing::info!("task class {}", c.summary());
            }
        }
        self.shared.stop.store(true, Ordering::Relaxed);
        // A program check in progress ends at its next line.
        self.programs.checker.stop();
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
        lock(&self.shared.running).stop();
    }
}

impl Drop for StationMachine {
    fn drop(&mut self) {
        self.stop();
    }
}
