//! Kill the station during motion: every drive stops by its own watchdog. Three simulated
//! IclA drives (`motus sim icla`) on a virtual CAN bus (`motus canbus serve`), each its own
//! process, are driven by `motus serve`; a wheel turns endlessly (a jog, the worst case: no
//! target to stop at). `motus serve` is killed with SIGKILL. The drives watch the station's
//! heartbeat (0x1016, set by the station when it connects): each reports EMCY 0x8130, runs
//! its fault reaction and stands still. Read back by SDO from a new process.
//! (The POWERLINK drives' lease is covered by `cli_epl_online.rs`; the KV-01 arm's 700 ms
//! safety time-out by `cli_kv01.rs` and the simulator's tests.)
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{http, SimProcess, MOTUS};

/// The station process; killed when the test ends, whatever happens.
struct Station(std::process::Child);

impl Drop for Station {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

const WHEEL: &str = r#"
[[device]]
name = "wheelN-drive"
kind = "cia402"
link = "vcan"
address = ADDR
simulate = false

[[axis]]
name = "wheelN"
device = "wheelN-drive"
unit = "rad"
scale = 0.029452431
limits = { min = -1.0e6, max = 1.0e6 }
max_velocity = 20.0
max_acceleration = 40.0
"#;

fn sdo_read(bus: &str, node: &str, index: &str, ty: &str) -> Option<i64> {
    sdo_read_sub(bus, node, index, "0", ty)
}

fn sdo_read_sub(bus: &str, node: &str, index: &str, sub: &str, ty: &str) -> Option<i64> {
    let o = Command::new(MOTUS)
        .args(["canopen", "--bus", bus, "sdo", "read", node, index, sub, "--type", ty])
        .output()
        .unwrap();
    // "0x6041:00 = 1616 (0x650) [50 06]": the decimal value after " = ".
    let out = String::from_utf8_lossy(&o.stdout);
    let value = out.split_once(" = ").and_then(|(_, v)| v.split_whitespace().next()?.parse().ok());
    if value.is_none() {
        eprintln!(
            "sdo read {node} {index}:{sub} failed: {}\nstdout: {out}\nstderr: {}",
            o.status,
            String::from_utf8_lossy(&o.stderr)
        );
    }
    value
}

#[test]
fn killing_the_station_stops_every_can_drive_by_its_heartbeat_watchdog() {
    let dir = tempfile::tempdir().unwrap();
    let can_port = free_port();
    let bus = format!("socketcand://127.0.0.1:{can_port}/can0");
    let _hub = SimProcess::start(&["canbus", "serve", "--listen", &format!("127.0.0.1:{can_port}")], "ready");
    let _drives = SimProcess::start(&["sim", "icla", "--bus", &bus, "--nodes", "2,3,4"], "ready");

    let listen = format!("127.0.0.1:{}", free_port());
    let mut cell = format!(
        "[station]\nname = \"kill test\"\nlisten = \"{listen}\"\ndata_dir = \"data\"\n\n[[link]]\nname = \"vcan\"\nkind = \"can\"\nuri = \"{bus}\"\n"
    );
    for (n, addr) in [(1, 2), (2, 3), (3, 4)] {
        cell.push_str(&WHEEL.replace("wheelN", &format!("wheel{n}")).replace("ADDR", &addr.to_string()));
    }
    let cell_file = dir.path().join("cell.toml");
    std::fs::write(&cell_file, cell).unwrap();
    let cfg = cell_file.to_str().unwrap();
    let mut add = Command::new(MOTUS)
        .args(["user", "--config", cfg, "add", "admin", "--role", "admin"])
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    add.stdin.take().unwrap().write_all(b"kill-test-password-1\n").unwrap();
    assert!(add.wait().unwrap().success());

    let mut station = Station(
        Command::new(MOTUS)
            .args(["serve", "--config", cfg, "--realtime", "nice"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let mut lines = BufReader::new(station.0.stdout.take().unwrap()).lines();
    let t0 = Instant::now();
    loop {
        let l = lines.next().expect("station exited").unwrap();
        if l.contains("Motus station") {
            break;
        }
        assert!(t0.elapsed() < Duration::from_secs(60));
    }
    std::thread::spawn(move || for _ in lines {});
    let (cookie, csrf) = common::login(&listen, "admin", "kill-test-password-1");
    let auth =
        [("Cookie", cookie.as_str()), ("X-CSRF-Token", csrf.as_str()), ("Content-Type", "application/json")];
    let axis = |id: &str| -> serde_json::Value {
        let (_, _, b) = http(&listen, "GET", "/api/axes", &auth, "");
        let v: serde_json::Value = serde_json::from_str(&b).unwrap();
        v.as_array().unwrap().iter().find(|a| a["id"] == id).unwrap().clone()
    };
    // The station connects to the drives (and sets their heartbeat consumer).
    let t0 = Instant::now();
    while !axis("wheel1")["fault"].is_null() || !axis("wheel3")["fault"].is_null() {
        assert!(t0.elapsed() < Duration::from_secs(30), "{}", axis("wheel1"));
        std::thread::sleep(Duration::from_millis(200));
    }
    // Each drive watches the station: 0x1016:1 = node 126 (0x7E), 300 ms (0x12C).
    for n in ["2", "3", "4"] {
        let t0 = Instant::now();
        loop {
            let v = sdo_read_sub(&bus, n, "0x1016", "1", "u32");
            if v == Some(0x007E_012C) {
                break;
            }
            assert!(t0.elapsed() < Duration::from_secs(20), "node {n}: 0x1016:1 = {v:?}");
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    // Home and jog wheel 1 (endless), wheels 2 and 3 to a far target.
    for w in ["wheel1", "wheel2", "wheel3"] {
        let (st, _, b) = http(&listen, "POST", &format!("/api/axes/{w}/home"), &auth, "");
        assert_eq!(st, 200, "{w}: {b}");
    }
    let t0 = Instant::now();
    while !["wheel1", "wheel2", "wheel3"]
        .iter()
        .all(|w| axis(w)["homed"] == true && axis(w)["moving"] == false)
    {
        assert!(t0.elapsed() < Duration::from_secs(30), "{}", axis("wheel1"));
        std::thread::sleep(Duration::from_millis(200));
    }
    let (st, _, b) = http(&listen, "POST", "/api/axes/wheel1/jog", &auth, r#"{"direction":1,"speed":5.0}"#);
    assert_eq!(st, 200, "{b}");
    for w in ["wheel2", "wheel3"] {
        let (st, _, b) =
            http(&listen, "POST", &format!("/api/axes/{w}/move"), &auth, r#"{"target":500.0,"speed":5.0}"#);
        assert_eq!(st, 200, "{w}: {b}");
    }
    // A jog is a dead-man: renewed every 200 ms (the station stops it 0.5 s after the last).
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_millis(1500) {
        std::thread::sleep(Duration::from_millis(200));
        let (st, _, b) =
            http(&listen, "POST", "/api/axes/wheel1/jog", &auth, r#"{"direction":1,"speed":5.0}"#);
        assert_eq!(st, 200, "{b}");
    }
    for n in ["2", "3", "4"] {
        let v = sdo_read(&bus, n, "0x606C", "i32").unwrap();
        assert!(v.abs() > 10, "node {n} turns before the kill: {v} Inc/s");
    }

    // SIGKILL the station: no clean-up, no last command.
    station.0.kill().unwrap();
    station.0.wait().unwrap();
    let killed = Instant::now();
    for n in ["2", "3", "4"] {
        let t = Instant::now();
        loop {
            let v = sdo_read(&bus, n, "0x606C", "i32");
            if v == Some(0) {
                break;
            }
            assert!(t.elapsed() < Duration::from_secs(5), "node {n} still turns: {v:?} Inc/s");
            std::thread::sleep(Duration::from_millis(50));
        }
        let code = sdo_read(&bus, n, "0x603F", "u16");
        let sw = sdo_read(&bus, n, "0x6041", "u16").unwrap();
        eprintln!(
            "node {n}: at rest {:?} after the kill, error code {code:x?}, statusword {sw:#06x}",
            killed.elapsed()
        );
        assert_eq!(code, Some(0x8130), "node {n}: heartbeat error");
        assert_eq!(sw & 0x004F, 0x0008, "node {n}: CiA 402 Fault state, statusword {sw:#06x}");
    }
}
