//! The README's command blocks run as written, against the simulators: every fenced `sh`
//! block (except the two `sh no-test` set-up commands: the demo runs until Ctrl-C and the
//! full tests would run themselves) is run by bash from the repository's root with `set -e`
//! and `pipefail`, so a command that fails (a refused KV-01 move in a session included)
//! fails the test. The only changes to the text: `target/release/motus` is the binary under
//! test, `/tmp/` a temporary directory of this test, the fixed ports free ones, and
//! `cargo build` lines are dropped (the binary is built already).
//!
//! Also the newcomer's mistakes the README avoids: a mistyped cell file for `motus user`, a
//! demo cell written over an existing directory.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::MOTUS;

/// Every block gets this long (a liveness bound: the robot's square and the station's start
/// take seconds, beside CPU hogs many more).
const BLOCK_TIME_OUT: Duration = Duration::from_secs(300);

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A fenced block of the README: its info string and its text.
struct Block {
    info: String,
    text: String,
    line: usize,
}

fn blocks(readme: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut open: Option<Block> = None;
    for (k, l) in readme.lines().enumerate() {
        match (&mut open, l.strip_prefix("```")) {
            (None, Some(info)) => {
                open = Some(Block { info: info.trim().to_string(), text: String::new(), line: k + 1 });
            }
            (Some(_), Some(_)) => out.extend(open.take()),
            (Some(b), None) => {
                b.text.push_str(l);
                b.text.push('\n');
            }
            (None, None) => {}
        }
    }
    assert!(open.is_none(), "README: a fenced block is not closed");
    out
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

fn free_udp_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// The block as the test runs it (see the module's comment).
fn as_run(text: &str, tmp: &Path, ports: &[(&str, u16)]) -> String {
    let mut s: String = text
        .lines()
        .filter(|l| !l.trim_start().starts_with("cargo build"))
        .map(|l| format!("{l}\n"))
        .collect();
    s = s.replace("target/release/motus", MOTUS).replace("/tmp/", &format!("{}/", tmp.display()));
    for (fixed, free) in ports {
        s = s.replace(&format!("127.0.0.1:{fixed}"), &format!("127.0.0.1:{free}"));
    }
    // Every background job of the block is stopped when it ends, as a user's Ctrl-C would.
    format!("set -euo pipefail\nM={MOTUS}\ntrap 'kill $(jobs -p) 2>/dev/null || true' EXIT\n{s}")
}

/// Runs one block in a process group of its own; returns (success, output).
fn run_block(script: &str) -> (bool, String) {
    use std::os::unix::process::CommandExt;
    let mut child = Command::new("bash")
        .arg("-c")
        .arg(script)
        .current_dir(root())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0)
        .spawn()
        .unwrap();
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = out.read_to_string(&mut s);
        s
    });
    let err_reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = err.read_to_string(&mut s);
        s
    });
    let deadline = Instant::now() + BLOCK_TIME_OUT;
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break Some(s);
        }
        if Instant::now() > deadline {
            break None;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    // Whatever the block left behind (a simulator that ignored the trap) goes with it.
    let _ = Command::new("kill")
        .args(["-KILL", "--", &format!("-{}", child.id())])
        .stderr(Stdio::null())
        .status();
    let _ = child.wait();
    let text = format!("stdout:\n{}\nstderr:\n{}", reader.join().unwrap(), err_reader.join().unwrap());
    match status {
        Some(s) => (s.success(), format!("{s}\n{text}")),
        None => (false, format!("no end within {BLOCK_TIME_OUT:?}\n{text}")),
    }
}

#[test]
fn every_command_block_of_the_readme_runs_as_written() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let all = blocks(&readme);
    let (skipped, run): (Vec<&Block>, Vec<&Block>) = all.iter().partition(|b| b.info == "sh no-test");
    // Only the two set-up commands are shown without being run here.
    let skipped: Vec<&str> = skipped.iter().map(|b| b.text.trim()).collect();
    assert_eq!(skipped, ["cargo run --release -p motus -- demo", "bash scripts/test.sh"]);
    assert!(run.iter().all(|b| b.info == "sh"), "README blocks must be `sh` or `sh no-test`");
    assert!(run.len() >= 7, "README: {} runnable blocks", run.len());
    let mut failures = Vec::new();
    for b in run {
        let tmp = tempfile::tempdir().unwrap();
        let ports = [("29536", free_port()), ("8080", free_port()), ("3819", free_udp_port())];
        let script = as_run(&b.text, tmp.path(), &ports);
        let started = Instant::now();
        let (ok, output) = run_block(&script);
        eprintln!(
            "README block at line {}: {} in {:.1} s",
            b.line,
            if ok { "ok" } else { "FAILED" },
            started.elapsed().as_secs_f64()
        );
        if !ok {
            failures.push(format!("README block at line {}:\n{}\n{output}", b.line, b.text));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

#[test]
fn user_refuses_a_cell_file_that_does_not_exist() {
    let dir = tempfile::tempdir().unwrap();
    let cell = dir.path().join("cell.toml");
    let mut child = Command::new(MOTUS)
        .args(["user", "--config", cell.to_str().unwrap(), "add", "alice", "--role", "student"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    {
        use std::io::Write;
        writeln!(child.stdin.as_mut().unwrap(), "a long passphrase").unwrap();
    }
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("cell file") && err.contains("not found"), "{err}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "nothing created");
}

#[test]
fn demo_write_cell_writes_a_cell_the_station_loads_and_never_overwrites() {
    let dir = tempfile::tempdir().unwrap();
    let cell_dir = dir.path().join("cell");
    let o = Command::new(MOTUS).args(["demo", "--write-cell", cell_dir.to_str().unwrap()]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let cell = PathBuf::from(String::from_utf8(o.stdout).unwrap().trim());
    assert_eq!(cell, cell_dir.join("demo-cell.toml"));
    for f in [
        "demo-cell.toml",
        "programs/drill-plate.ngc",
        "juggler.toml",
        "data/admin.key",
        "data/juggler.approved",
    ] {
        assert!(cell_dir.join(f).is_file(), "{f}");
    }
    motus_station::config::load(&cell).unwrap();
    let again =
        Command::new(MOTUS).args(["demo", "--write-cell", cell_dir.to_str().unwrap()]).output().unwrap();
    assert_eq!(again.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&again.stderr).contains("is not empty"));
}
