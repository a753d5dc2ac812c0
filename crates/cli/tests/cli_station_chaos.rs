//! Chaos with separate processes (issue 18, acceptance 5): `motus serve` drives devices that
//! run as processes of their own — the virtual CAN bus (`motus canbus serve`), a CiA 402
//! drive (`motus sim icla`) and the KV-01 arm (`motus sim kv01`) — and those processes are
//! killed and started again under it. Everything on 127.0.0.1, free ports, temporary folders.
//!
//! - The drive's process restarts: the station runs the drive's bring-up again (its heartbeat
//!   consumer 0x1016:1, read by SDO from another process, is set again) and, after a reset,
//!   the axis homes through the HTTP API.
//! - The hub's process restarts (the drive's simulator exits with it and is started again):
//!   the station is connected to the drive again (0.7-2.8 s measured, issue 18's 5 s; the
//!   time is printed, the test's time-out is liveness only).
//! - The station starts while the arm's simulator is not running: it serves, the arm's
//!   joints are shown disconnected with an alarm; when the simulator starts, the station
//!   connects the arm and clears the alarm.
//!
//! The in-process versions are `crates/cell/tests/can_recovery.rs` and
//! `crates/station-machine/tests/recovery.rs`.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use common::{http, MOTUS};
use serde_json::Value;

/// The drive's node id on the bus.
const NODE: &str = "2";

/// What the station's bring-up writes into the drive's 0x1016:1: the master (node 126,
/// 0x7E) watched with 300 ms (0x12C).
const CONSUMER_ENTRY: i64 = 0x007E_012C;

/// The administrator's password in every test station.
const PASSWORD: &str = "chaos-test-password-1";

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// `motus <args>` as a child process, killed when dropped (a failing test leaves none
/// behind); its stderr is kept, and printed if the test fails.
struct Process {
    name: String,
    child: Child,
    log: Arc<Mutex<String>>,
}

impl Process {
    /// Starts `motus <args>` and waits (at most 60 s) for a line containing `ready` on
    /// stderr, or on stdout with `ready_on_stdout`.
    fn start(name: &str, args: &[&str], ready: &str, ready_on_stdout: bool) -> Process {
        let mut child = Command::new(MOTUS)
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let log = Arc::new(Mutex::new(String::new()));
        let (ready_tx, ready_rx) = std::sync::mpsc::channel::<()>();
        let streams: [(Box<dyn std::io::Read + Send>, bool); 2] =
            [(Box::new(child.stdout.take().unwrap()), true), (Box::new(child.stderr.take().unwrap()), false)];
        for (stream, is_stdout) in streams {
            let (log, ready_tx, ready) = (Arc::clone(&log), ready_tx.clone(), ready.to_owned());
            std::thread::spawn(move || {
                for line in BufReader::new(stream).lines().map_while(Result::ok) {
                    log.lock().unwrap().push_str(&format!("{line}\n"));
                    if is_stdout == ready_on_stdout && line.contains(&ready) {
                        let _ = ready_tx.send(());
                    }
                }
            });
        }
        let mut p = Process { name: name.to_owned(), child, log };
        if ready_rx.recv_timeout(Duration::from_secs(60)).is_err() {
            panic!("{name} ({args:?}) did not say {ready:?}:\n{}", p.log());
        }
        assert!(p.child.try_wait().unwrap().is_none(), "{name} exited:\n{}", p.log());
        p
    }

    fn log(&self) -> String {
        self.log.lock().unwrap().clone()
    }

    /// SIGKILL: no clean-up, like a crash or a power loss.
    fn kill(mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }

    /// Waits for the process to exit by itself.
    fn exits_within(&mut self, timeout: Duration) -> ExitStatus {
        let t0 = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                return status;
            }
            assert!(t0.elapsed() < timeout, "{} still runs after {timeout:?}:\n{}", self.name, self.log());
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        if std::thread::panicking() {
            let log = self.log();
            let tail: Vec<&str> = log.lines().rev().take(60).collect();
            let tail: Vec<&str> = tail.into_iter().rev().collect();
            eprintln!("---- last output of {} ----\n{}\n----", self.name, tail.join("\n"));
        }
    }
}

/// The hub: `motus canbus serve` on `port`.
fn hub(port: u16) -> Process {
    Process::start("hub", &["canbus", "serve", "--listen", &format!("127.0.0.1:{port}")], "ready", false)
}

