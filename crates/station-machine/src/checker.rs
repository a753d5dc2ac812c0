//! The program checker: G-code interpreted off the web runtime, on a small fixed pool of
//! worker threads fed by a bounded queue, each check within a time and a step budget.
//!
//! A check streams the program through the interpreter (no list of calls is kept) and
//! measures, per gantry axis (program X, Y, Z onto the cell's `kind = "gantry"` group, in
//! order), the extent of the path (every move's end points and the extremes of every arc,
//! in the axis's unit) and its peak speed (the feed rate of G1/G2/G3, the axis's maximum
//! velocity for G0 rapids) and acceleration (the planner's, the axis's maximum): the
//! station checks these against the machine travel for everyone and the lab against the
//! student limits. A watchdog thread sets the interpreter's [`CancelFlag`] when a check's
//! time runs out; the interpreter stops before its next line.
//!
//! When every worker is busy and the queue is full, [`Checker::check`] refuses at once
//! ([`CheckError::Busy`]); a check of a program already being checked joins it.

use std::collections::HashMap;
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_gcode::{CancelFlag, ErrorKind, Interpreter, InterpreterConfig, MachineMove, Pose};
use motus_station_web::ProgramDiagnostic;

/// Limits of the station's program checker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProgramCheckOptions {
    /// Worker threads (default 1: the other core stays for the machine and the web).
    pub workers: usize,
    /// Checks waiting for a worker at most (default 1); beyond it a check is refused at once.
    pub queue: usize,
    /// Time budget of one check; `None`: the cell file's `[station] program_check_time`.
    pub time_budget: Option<Duration>,
    /// Lines one check executes at most (default 50 million).
    pub max_steps: u64,
}

impl Default for ProgramCheckOptions {
    fn default() -> Self {
        Self { workers: 1, queue: 1, time_budget: None, max_steps: 50_000_000 }
    }
}

impl ProgramCheckOptions {
    /// Checks in progress or waiting at most (workers + queue).
    #[must_use]
    pub fn capacity(&self) -> usize {
        self.workers.max(1) + self.queue
    }
}

/// One gantry axis as programs see it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct GantryAxis {
    /// Axis id.
    pub name: String,
    /// Program millimetres per axis unit (1000 for an axis in m).
    pub mm_per_unit: f64,
    /// The planner's velocity limit (the rapid speed), axis units/s.
    pub max_velocity: f64,
    /// The planner's acceleration, axis units/s².
    pub acceleration: f64,
}

/// Where one axis goes in a program, in the axis's unit.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Extent {
    /// Axis id.
    pub axis: String,
    /// Lowest position and the (1-based) line that reaches it.
    pub lo: (f64, u32),
    /// Highest position and its line.
    pub hi: (f64, u32),
    /// Peak speed asked (units/s).
    pub speed: f64,
    /// Peak acceleration (units/s²).
    pub acceleration: f64,
}

/// What a check found.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Analysis {
    /// Errors (empty: the program interprets to its end within the budget).
    pub errors: Vec<ProgramDiagnostic>,
    /// Per gantry axis the program moves.
    pub extents: Vec<Extent>,
    /// The tool path, for the HMI's preview.
    pub preview: motus_station_web::ProgramPreview,
    /// Lines executed.
    pub steps: u64,
    /// Wall time of the check.
    pub elapsed: Duration,
}

/// Why a check was not done.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub(crate) enum CheckError {
    /// Every worker is busy and the queue is full.
    #[error("every program checker is busy ({0} checks in progress or waiting); try again in a few seconds")]
    Busy(usize),
    /// The checker is stopping.
    #[error("the program checker has stopped")]
    Stopped,
    /// No result in far more than the budget (a worker is stuck).
    #[error("the program checker did not answer in time")]
    Late,
}

/// Per-axis accumulation over the moves.
struct Accumulator<'g> {
    gantry: &'g [GantryAxis],
    extents: Vec<Option<Extent>>,
    first_move: bool,
    /// A program axis (X, Y, Z) that moves but has no gantry axis: (axis letter, line).
    missing: Option<(char, u32)>,
}

