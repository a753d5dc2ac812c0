//! `motus serve` (a station on a cell file) and `motus demo` (the whole simulated cell with
//! the station and its HMI, no hardware, no root).

use std::net::SocketAddr;
use std::path::Path;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, SystemTime};

use anyhow::{Context, Result};
use motus_lab::{Lab, LabConfig, MotionLimits, Role, SqliteStore, Store, UnixMs};
use motus_station_machine::alarms::LabAlarmSink;
use motus_station_machine::{StationMachine, StationOptions};
use motus_station_web::{start, WebConfig};
use rand::Rng;

use crate::cli::DemoArgs;
use crate::cli_station::ServeArgs;

/// Lab configuration for a cell: student limits from each axis's `student` table; cookies
/// without `Secure` when the station listens on loopback over plain HTTP.
fn lab_config(cell: &motus_station::config::Cell, listen: SocketAddr) -> LabConfig {
    let mut config = LabConfig::default();
    for a in &cell.axes {
        config.student_limits.axes.insert(
            a.name.clone(),
            MotionLimits { max_speed: a.student.max_velocity, max_acceleration: a.student.max_acceleration },
        );
    }
    config.sessions.cookie.secure = !listen.ip().is_loopback();
    config
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
        WebConfig { listen, station: cell.station.name.clone(), ..WebConfig::default() },
        backend,
        lab,
    )?;
    println!("Motus station \"{}\" on {}", cell.station.name, web.url());
    if let Some((name, password)) = admin {
        println!("administrator login: user {name}, password {password}");
    }
    let stop = super::stop_flag()?;
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(100));
    }
    eprintln!("stopping…");
    drop(web); // the server's reference to the machine goes with it
    drop(machine); // the last reference: simulators and threads stop
    eprintln!("stopped");
    Ok(())
}

/// `motus serve`.
pub fn serve(a: ServeArgs) -> Result<()> {
    let db = a.db.clone().unwrap_or_else(|| motus_lab::store::default_db_path(&a.config));
    run_station(&a.config, a.listen, &db, None)
}

/// `motus demo`.
pub fn demo(a: DemoArgs) -> Result<()> {
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