/// The drive: `motus sim icla --node 2` on `bus`.
fn drive(bus: &str) -> Process {
    Process::start("drive", &["sim", "icla", "--bus", bus, "--node", NODE], "ready", false)
}

/// The arm: `motus sim kv01` on a pty at `path`.
/// The arm's simulator on `path`, its modules' safety time-out at 3 s instead of 700 ms: a
/// liveness margin, so that a station stalled by a loaded host while it connects does not
/// latch the modules (the latch has tests of its own).
fn arm(path: &Path) -> Process {
    let link = format!("pty:{}", path.display());
    let args = ["sim", "kv01", "--link", &link, "--arm", r#"{"cm":{"safety_timeout_ms":3000}}"#];
    Process::start("arm", &args, "simulating the KV-01 arm", false)
}

/// A cell whose devices all run outside the station (`simulate` absent): the CiA 402
/// drive on the hub's bus, and with `arm_path` the KV-01 arm (joints 1 and 3) on that path.
fn cell_text(bus: &str, arm_path: Option<&Path>) -> String {
    let mut text = format!(
        "[station]\nname = \"chaos\"\nlisten = \"127.0.0.1:0\"\ndata_dir = \"data\"\n\n\
         [[link]]\nname = \"vcan\"\nkind = \"can\"\nuri = \"{bus}\"\n\n\
         [[device]]\nname = \"drive\"\nkind = \"cia402\"\nlink = \"vcan\"\naddress = {NODE}\n\n\
         [[axis]]\nname = \"wheel\"\ndevice = \"drive\"\nunit = \"rad\"\nscale = 0.029452431\n\
         limits = {{ min = -1.0e6, max = 1.0e6 }}\nmax_velocity = 20.0\nmax_acceleration = 40.0\n"
    );
    if let Some(path) = arm_path {
        text.push_str(&format!(
            "\n[[link]]\nname = \"arm-line\"\nkind = \"serial\"\nuri = \"{}\"\n\n\
             [[device]]\nname = \"kv01\"\nkind = \"kv01\"\nlink = \"arm-line\"\nbaud = 115200\n",
            path.display()
        ));
        for (index, name) in [(0, "joint1"), (2, "joint3")] {
            text.push_str(&format!(
                "\n[[axis]]\nname = \"{name}\"\ndevice = \"kv01\"\nindex = {index}\nunit = \"rad\"\n\
                 scale = 1.745329e-5\nlimits = {{ min = -1.9, max = 1.9 }}\nmax_velocity = 1.0\n\
                 max_acceleration = 2.0\n"
            ));
        }
        text.push_str("\n[[group]]\nname = \"arm\"\nkind = \"arm\"\naxes = [\"joint1\", \"joint3\"]\n");
    }
    text
}

/// A running `motus serve` and an administrator's session on it.
struct Station {
    addr: String,
    cookie: String,
    csrf: String,
    _process: Process,
}

impl Station {
    /// Writes the cell into `dir`, adds the administrator (`motus user add`) and starts
    /// `motus serve` on a free port.
    fn start(dir: &Path, cell: &str) -> Station {
        let cell_file = dir.join("cell.toml");
        std::fs::write(&cell_file, cell).unwrap();
        let db: PathBuf = dir.join("station.sqlite");
        let mut add = Command::new(MOTUS)
            .args(["user", "--db", db.to_str().unwrap(), "add", "admin", "--role", "admin"])
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .spawn()
            .unwrap();
        add.stdin.take().unwrap().write_all(format!("{PASSWORD}\n").as_bytes()).unwrap();
        assert!(add.wait().unwrap().success());
        let addr = format!("127.0.0.1:{}", free_port());
        let process = Process::start(
            "station",
            &[
                "serve",
                "--config",
                cell_file.to_str().unwrap(),
                "--listen",
                &addr,
                "--db",
                db.to_str().unwrap(),
                // Several stations share two cores in the test suite: no FIFO threads.
                "--realtime",
                "nice",
            ],
            "Motus station",
            true,
        );
        let (cookie, csrf) = common::login(&addr, "admin", PASSWORD);
        Station { addr, cookie, csrf, _process: process }
    }

    fn request(&self, method: &str, path: &str, body: &str) -> (u16, String) {
        let auth = [
            ("Cookie", self.cookie.as_str()),
            ("X-CSRF-Token", self.csrf.as_str()),
            ("Content-Type", "application/json"),
        ];
        let (status, _, body) = http(&self.addr, method, path, &auth, body);
        (status, body)
    }

    fn get(&self, path: &str) -> Value {
        let (status, body) = self.request("GET", path, "");
        assert_eq!(status, 200, "GET {path}: {body}");
        serde_json::from_str(&body).unwrap()
    }

    fn post(&self, path: &str) {
        let (status, body) = self.request("POST", path, "");
        assert_eq!(status, 200, "POST {path}: {body}");
    }

    /// The axis's view in `GET /api/axes`.
    fn axis(&self, id: &str) -> Value {
        let axes = self.get("/api/axes");
        axes.as_array().unwrap().iter().find(|a| a["id"] == id).unwrap_or_else(|| panic!("{axes}")).clone()
    }

    /// Whether the axis is connected and readable: no fault in its view.
    fn connected(&self, id: &str) -> bool {
        self.axis(id)["fault"].is_null()
    }

    /// The alarms (`active` and `history`) of `device` with code `device_disconnected`.
    fn disconnect_alarms(&self, device: &str, which: &str) -> Vec<Value> {
        let alarms = self.get("/api/alarms");
        alarms[which]
            .as_array()
            .unwrap()
            .iter()
            .filter(|a| a["code"] == "device_disconnected" && a["source"] == format!("device:{device}"))
            .cloned()
            .collect()
    }

    /// Whether a disconnect alarm of `device` is raised and not cleared.
    fn disconnected_alarm_up(&self, device: &str) -> bool {
        self.disconnect_alarms(device, "active").iter().any(|a| a["cleared_at"].is_null())
    }

    /// Reset (the drive's fault), home the axis, wait until homed and at rest.
    fn reset_and_home(&self, id: &str) {
        self.post("/api/reset");
        self.post(&format!("/api/axes/{id}/home"));
        until(&format!("{id} homed"), Duration::from_secs(30), || {
            let a = self.axis(id);
            a["homed"] == true && a["moving"] == false && a["fault"].is_null()
        });
    }
}

/// Polls `done` every 100 ms until it holds; fails after `timeout` (a liveness bound).
fn until(what: &str, timeout: Duration, mut done: impl FnMut() -> bool) -> Duration {
    let t0 = Instant::now();
    while !done() {
        assert!(t0.elapsed() < timeout, "{what}: not within {timeout:?}");
        std::thread::sleep(Duration::from_millis(100));
    }
    t0.elapsed()
}

/// Reads `index:sub` (u32) of the drive by SDO with `motus canopen`, another process on
/// the bus; `None` when it does not answer.
fn sdo_read_u32(bus: &str, index: &str, sub: &str) -> Option<i64> {
    let o = Command::new(MOTUS)
        .args(["canopen", "--bus", bus, "sdo", "read", NODE, index, sub, "--type", "u32"])
        .output()
        .unwrap();
    // "0x1016:01 = 8257836 (0x7E012C) [2C 01 7E 00]": the decimal value after " = ".
    let out = String::from_utf8_lossy(&o.stdout);
    out.split_once(" = ").and_then(|(_, v)| v.split_whitespace().next()?.parse().ok())
}

#[test]
fn a_restarted_drive_process_is_brought_up_again_and_homes_after_a_reset() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let bus = format!("socketcand://127.0.0.1:{port}/can0");
    let _hub = hub(port);
    let sim = drive(&bus);
    let station = Station::start(dir.path(), &cell_text(&bus, None));
    let took = until("drive connected", Duration::from_secs(30), || station.connected("wheel"));
    eprintln!("drive connected {took:?} after the station served");
    assert_eq!(sdo_read_u32(&bus, "0x1016", "1"), Some(CONSUMER_ENTRY), "the first bring-up");
    station.reset_and_home("wheel");
    let alarms_before = station.disconnect_alarms("drive", "history").len();

    // The drive's process dies and starts again: fresh object dictionary (0x1016:1 = 0),
    // pre-operational, a boot-up message on the bus.
    sim.kill();
    let _sim = drive(&bus);
    let restarted = Instant::now();
    let mut fresh_seen = false;
    until("0x1016:1 set again", Duration::from_secs(30), || {
        let v = sdo_read_u32(&bus, "0x1016", "1");
        fresh_seen |= v == Some(0);
        v == Some(CONSUMER_ENTRY)
    });
    eprintln!(
        "bring-up ran again {:?} after the restart (the fresh drive's 0 {}seen before)",
        restarted.elapsed(),
        if fresh_seen { "" } else { "not " }
    );
    // The station saw the restart (an alarm in the history), brought the drive up again and
    // cleared the alarm.
    until("the restart's alarm cleared", Duration::from_secs(30), || {
        let history = station.disconnect_alarms("drive", "history");
        history.len() > alarms_before && history.iter().all(|a| !a["cleared_at"].is_null())
    });
    until("drive connected again", Duration::from_secs(30), || station.connected("wheel"));
    let view = station.axis("wheel");
    assert_eq!(view["homed"], false, "the restarted drive lost its reference: {view}");
    // After a reset the axis homes through the API (PDOs and state machine work).
    station.reset_and_home("wheel");
    eprintln!("homed again {:?} after the restart", restarted.elapsed());
}