const TAU: f64 = std::f64::consts::TAU;

impl<'g> Accumulator<'g> {
    fn new(gantry: &'g [GantryAxis]) -> Self {
        Self { gantry, extents: vec![None; gantry.len()], first_move: true, missing: None }
    }

    /// Position `mm` (machine mm) of program axis `i` is reached at `line`.
    fn reach(&mut self, i: usize, mm: f64, line: u32) {
        let (Some(g), Some(slot)) = (self.gantry.get(i), self.extents.get_mut(i)) else {
            if mm.abs() > 1e-9 && self.missing.is_none() {
                self.missing = Some((['X', 'Y', 'Z'].get(i).copied().unwrap_or('?'), line));
            }
            return;
        };
        let v = mm / g.mm_per_unit;
        let e = slot.get_or_insert_with(|| Extent {
            axis: g.name.clone(),
            lo: (v, line),
            hi: (v, line),
            speed: 0.0,
            acceleration: 0.0,
        });
        // A NaN position replaces the bound and stays (every later comparison is false), so
        // the program is refused.
        if v.is_nan() || v < e.lo.0 {
            e.lo = (v, line);
        }
        if v.is_nan() || v > e.hi.0 {
            e.hi = (v, line);
        }
    }

    /// Program axis `i` moves at `speed_mm_s` (`None`: a rapid, at the axis's maximum).
    fn moves(&mut self, i: usize, speed_mm_s: Option<f64>) {
        let (Some(g), Some(Some(e))) = (self.gantry.get(i), self.extents.get_mut(i)) else { return };
        let v = speed_mm_s.map_or(g.max_velocity, |s| s / g.mm_per_unit);
        if v.is_nan() || v > e.speed {
            e.speed = v;
        }
        e.acceleration = e.acceleration.max(g.acceleration);
    }

    fn point(&mut self, p: &Pose, line: u32) {
        for (i, v) in p.iter().take(3).enumerate() {
            self.reach(i, *v, line);
        }
    }

    /// The axes of `start` -> `end` that move (every axis on the first move: the machine
    /// starts wherever it is, not where the interpreter assumes).
    fn moving(&self, start: &Pose, end: &Pose) -> [bool; 3] {
        let mut m = [self.first_move; 3];
        for (i, flag) in m.iter_mut().enumerate() {
            let (s, e) = (start.get(i).copied().unwrap_or(0.0), end.get(i).copied().unwrap_or(0.0));
            *flag |= (s - e).abs() > 1e-9 || s.is_nan() || e.is_nan();
        }
        m
    }

    fn visit(&mut self, line: u32, m: &MachineMove) {
        match m {
            MachineMove::Traverse { start, end } => {
                self.point(end, line);
                let moving = self.moving(start, end);
                for (i, _) in moving.iter().enumerate().filter(|(_, m)| **m) {
                    self.moves(i, None);
                }
            }
            MachineMove::Feed { start, end, feed } => {
                self.point(end, line);
                let moving = self.moving(start, end);
                for (i, _) in moving.iter().enumerate().filter(|(_, m)| **m) {
                    self.moves(i, Some(feed / 60.0));
                }
            }
            MachineMove::Arc { start, end, centre, plane, rotation, feed } => {
                self.point(start, line);
                self.point(end, line);
                let (a, b, _) = plane.axes();
                let at = |p: &Pose, i: usize| p.get(i).copied().unwrap_or(0.0);
                let (ca, cb) = (centre.get(a).copied().unwrap_or(0.0), centre.get(b).copied().unwrap_or(0.0));
                for (i, v) in arc_extremes(
                    (at(start, a) - ca, at(start, b) - cb),
                    (at(end, a) - ca, at(end, b) - cb),
                    *rotation,
                ) {
                    let (axis, c) = if i == 0 { (a, ca) } else { (b, cb) };
                    self.reach(axis, c + v, line);
                }
                let mut moving = self.moving(start, end);
                // Both axes of the plane move along an arc, even a full circle.
                for i in [a, b] {
                    if let Some(f) = moving.get_mut(i) {
                        *f = true;
                    }
                }
                for (i, _) in moving.iter().enumerate().filter(|(_, m)| **m) {
                    self.moves(i, Some(feed / 60.0));
                }
            }
        }
        self.first_move = false;
    }
}

