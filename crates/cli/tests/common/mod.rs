//! Shared by the CLI tests: a simulator run as a `motus sim ...` process, ready once it
//! says so on stderr (a stale pty link left by a killed simulator does not count).
#![allow(dead_code, clippy::panic, clippy::unwrap_used, clippy::expect_used)]

use std::io::BufRead;
use std::process::{Child, Command, Stdio};

/// The binary under test.
pub const MOTUS: &str = env!("CARGO_BIN_EXE_motus");

/// A simulator process, killed on drop.
pub struct SimProcess(Child);

impl SimProcess {
    /// Runs `motus <args>` and waits for a stderr line containing `ready`.
    pub fn start(args: &[&str], ready: &str) -> SimProcess {
        let mut child =
            Command::new(MOTUS).args(args).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
        let mut lines = std::io::BufReader::new(child.stderr.take().unwrap()).lines();
        loop {
            let line = lines.next().expect("simulator exited before serving").unwrap();
            if line.contains(ready) {
                break;
            }
        }
        std::thread::spawn(move || for _ in lines {});
        SimProcess(child)
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
