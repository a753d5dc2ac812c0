//! A station web server over the in-memory [`FakeBackend`] and a memory (or SQLite) lab
//! store, for trying the HMI and for the browser tests.
//!
//! ```text
//! cargo run -p motus-station-web --example fake_station -- --listen 127.0.0.1:8080 \
//!     --admin-password admin-secret-1 [--student-password ...] [--viewer-password ...] \
//!     [--station NAME] [--camera-url URL] [--db FILE] [--rate HZ]
//! ```
//! Users: `admin`, and `student`, `student2`, `viewer` when their passwords are given
//! (`student2` shares the student password). Prints `listening on http://ADDR` and serves
//! until killed.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::SystemTime;

use motus_lab::{Lab, LabConfig, MemoryStore, MotionLimits, Role, SqliteStore, Store, UnixMs};
use motus_station_web::{start, FakeBackend, WebConfig};

fn main() {
    tracing_subscriber::fmt().with_env_filter(tracing_subscriber::EnvFilter::from_default_env()).init();
    if let Err(e) = run() {
        eprintln!("fake_station: {e}");
        std::process::exit(2);
    }
}

fn run() -> Result<(), String> {
    let mut listen: SocketAddr = SocketAddr::from(([127, 0, 0, 1], 8080));
    let mut admin = None;
    let mut student = None;
    let mut viewer = None;
    let mut station = "fake".to_string();
    let mut camera = None;
    let mut db: Option<PathBuf> = None;
    let mut rate = 20.0;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut val = || args.next().ok_or_else(|| format!("{a} needs a value"));
        match a.as_str() {
            "--listen" => listen = val()?.parse().map_err(|e| format!("--listen: {e}"))?,
            "--admin-password" => admin = Some(val()?),
            "--student-password" => student = Some(val()?),
            "--viewer-password" => viewer = Some(val()?),
            "--station" => station = val()?,
            "--camera-url" => camera = Some(val()?),
            "--db" => db = Some(PathBuf::from(val()?)),
            "--rate" => rate = val()?.parse().map_err(|e| format!("--rate: {e}"))?,
            other => return Err(format!("unknown argument {other}")),
        }
    }
    let admin = admin.ok_or("--admin-password is required")?;
    let store: Arc<dyn Store> = match db {
        Some(p) => Arc::new(SqliteStore::open(&p).map_err(|e| e.to_string())?),
        None => Arc::new(MemoryStore::new()),
    };
    let mut config = LabConfig::default();
    // Plain http on localhost: the cookie cannot be Secure.
    config.sessions.cookie.secure = false;
    // Students may move every axis up to 1 unit/s and 6 units/s^2.
    config.student_limits.default = Some(MotionLimits { max_speed: 1.0, max_acceleration: 6.0 });
    let lab = Arc::new(Lab::new(store, config));
    let now = UnixMs::from(SystemTime::now());
    let mut users = vec![("admin", admin, Role::Admin)];
    if let Some(p) = student {
        users.push(("student", p.clone(), Role::Student));
        users.push(("student2", p, Role::Student));
    }
    if let Some(p) = viewer {
        users.push(("viewer", p, Role::Viewer));
    }
    for (name, pw, role) in users {
        if lab.users().get(name).map_err(|e| e.to_string())?.is_none() {
            lab.users().add(name, &pw, role, now).map_err(|e| format!("user {name}: {e}"))?;
        }
    }
    let backend = Arc::new(FakeBackend::new());
    backend.set_camera_url(camera);
    let handle = start(WebConfig { listen, station, ws_rate_hz: rate, ..WebConfig::default() }, backend, lab)
        .map_err(|e| e.to_string())?;
    println!("listening on {}", handle.url());
    loop {
        std::thread::park();
    }
}