/// The angle an arc sweeps from angle `t0` to `t1` (radians), `rotation` < 0 clockwise,
/// |rotation| turns (the same start and end: a full circle; extra turns bounded at 1,000).
pub(crate) fn arc_sweep(t0: f64, t1: f64, rotation: i32) -> f64 {
    let mut sweep = if rotation >= 0 { t1 - t0 } else { t0 - t1 }.rem_euclid(TAU);
    if sweep < 1e-9 {
        sweep += TAU;
    }
    sweep + f64::from(rotation.unsigned_abs().saturating_sub(1).min(1_000)) * TAU
}

/// The extremes of an arc about the origin from `s` to `e` (plane coordinates relative to
/// the centre), `rotation` < 0 clockwise, |rotation| turns: every crossing of a coordinate
/// axis inside the swept angle, as (0 = first coordinate | 1 = second, value).
fn arc_extremes(s: (f64, f64), e: (f64, f64), rotation: i32) -> Vec<(usize, f64)> {
    let r = s.0.hypot(s.1).max(e.0.hypot(e.1));
    let ts = s.1.atan2(s.0);
    let te = e.1.atan2(e.0);
    let ccw = rotation >= 0;
    let sweep = arc_sweep(ts, te, rotation);
    let mut out = Vec::new();
    for (phi, (axis, value)) in
        [0.0, 0.25, 0.5, 0.75].into_iter().map(|q| q * TAU).zip([(0, r), (1, r), (0, -r), (1, -r)])
    {
        let delta = if ccw { phi - ts } else { ts - phi }.rem_euclid(TAU);
        if delta <= sweep {
            out.push((axis, value));
        }
    }
    out
}

/// Interprets `text` to its end (or the budget) and measures it; `cancel` stops it.
/// `machine`: the interpreter settings the program will run with (tool table, step limit).
pub(crate) fn analyse(
    text: &str,
    gantry: Option<&[GantryAxis]>,
    machine: &InterpreterConfig,
    budget: Duration,
    cancel: &CancelFlag,
) -> Analysis {
    let started = Instant::now();
    let max_steps = machine.max_steps;
    let config =
        InterpreterConfig { require_program_end: false, cancel: Some(cancel.clone()), ..machine.clone() };
    let no_gantry: [GantryAxis; 0] = [];
    let mut acc = Accumulator::new(gantry.unwrap_or(&no_gantry));
    let mut errors = Vec::new();
    let mut interp = Interpreter::with_config(text, config);
    let mut moved = false;
    let mut preview = crate::preview::PreviewBuilder::default();
    for call in interp.by_ref() {
        match call {
            Ok(c) => {
                if let Some(m) = &c.machine {
                    acc.visit(c.line, m);
                    preview.visit(m);
                    moved = true;
                }
            }
            Err(e) => {
                let message = match e.kind {
                    ErrorKind::Cancelled(steps) | ErrorKind::StepLimit(steps) => format!(
                        "check stopped after {:.1} s / {steps} lines executed: the program is too long or \
                         does not end; a check may take {:.1} s and {max_steps} lines",
                        started.elapsed().as_secs_f64(),
                        budget.as_secs_f64(),
                    ),
                    kind => kind.to_string(),
                };
                errors.push(ProgramDiagnostic { line: e.line as usize, col: e.column as usize, message });
                break;
            }
        }
    }
    if moved && gantry.is_none() {
        errors.push(ProgramDiagnostic {
            line: 1,
            col: 1,
            message: "this cell has no gantry group (kind = \"gantry\"): programs cannot move anything here"
                .into(),
        });
    }
    if let Some((letter, line)) = acc.missing {
        errors.push(ProgramDiagnostic {
            line: line as usize,
            col: 1,
            message: format!("the program moves {letter}, but the cell's gantry has no axis for it"),
        });
    }
    Analysis {
        errors,
        extents: acc.extents.into_iter().flatten().collect(),
        preview: preview.finish(),
        steps: interp.steps(),
        elapsed: started.elapsed(),
    }
}