#[test]
fn the_station_reconnects_after_the_hub_process_restarts() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let bus = format!("socketcand://127.0.0.1:{port}/can0");
    let hub1 = hub(port);
    let mut sim = drive(&bus);
    let station = Station::start(dir.path(), &cell_text(&bus, None));
    until("drive connected", Duration::from_secs(30), || station.connected("wheel"));
    station.reset_and_home("wheel");

    // The hub dies: the drive's simulator exits (documented: start it again when the bus
    // is back), the station marks the drive disconnected.
    hub1.kill();
    let status = sim.exits_within(Duration::from_secs(15));
    assert!(!status.success(), "{status}");
    until("drive lost", Duration::from_secs(15), || {
        !station.connected("wheel") && station.disconnected_alarm_up("drive")
    });
    // Down for a while: the station's back-off grows to its cap (2 s).
    std::thread::sleep(Duration::from_secs(3));
    assert!(!station.connected("wheel"));

    // The hub comes back on the same port, then the drive.
    let _hub = hub(port);
    let restarted = Instant::now();
    let _sim = drive(&bus);
    let drive_back = restarted.elapsed();
    let took = until("drive connected again", Duration::from_secs(30), || {
        station.connected("wheel") && !station.disconnected_alarm_up("drive")
    });
    let took = drive_back + took;
    eprintln!(
        "reconnected {took:?} after the hub restarted (the drive's simulator was back after {drive_back:?})"
    );
    // About 1-3 s, from the back-offs (they have no jitter): the bus is tried again at most
    // 2 s after the restart (`ReconnectPolicy::default`), the drive at most 1 s after that
    // (`DEVICE_BACKOFF`), then one bring-up (a few SDOs). Measured 0.7-2.8 s, also with two
    // busy loops beside the test; printed above, the 30 s time-out is liveness only.
    assert_eq!(sdo_read_u32(&bus, "0x1016", "1"), Some(CONSUMER_ENTRY), "brought up again");
    station.reset_and_home("wheel");
}

