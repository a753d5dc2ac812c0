//! Shared by the CLI tests: a simulator run as a `motus sim ...` process, ready once it
//! says so on stderr (a stale pty link left by a killed simulator does not count).
#![allow(dead_code, clippy::panic, clippy::unwrap_used, clippy::expect_used)]

pub mod oplk;

use std::io::{BufRead, Read, Write};
use std::process::{Child, Command, Stdio};

/// The binary under test.
pub const MOTUS: &str = env!("CARGO_BIN_EXE_motus");

/// A simulator process, killed on drop.
pub struct SimProcess(Child);

impl SimProcess {
    /// Runs `motus <args>` and waits for a stderr line containing `ready`.
    pub fn start(args: &[&str], ready: &str) -> SimProcess {
        Self::start_logged(args, ready).0
    }

    /// [`SimProcess::start`], and the simulator's later stderr lines as they come.
    pub fn start_logged(args: &[&str], ready: &str) -> (SimProcess, std::sync::mpsc::Receiver<String>) {
        let mut child =
            Command::new(MOTUS).args(args).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
        let mut lines = std::io::BufReader::new(child.stderr.take().unwrap()).lines();
        loop {
            let line = lines.next().expect("simulator exited before serving").unwrap();
            if line.contains(ready) {
                break;
            }
        }
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in lines.map_while(Result::ok) {
                let _ = tx.send(line);
            }
        });
        (SimProcess(child), rx)
    }

    /// Kills the simulator (SIGKILL: no clean-up, like a crash or power loss).
    pub fn kill(mut self) {
        self.0.kill().unwrap();
        self.0.wait().unwrap();
    }
}

impl Drop for SimProcess {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// One HTTP/1.1 request (Connection: close); returns (status, headers, body).
pub fn http(
    addr: &str,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &str,
) -> (u16, String, String) {
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    // A liveness bound: the station's web threads run at nice +10, so beside CPU hogs a login
    // (an Argon2 hash) may take many seconds.
    s.set_read_timeout(Some(std::time::Duration::from_secs(60))).unwrap();
    let mut req = format!(
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\nContent-Length: {}\r\n",
        body.len()
    );
    for (k, v) in headers {
        req.push_str(&format!("{k}: {v}\r\n"));
    }
    req.push_str("\r\n");
    req.push_str(body);
    s.write_all(req.as_bytes()).unwrap();
    let mut resp = String::new();
    s.read_to_string(&mut resp).unwrap();
    let (head, body) = resp.split_once("\r\n\r\n").unwrap_or((&resp, ""));
    let status = head.split_whitespace().nth(1).unwrap().parse().unwrap();
    (status, head.to_owned(), body.to_owned())
}

/// Logs in to a station's API: (session cookie `name=value`, CSRF token).
pub fn login(addr: &str, user: &str, password: &str) -> (String, String) {
    let body = serde_json::json!({ "user": user, "password": password }).to_string();
    let (st, head, b) = http(addr, "POST", "/api/login", &[("Content-Type", "application/json")], &body);
    assert_eq!(st, 200, "{b}");
    let cookie = head
        .lines()
        .find_map(|l| l.strip_prefix("set-cookie: ").or_else(|| l.strip_prefix("Set-Cookie: ")))
        .unwrap()
        .split(';')
        .next()
        .unwrap()
        .to_owned();
    let v: serde_json::Value = serde_json::from_str(&b).unwrap();
    (cookie, v["csrf_token"].as_str().unwrap().to_owned())
}

/// The shipped juggler rules (`crates/safety/examples/juggler.toml`) for a 1 ms cycle, as a
/// POWERLINK segment of separate processes runs them: written to `dir`, their path returned.
pub fn juggler_rules_1ms(dir: &std::path::Path) -> std::path::PathBuf {
    let shipped = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../safety/examples/juggler.toml");
    let text = std::fs::read_to_string(shipped).unwrap();
    let text = text
        .replace("cycle_time = 0.0004", "cycle_time = 0.001")
        .replace("lease_time = 0.0008", "lease_time = 0.005");
    let p = dir.join("juggler.toml");
    std::fs::write(&p, text).unwrap();
    p
}