/// A check in progress: its result, once there.
#[derive(Default)]
struct Slot {
    result: Mutex<Option<Arc<Analysis>>>,
    done: Condvar,
}

/// A program id and version.
type JobKey = (String, u64);

struct Job {
    key: JobKey,
    text: Arc<str>,
    cancel: CancelFlag,
    slot: Arc<Slot>,
}

/// The pool's shared state.
struct Shared {
    /// Checks queued or running, by (program id, version).
    inflight: Mutex<HashMap<JobKey, (Arc<Slot>, CancelFlag)>>,
    /// Deadlines the watchdog enforces.
    deadlines: Mutex<Vec<(Instant, CancelFlag)>>,
    wake: Condvar,
    stopping: std::sync::atomic::AtomicBool,
    gantry: Option<Vec<GantryAxis>>,
    budget: Duration,
    /// The interpreter settings programs run with (its step limit bounds a check).
    config: InterpreterConfig,
    capacity: usize,
    /// Callers waiting for a result (each holds a thread of the web's blocking pool).
    waiters: std::sync::atomic::AtomicUsize,
}

/// Callers that may wait for checks at once, per place of the pool: joining a check in
/// progress is refused beyond it, so that repeated requests cannot fill the web server's
/// blocking pool (the E-stop's path).
const WAITERS_PER_PLACE: usize = 4;

/// Counts a waiting caller while it lives.
struct Waiting<'a>(&'a std::sync::atomic::AtomicUsize);

impl Drop for Waiting<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, std::sync::atomic::Ordering::Relaxed);
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The pool of checker threads (see the module documentation).
pub(crate) struct Checker {
    tx: Option<SyncSender<Job>>,
    shared: Arc<Shared>,
    threads: Vec<JoinHandle<()>>,
}

impl Checker {
    /// Starts `options.workers` workers and the watchdog; checks interpret with `config`
    /// (the machine's tool table...) and `options.max_steps`.
    pub(crate) fn start(
        options: ProgramCheckOptions,
        budget: Duration,
        gantry: Option<Vec<GantryAxis>>,
        config: InterpreterConfig,
    ) -> std::io::Result<Self> {
        let (tx, rx) = mpsc::sync_channel::<Job>(options.queue);
        let rx = Arc::new(Mutex::new(rx));
        let shared = Arc::new(Shared {
            inflight: Mutex::new(HashMap::new()),
            deadlines: Mutex::new(Vec::new()),
            wake: Condvar::new(),
            stopping: std::sync::atomic::AtomicBool::new(false),
            gantry,
            budget,
            config: InterpreterConfig { max_steps: options.max_steps, ..config },
            capacity: options.capacity(),
            waiters: std::sync::atomic::AtomicUsize::new(0),
        });
        let mut threads = Vec::new();
        for k in 0..options.workers.max(1) {
            let (rx, shared) = (Arc::clone(&rx), Arc::clone(&shared));
            threads.push(
                std::thread::Builder::new()
                    .name(format!("motus-gcode-check-{k}"))
                    .spawn(move || worker(&rx, &shared))?,
            );
        }
        let s = Arc::clone(&shared);
        threads.push(
            std::thread::Builder::new().name("motus-gcode-watchdog".into()).spawn(move || watchdog(&s))?,
        );
        Ok(Self { tx: Some(tx), shared, threads })
    }

