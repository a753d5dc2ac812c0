//! `motus serve` (a station on a cell file) and `motus demo` (the whole simulated cell with
//! the station and its HMI, no hardware, no root).

use std::net::SocketAddr;
use std::path::Path;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime};

use anyhow::{bail, Context, Result};
use motus_lab::{Lab, LabConfig, Role, SqliteStore, Store, UnixMs};
use motus_station_machine::alarms::LabAlarmSink;
use motus_station_machine::{StationMachine, StationOptions};
use motus_station_web::{start, Caller, MachineBackend, WebConfig, WebHandle};
use rand::Rng;

use crate::cli::DemoArgs;
use crate::cli_station::ServeArgs;

/// Lab configuration for a cell (see [`motus_station_machine::lab_config`]): cookies
/// without `Secure` when the station listens on loopback over plain HTTP.
fn lab_config(cell: &motus_station::config::Cell, listen: SocketAddr) -> LabConfig {
    motus_station_machine::lab_config(cell, !listen.ip().is_loopback())
}

fn run_station(
    cell_file: &Path,
    listen: Option<SocketAddr>,
    db: &Path,
    admin: Option<(&str, &str)>,
) -> Result<()> {
    let cell = motus_station::config::load(cell_file).map_err(|e| anyhow::anyhow!("{e}"))?;
    let listen = listen.unwrap_or(cell.station.listen);
    let store: Arc<dyn Store> = Arc::new(
        SqliteStore::open(db)
            .with_context(|| format!("cannot open the station database {}", db.display()))?,
    );
    let lab = Arc::new(Lab::new(Arc::clone(&store), lab_config(&cell, listen)));
    if let Some((name, password)) = admin {
        let now = UnixMs::from(SystemTime::now());
        if lab.users().get(name)?.is_none() {
            lab.users().add(name, password, Role::Admin, now)?;
        } else {
            lab.users().passwd(name, password, now)?;
        }
    }
    eprintln!("starting the cell {} ({} axes)…", cell_file.display(), cell.axes.len());
    let alarm_sink = LabAlarmSink::start(Arc::clone(&lab)).context("starting the alarm writer")?;
    let options = StationOptions { alarm_sink: Some(alarm_sink), ..StationOptions::default() };
    let machine = Arc::new(StationMachine::start(&cell, options)?);
    let backend: Arc<dyn motus_station_web::MachineBackend> = machine.clone();
    let web = start(
        WebConfig {
            listen,
            station: cell.station.name.clone(),
            allowed_origins: cell.station.origins.clone(),
            shutdown_grace: WEB_GRACE,
            ..WebConfig::default()
        },
        backend,
        lab,
    )?;
    println!("Motus station \"{}\" on {}", cell.station.name, web.url());
    if let Some((name, password)) = admin {
        println!("administrator login: user {name}, password {password}");
    }
    let stop = super::stop_flag()?;
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(50));
    }
    let signalled = Instant::now();
    eprintln!("stopping…");
    let report = stop_station(machine, web, signalled);
    let steps = report.steps.join(", ");
    if report.left_behind.is_empty() {
        eprintln!("stopped in {} ms ({steps})", signalled.elapsed().as_millis());
        return Ok(());
    }
    eprintln!(
        "exiting {} ms after the signal ({steps}); did not stop in time: {}",
        signalled.elapsed().as_millis(),
        report.left_behind.join(", ")
    );
    std::process::exit(if report.estopped { 0 } else { 1 });
}

/// How long the E-stop may take before the stop goes on without it.
const ESTOP_WAIT: Duration = Duration::from_millis(500);
/// When, after the signal, the web server must be down.
const WEB_DONE_BY: Duration = Duration::from_millis(1400);
/// When, after the signal, everything must be down (the bound is 2 s).
const ALL_DONE_BY: Duration = Duration::from_millis(1900);

/// What [`stop_station`] achieved.
struct StopReport {
    /// The E-stop returned (motion stopped).
    estopped: bool,
    /// The steps that did not finish in time.
    left_behind: Vec<&'static str>,
    /// Each finished step and when it finished after the signal (`E-stop 3 ms`).
    steps: Vec<String>,
}

/// Requests in progress get this long at a stop (the web server's part of the budget).
const WEB_GRACE: Duration = Duration::from_millis(800);

/// A step of the stop running on a thread of its own; [`Step::done_by`] waits for it.
struct Step(Option<std::sync::mpsc::Receiver<()>>);

impl Step {
    fn start(name: &str, f: impl FnOnce() + Send + 'static) -> Step {
        let (tx, rx) = std::sync::mpsc::channel();
        let spawned = std::thread::Builder::new().name(name.to_string()).spawn(move || {
            f();
            let _ = tx.send(());
        });
        Step(spawned.ok().map(|_| rx))
    }