#[test]
fn the_station_starts_without_the_arm_and_connects_it_when_its_simulator_starts() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let bus = format!("socketcand://127.0.0.1:{port}/can0");
    let _hub = hub(port);
    let _sim = drive(&bus);
    let arm_path = dir.path().join("kv01");
    assert!(!arm_path.exists());
    let station = Station::start(dir.path(), &cell_text(&bus, Some(&arm_path)));

    // It serves; the arm's joints are not connected and an alarm says so; the drive works.
    until("arm alarm", Duration::from_secs(30), || station.disconnected_alarm_up("kv01"));
    let alarm = station.disconnect_alarms("kv01", "active").remove(0);
    eprintln!("alarm while the arm is absent: {}", alarm["message"]);
    assert!(alarm["message"].as_str().unwrap().contains("cannot be reached"), "{alarm}");
    for j in ["joint1", "joint3"] {
        let view = station.axis(j);
        assert!(!view["fault"].is_null(), "{j} is shown not connected: {view}");
    }
    until("drive connected", Duration::from_secs(30), || station.connected("wheel"));
    station.reset_and_home("wheel");
    assert!(!station.connected("joint1"), "still no arm");

    // The arm's simulator starts on that path: the station connects the arm.
    let _arm = arm(&arm_path);
    let took = until("arm connected", Duration::from_secs(30), || {
        station.connected("joint1") && station.connected("joint3") && !station.disconnected_alarm_up("kv01")
    });
    eprintln!("arm connected {took:?} after its simulator started");
    for j in ["joint1", "joint3"] {
        let view = station.axis(j);
        assert!(view["position"].as_f64().unwrap().is_finite(), "{view}");
    }
}