    /// Checks `text` (program `id` at `version`), waiting for the result (at most about the
    /// budget once a worker has it). A check of the same version in progress is joined.
    pub(crate) fn check(&self, id: &str, version: u64, text: Arc<str>) -> Result<Arc<Analysis>, CheckError> {
        let key = (id.to_owned(), version);
        let max_waiters = self.shared.capacity * WAITERS_PER_PLACE;
        if self.shared.waiters.fetch_add(1, std::sync::atomic::Ordering::Relaxed) >= max_waiters {
            self.shared.waiters.fetch_sub(1, std::sync::atomic::Ordering::Relaxed);
            return Err(CheckError::Busy(self.shared.capacity));
        }
        let _waiting = Waiting(&self.shared.waiters);
        let slot = {
            let mut inflight = lock(&self.shared.inflight);
            if let Some((slot, _)) = inflight.get(&key) {
                Arc::clone(slot)
            } else {
                let tx = self.tx.as_ref().ok_or(CheckError::Stopped)?;
                let slot = Arc::new(Slot::default());
                let cancel = CancelFlag::new();
                let job = Job { key: key.clone(), text, cancel: cancel.clone(), slot: Arc::clone(&slot) };
                match tx.try_send(job) {
                    Ok(()) => {}
                    Err(TrySendError::Full(_)) => return Err(CheckError::Busy(self.shared.capacity)),
                    Err(TrySendError::Disconnected(_)) => return Err(CheckError::Stopped),
                }
                inflight.insert(key, (Arc::clone(&slot), cancel));
                slot
            }
        };
        // A queued check waits for the one before it: wait for both budgets, and more.
        let limit = Instant::now() + self.shared.budget * 2 + Duration::from_secs(10);
        let mut result = lock(&slot.result);
        loop {
            if let Some(a) = result.as_ref() {
                return Ok(Arc::clone(a));
            }
            let now = Instant::now();
            if self.shared.stopping.load(std::sync::atomic::Ordering::Relaxed) {
                return Err(CheckError::Stopped);
            }
            if now >= limit {
                return Err(CheckError::Late);
            }
            result = slot.done.wait_timeout(result, limit - now).unwrap_or_else(PoisonError::into_inner).0;
        }
    }

    /// Cancels every check and stops the threads.
    pub(crate) fn stop(&mut self) {
        self.shared.stopping.store(true, std::sync::atomic::Ordering::Relaxed);
        self.tx = None;
        for (slot, cancel) in lock(&self.shared.inflight).values() {
            cancel.cancel();
            slot.done.notify_all();
        }
        self.shared.wake.notify_all();
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

impl Drop for Checker {
    fn drop(&mut self) {
        self.stop();
    }
}

fn worker(rx: &Mutex<Receiver<Job>>, shared: &Shared) {
    // Checking is web work: it yields to the machine's threads.
    motus_realtime::demote_current_thread_for_web();
    loop {
        let job = match lock(rx).recv() {
            Ok(j) => j,
            Err(_) => return,
        };
        if shared.stopping.load(std::sync::atomic::Ordering::Relaxed) {
            job.cancel.cancel();
        }
        let deadline = Instant::now() + shared.budget;
        lock(&shared.deadlines).push((deadline, job.cancel.clone()));
        shared.wake.notify_all();
        let analysis =
            analyse(&job.text, shared.gantry.as_deref(), &shared.config, shared.budget, &job.cancel);
        tracing::info!(
            program = %job.key.0,
            steps = analysis.steps,
            elapsed_ms = analysis.elapsed.as_millis() as u64,
            errors = analysis.errors.len(),
            "program checked"
        );
        lock(&shared.deadlines).retain(|(_, c)| c != &job.cancel);
        *lock(&job.slot.result) = Some(Arc::new(analysis));
        job.slot.done.notify_all();
        lock(&shared.inflight).remove(&job.key);
    }
}

/// Sets the cancel flag of every check whose time ran out.
fn watchdog(shared: &Shared) {
    let mut deadlines = lock(&shared.deadlines);
    while !shared.stopping.load(std::sync::atomic::Ordering::Relaxed) {
        let now = Instant::now();
        for (d, c) in deadlines.iter() {
            if *d <= now {
                c.cancel();
            }
        }
        deadlines.retain(|(d, _)| *d > now);
        let wait = deadlines.iter().map(|(d, _)| *d - now).min().unwrap_or(Duration::from_secs(1));
        deadlines = shared.wake.wait_timeout(deadlines, wait).unwrap_or_else(PoisonError::into_inner).0;
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]
    use super::*;

    fn steps(max_steps: u64) -> InterpreterConfig {
        InterpreterConfig { max_steps, ..InterpreterConfig::default() }
    }

    fn gantry() -> Vec<GantryAxis> {
        ["x", "y", "z"]
            .iter()
            .map(|n| GantryAxis {
                name: (*n).into(),
                mm_per_unit: 1000.0,
                max_velocity: 0.1,
                acceleration: 1.0,
            })
            .collect()
    }

    fn run(text: &str) -> Analysis {
        analyse(text, Some(&gantry()), &steps(1_000_000), Duration::from_secs(5), &CancelFlag::new())
    }

    fn extent<'a>(a: &'a Analysis, axis: &str) -> &'a Extent {
        a.extents.iter().find(|e| e.axis == axis).unwrap()
    }

