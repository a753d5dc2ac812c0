//! `motus sim icla` exits when its CAN bus goes away (the hub process dies): with a clear
//! message and a non-zero status, in both of its modes (drives, and the robot's drives).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::MOTUS;
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A free loopback port (bound then released).
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// `motus <args>`, ready once stderr says `ready`; stderr is kept.
struct Process {
    child: Child,
    stderr: Arc<Mutex<String>>,
    /// The thread collecting stderr: joined once the process has exited, so that its last
    /// lines are in (a loaded host may run it after the exit is seen).
    reader: Option<std::thread::JoinHandle<()>>,
}

impl Process {
    fn start(args: &[&str], ready: &str) -> Process {
        let mut child =
            Command::new(MOTUS).args(args).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
        let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
        let stderr = Arc::new(Mutex::new(String::new()));
        loop {
            let line = lines.next().unwrap_or_else(|| panic!("{args:?} exited before serving")).unwrap();
            stderr.lock().unwrap().push_str(&format!("{line}\n"));
            if line.contains(ready) {
                break;
            }
        }
        let keep = Arc::clone(&stderr);
        let reader = std::thread::spawn(move || {
            for line in lines.map_while(Result::ok) {
                keep.lock().unwrap().push_str(&format!("{line}\n"));
            }
        });
        Process { child, stderr, reader: Some(reader) }
    }

    /// Waits for the process to exit by itself (generous time-out).
    fn exits_within(&mut self, timeout: Duration) -> ExitStatus {
        let t0 = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                // The pipe is closed with the process: its reader ends with the last line
                // (a liveness bound all the same).
                if let Some(reader) = self.reader.take() {
                    let t1 = Instant::now();
                    while !reader.is_finished() && t1.elapsed() < timeout {
                        std::thread::sleep(Duration::from_millis(20));
                    }
                }
                return status;
            }
            assert!(t0.elapsed() < timeout, "still running after {timeout:?}; stderr:\n{}", self.stderr());
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    fn stderr(&self) -> String {
        self.stderr.lock().unwrap().clone()
    }
}

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[test]
fn sim_icla_exits_with_a_clear_error_when_its_bus_closes() {
    let port = free_port();
    let listen = format!("127.0.0.1:{port}");
    let bus = format!("socketcand://127.0.0.1:{port}/can0");
    let mut hub = Process::start(&["canbus", "serve", "--listen", &listen], "ready");
    let mut drives = Process::start(&["sim", "icla", "--bus", &bus, "--nodes", "2,3"], "ready");
    let mut robot =
        Process::start(&["sim", "icla", "--bus", &bus, "--nodes", "5,6,7", "--slip", "0,0,0"], "ready");
    std::thread::sleep(Duration::from_millis(300));
    assert!(drives.child.try_wait().unwrap().is_none() && robot.child.try_wait().unwrap().is_none());

    hub.child.kill().unwrap(); // SIGKILL: the hub dies, every connection closes
    hub.child.wait().unwrap();
    for (name, p) in [("drives", &mut drives), ("robot", &mut robot)] {
        let status = p.exits_within(Duration::from_secs(15));
        let err = p.stderr();
        eprintln!("{name}: {status}; stderr:\n{err}");
        assert!(!status.success(), "{name}: a simulator that lost its bus fails: {status}");
        assert!(err.contains(&format!("error: the CAN bus {bus} is gone")), "{name}: {err}");
        assert!(err.contains("start the simulator again"), "{name}: {err}");
    }
}