    /// True if the step finished by `deadline` (else its thread is left behind: the process
    /// exits without it).
    fn done_by(&self, deadline: Instant) -> bool {
        self.0
            .as_ref()
            .is_some_and(|rx| rx.recv_timeout(deadline.saturating_duration_since(Instant::now())).is_ok())
    }
}

/// Stops the station after SIGINT or SIGTERM within 2 s, whatever runs (a long program check
/// or a stuck request holding the web runtime's blocking threads, a device that does not
/// answer), in this order:
///
/// 1. **E-stop**: `MachineBackend::estop` as the `console` caller, on its own thread, waited
///    for at most 0.5 s: motion stops first.
/// 2. **Web server**, started right after the E-stop on a thread of its own: it stops
///    accepting, closes idle connections and WebSockets, gives requests in progress its
///    `shutdown_grace` (0.8 s) and abandons blocking work left behind 250 ms later
///    ([`motus_station_web::WebHandle::shutdown`]); waited for until 1.4 s after the signal.
/// 3. **Machine**: our reference is dropped on its own thread (the last one once the web
///    server is down: simulators, device and cyclic threads stop), waited for until 1.9 s
///    after the signal.
///
/// A step that misses its deadline is named in the report and left running; the caller
/// exits the process anyway.
fn stop_station(machine: Arc<StationMachine>, web: WebHandle, signalled: Instant) -> StopReport {
    let mut report = StopReport { estopped: false, left_behind: Vec::new(), steps: Vec::new() };
    let mut step = |name: &'static str, done: bool| {
        if done {
            report.steps.push(format!("{name} {} ms", signalled.elapsed().as_millis()));
        } else {
            report.left_behind.push(name);
        }
        done
    };
    let m = Arc::clone(&machine);
    let estop = Step::start("motus-stop-estop", move || m.estop(&Caller::new("console", Role::Admin)));
    let web = Step::start("motus-stop-web", move || {
        if let Err(e) = web.shutdown() {
            tracing::error!(error = %e, "web server ended with an error");
        }
    });
    let estopped = step("E-stop", estop.done_by(signalled + ESTOP_WAIT));
    step("web server", web.done_by(signalled + WEB_DONE_BY));
    let machine = Step::start("motus-stop-machine", move || drop(machine));
    step("machine", machine.done_by(signalled + ALL_DONE_BY));
    report.estopped = estopped;
    report
}

/// The process's real-time policy, set before any device thread starts, and its memory
/// locked when permitted (both logged once by `motus_realtime`).
fn set_realtime(policy: crate::cli_station::RealtimeArg) {
    let obtained = motus_realtime::set_policy(policy.into());
    let memory = motus_realtime::lock_memory();
    eprintln!("real-time: {obtained}; {memory}");
}

/// `motus serve`.
pub fn serve(a: ServeArgs) -> Result<()> {
    set_realtime(a.realtime);
    let db = a.db.clone().unwrap_or_else(|| motus_lab::store::default_db_path(&a.config));
    run_station(&a.config, a.listen, &db, None)
}

/// `motus demo`.
pub fn demo(a: DemoArgs) -> Result<()> {
    if let Some(dir) = &a.write_cell {
        return write_cell(dir, &a.listen);
    }
    set_realtime(a.realtime);
    let dir = tempfile::Builder::new()
        .prefix("motus-demo-")
        .tempdir()
        .context("cannot create a temporary directory")?;
    let listen: SocketAddr = a.listen.parse().with_context(|| format!("--listen {}", a.listen))?;
    let cell = motus_station_machine::demo::write_demo_cell(dir.path(), &listen.to_string())?;
    let password: String =
        rand::thread_rng().sample_iter(&rand::distributions::Alphanumeric).take(20).map(char::from).collect();
    run_station(&cell, Some(listen), &dir.path().join("demo.lab.sqlite"), Some(("admin", &password)))
}

/// `motus demo --write-cell DIR`: the demo cell in `dir` (new or empty), and what to do next.
fn write_cell(dir: &Path, listen: &str) -> Result<()> {
    let listen: SocketAddr = listen.parse().with_context(|| format!("--listen {listen}"))?;
    if dir.exists()
        && std::fs::read_dir(dir).with_context(|| format!("cannot read {}", dir.display()))?.next().is_some()
    {
        bail!("{} is not empty: give a new or empty directory for the demo cell", dir.display());
    }
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let cell = motus_station_machine::demo::write_demo_cell(dir, &listen.to_string())
        .with_context(|| format!("cannot write the demo cell into {}", dir.display()))?;
    println!("{}", cell.display());
    eprintln!(
        "the demo cell is in {}; add an administrator, then run the station:\n  \
         echo 'a long passphrase' | motus user --config {c} add admin --role admin\n  \
         motus serve --config {c}",
        dir.display(),
        c = cell.display()
    );
    Ok(())
}