    #[test]
    fn lines_give_extent_feed_and_rapid_speeds_in_axis_units() {
        let a = run("G21 G90\nG0 X10 Y20\nG1 X500 F1000000\nG1 Y5 F600\nM2\n");
        assert!(a.errors.is_empty(), "{:?}", a.errors);
        let x = extent(&a, "x");
        assert_eq!((x.lo, x.hi), ((0.01, 2), (0.5, 3)));
        assert!((x.speed - 1_000_000.0 / 60.0 / 1000.0).abs() < 1e-9, "{x:?}");
        assert_eq!(x.acceleration, 1.0);
        let y = extent(&a, "y");
        assert_eq!((y.lo, y.hi), ((0.005, 4), (0.02, 2)));
        // Y: the rapid (0.1 m/s), and F600 = 10 mm/s; not the X feed (Y does not move then).
        assert!((y.speed - 0.1).abs() < 1e-12, "{y:?}");
        let z = extent(&a, "z");
        assert_eq!((z.lo.0, z.hi.0), (0.0, 0.0), "Z goes to 0 on the first move");
    }

    #[test]
    fn inches_are_converted() {
        let a = run("G20 G90\nG1 X10 F10\nM2\n");
        let x = extent(&a, "x");
        assert!((x.hi.0 - 0.254).abs() < 1e-12, "{x:?}");
        assert!((x.speed - 0.254 / 60.0).abs() < 1e-12, "{x:?}");
    }

    #[test]
    fn arcs_reach_their_extremes() {
        // A half circle from (10, 0) about (0, 0) counter-clockwise to (-10, 0): Y reaches 10.
        let a = run("G21 G90\nG0 X10 Y0\nG3 X-10 Y0 I-10 J0 F60\nM2\n");
        assert!(a.errors.is_empty(), "{:?}", a.errors);
        let y = extent(&a, "y");
        assert!((y.hi.0 - 0.01).abs() < 1e-12 && y.hi.1 == 3, "{y:?}");
        assert!(y.lo.0.abs() < 1e-12, "{y:?}");
        // Clockwise instead: Y reaches -10.
        let a = run("G21 G90\nG0 X10 Y0\nG2 X-10 Y0 I-10 J0 F60\nM2\n");
        let y = extent(&a, "y");
        assert!((y.lo.0 + 0.01).abs() < 1e-12 && y.hi.0.abs() < 1e-12, "{y:?}");
        // A full circle reaches every side.
        let a = run("G21 G90\nG0 X10 Y0\nG2 X10 Y0 I-10 J0 F60\nM2\n");
        let (x, y) = (extent(&a, "x"), extent(&a, "y"));
        assert!((x.lo.0 + 0.01).abs() < 1e-12 && (y.lo.0 + 0.01).abs() < 1e-12, "{x:?} {y:?}");
        assert!((y.hi.0 - 0.01).abs() < 1e-12, "{y:?}");
    }

    #[test]
    fn errors_and_missing_axes_are_reported_with_their_line() {
        let a = run("G21\nG1 X1 F10\nQ7\nM2\n");
        assert_eq!((a.errors[0].line, a.errors[0].col), (3, 1), "{:?}", a.errors);
        let two = &gantry()[..2];
        let a =
            analyse("G1 X1 Z5 F10\n", Some(two), &steps(1000), Duration::from_secs(1), &CancelFlag::new());
        assert!(a.errors.iter().any(|e| e.line == 1 && e.message.contains("moves Z")), "{:?}", a.errors);
        let a = analyse("G1 X1 F10\n", None, &steps(1000), Duration::from_secs(1), &CancelFlag::new());
        assert!(a.errors[0].message.contains("no gantry"), "{:?}", a.errors);
    }

    #[test]
    fn the_step_budget_ends_an_endless_loop_with_a_clear_error() {
        let text = "#1 = 0\no100 while [1]\n#1 = [#1 + 1]\no100 endwhile\nM2\n";
        let a = analyse(text, Some(&gantry()), &steps(10_000), Duration::from_secs(3), &CancelFlag::new());
        let e = &a.errors[0];
        assert!(e.message.starts_with("check stopped after "), "{e:?}");
        assert!(e.message.contains("10000 lines"), "{e:?}");
        assert!((2..=4).contains(&e.line), "{e:?}");
    }

    #[test]
    fn the_pool_refuses_beyond_its_capacity_and_cancels_at_the_budget() {
        let opts = ProgramCheckOptions { workers: 1, queue: 1, time_budget: None, max_steps: u64::MAX };
        let budget = Duration::from_millis(400);
        let checker =
            Arc::new(Checker::start(opts, budget, Some(gantry()), InterpreterConfig::default()).unwrap());
        // Endless programs, one after the other: the worker takes the first, the queue holds
        // the second, the third is refused at once (or the second, if the worker has not
        // taken the first yet).
        let mut running = Vec::new();
        let mut refused = None;
        for k in 0..opts.capacity() + 1 {
            let c = Arc::clone(&checker);
            let (tx, rx) = mpsc::channel();
            running.push(std::thread::spawn(move || {
                let t0 = Instant::now();
                let r = c.check(&format!("p{k}"), 1, Arc::from("o1 while [1]\no1 endwhile\n"));
                let _ = tx.send(t0.elapsed());
                r
            }));
            if let Ok(waited) = rx.recv_timeout(Duration::from_millis(100)) {
                refused = Some(waited);
                break;
            }
        }
        let waited = refused.expect("a check beyond the capacity is refused");
        assert!(waited < Duration::from_millis(100), "refused at once: {waited:?}");
        let mut outcomes = running.into_iter().map(|t| t.join().unwrap()).collect::<Vec<_>>();
        assert_eq!(outcomes.pop().unwrap().unwrap_err(), CheckError::Busy(2));
        for a in outcomes {
            let a = a.unwrap();
            assert!(a.errors[0].message.starts_with("check stopped after 0."), "{:?}", a.errors);
            assert!(a.elapsed < Duration::from_secs(3), "{:?}", a.elapsed);
        }
        // Free again.
        assert!(checker.check("c", 1, Arc::from("G0 X1\n")).unwrap().errors.is_empty());
        // Callers joining one check in progress are bounded too: beyond the limit, refused.
        let joiners: Vec<_> = (0..opts.capacity() * WAITERS_PER_PLACE + 3)
            .map(|_| {
                let c = Arc::clone(&checker);
                std::thread::spawn(move || c.check("same", 1, Arc::from("o1 while [1]\no1 endwhile\n")))
            })
            .collect();
        let outcomes: Vec<_> = joiners.into_iter().map(|t| t.join().unwrap()).collect();
        let busy = outcomes.iter().filter(|o| matches!(o, Err(CheckError::Busy(_)))).count();
        let checked = outcomes.iter().filter(|o| o.is_ok()).count();
        assert!(busy >= 3, "{busy} refused");
        assert_eq!(busy + checked, outcomes.len(), "{outcomes:?}");
        // Those that joined share one check (one analysis).
        let first = outcomes.iter().find_map(|o| o.as_ref().ok()).unwrap();
        assert!(outcomes.iter().filter_map(|o| o.as_ref().ok()).all(|a| Arc::ptr_eq(a, first)));
    }
}
