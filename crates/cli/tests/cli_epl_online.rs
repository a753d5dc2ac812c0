//! `motus sim epl`, `motus epl monitor`, `motus safety approve` and `motus safety run` as
//! separate processes on the unprivileged UDP segment (loopback).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::{SimProcess, MOTUS};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A base port with 16 free UDP ports after it (best effort: probed now).
fn free_segment() -> u16 {
    for _ in 0..50 {
        let s = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let base = s.local_addr().unwrap().port();
        drop(s);
        if base < 60_000 && (0..16).all(|i| std::net::UdpSocket::bind(("127.0.0.1", base + i)).is_ok()) {
            return base;
        }
    }
    panic!("no free block of 16 UDP ports");
}

/// A running process whose stdout lines arrive on a channel.
struct Lines {
    child: Child,
    rx: mpsc::Receiver<String>,
}

/// Sends one operator command line to the process's standard input.
fn operator(l: &mut Lines, cmd: &str) {
    use std::io::Write;
    let stdin = l.child.stdin.as_mut().unwrap();
    writeln!(stdin, "{cmd}").unwrap();
    stdin.flush().unwrap();
}

impl Lines {
    fn start(args: &[&str]) -> Lines {
        let mut child = Command::new(MOTUS)
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .unwrap();
        let out = child.stdout.take().unwrap();
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for l in BufReader::new(out).lines().map_while(Result::ok) {
                if tx.send(l).is_err() {
                    break;
                }
            }
        });
        Lines { child, rx }
    }

    /// Waits up to `timeout` for a line containing all of `needles`.
    fn wait_for(&self, needles: &[&str], timeout: Duration) -> String {
        let end = Instant::now() + timeout;
        let mut seen = Vec::new();
        while let Some(left) = end.checked_duration_since(Instant::now()) {
            match self.rx.recv_timeout(left) {
                Ok(l) if needles.iter().all(|n| l.contains(n)) => return l,
                Ok(l) => seen.push(l),
                Err(_) => break,
            }
        }
        panic!(
            "no line with {needles:?} within {timeout:?}; saw {:?}",
            &seen[seen.len().saturating_sub(10)..]
        );
    }
}

impl Drop for Lines {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `motus safety approve` of `rules` (and `drives`) signed with `key` by `admin` into
/// `approval`.
fn safety_approve(rules: &Path, drives: Option<&Path>, key: &Path, admin: &str, approval: &Path) -> Output {
    let mut c = Command::new(MOTUS);
    c.args(["safety", "approve", "--rules", path(rules)]);
    if let Some(d) = drives {
        c.args(["--drives", path(d)]);
    }
    c.args(["--key", path(key), "--admin", admin, "--out", path(approval)]).output().unwrap()
}

/// `motus safety run` of `rules` (and `drives`) on segment `seg`, approved by `approval`.
fn safety_run(rules: &Path, drives: Option<&Path>, seg: &str, approval: &Path, key: &Path) -> Lines {
    let mut args = vec!["safety", "run", "--rules", path(rules)];
    if let Some(d) = drives {
        args.extend(["--drives", path(d)]);
    }
    args.extend(["--if", seg, "--approval", path(approval), "--key", path(key)]);
    Lines::start(&args)
}

#[test]
fn online_supervisor_stops_a_student_program_and_blocks_on_an_unapproved_change() {
    let dir = tempfile::tempdir().unwrap();
    let rules = common::juggler_rules_1ms(dir.path());
    let key = dir.path().join("admin.key");
    std::fs::write(&key, "a-secret-administrator-key-0123456789\n").unwrap();
    let approval = dir.path().join("juggler.approved");
    let seg = format!("udp://127.0.0.1:{}", free_segment());

    // Administrator approves the rules.
    let o = safety_approve(&rules, None, &key, "alice", &approval);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["approved"].as_str().unwrap().len(), 64);

    // The supervisor, then the machine running a student program that aims beyond a limit.
    let mut sup = safety_run(&rules, None, &seg, &approval, &key);
    std::thread::sleep(Duration::from_millis(300));
    let _sim = SimProcess::start(
        &["sim", "epl", "--if", &seg, "--config", path(&rules), "--program", "limit"],
        "segment OPERATIONAL",
    );
    // The drives' layout (status 0, position 16, speed 20) for nodes 1..=5.
    let monitor_map = dir.path().join("map.toml");
    let mut map = String::new();
    for n in 1..=5 {
        map.push_str(&format!(
            "[[node]]\nnode = {n}\nvalues = [{{ name = \"position\", offset = 16, type = \"i32\" }}, {{ name = \"speed\", offset = 20, type = \"i32\" }}]\n"
        ));
    }
    std::fs::write(&monitor_map, map).unwrap();
    // On a loaded machine a late frame may stop the drives before the program gets far (the
    // lease expires); the operator then resets, as on the real machine.
    let deadline = Instant::now() + Duration::from_secs(20);
    let stop = loop {
        assert!(Instant::now() < deadline, "no stop by limits_thrower");
        let l = sup.wait_for(&["\"event\""], Duration::from_secs(10));
        let v: serde_json::Value = serde_json::from_str(&l).unwrap();
        let reaction = v["reaction_us"].as_f64();
        if l.contains("\"unsafe\"") && l.contains("limits_thrower") {
            // No reaction: the drives were already stopped (an expired lease held them);
            // the operator resets and the supervisor stops them again, now for the limit.
            match reaction {
                Some(r) => break (l, r),
                None => operator(&mut sup, "reset"),
            }
        } else if l.contains("\"held\":true") {
            operator(&mut sup, "reset");
        }
    };
    let (stop, reaction) = stop;
    assert!(reaction > 0.0, "{stop}");
    eprintln!("stop: {stop}");

    // A monitor in a third process sees every drive stopped by the revoked lease.
    let mon = Lines::start(&["epl", "monitor", "--if", &seg, "--map", path(&monitor_map), "--cycles", "400"]);
    let mut last = serde_json::Value::Null;
    for _ in 0..400 {
        let l = mon.wait_for(&["\"cycle\""], Duration::from_secs(5));
        last = serde_json::from_str(&l).unwrap();
    }
    let nodes = last["nodes"].as_array().unwrap();
    assert_eq!(nodes.len(), 5, "{last}");
    for n in nodes {
        assert_eq!(n["values"]["speed"].as_f64(), Some(0.0), "{n}");
        assert!(n["values"]["position"].as_f64().unwrap() < 34_000.0, "{n}");
    }

    // A student edits the rules (widens the thrower's limit) without the admin action.
    let text = std::fs::read_to_string(&rules).unwrap();
    let edited = text.replace("limits = { min = -7600, max = 3400 }", "limits = { min = -7600, max = 9400 }");
    assert_ne!(edited, text);
    std::fs::write(&rules, edited).unwrap();
    let blocked = sup.wait_for(&["\"event\":\"integrity\"", "\"ok\":false"], Duration::from_secs(5));
    assert!(blocked.contains("axis[thrower].limits.max: 3400.0 -> 9400.0"), "{blocked}");

    // A forged approval (signed with another key) is refused too.
    let other_key = dir.path().join("other.key");
    std::fs::write(&other_key, "not-the-administrator-key-000000").unwrap();
    let o = safety_approve(&rules, None, &other_key, "mallory", &approval);
    assert!(o.status.success());
    let still =
        sup.wait_for(&["\"event\":\"integrity\"", "signature does not match"], Duration::from_secs(5));
    assert!(still.contains("\"ok\":false"), "{still}");
}

#[test]
fn safety_run_watches_the_approved_drive_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let rules = common::juggler_rules_1ms(dir.path());
    let drives = dir.path().join("juggler-drives.toml");
    let shipped = std::fs::read_to_string(root().join("crates/safety/examples/juggler-drives.toml")).unwrap();
    std::fs::write(&drives, &shipped).unwrap();
    let key = dir.path().join("admin.key");
    std::fs::write(&key, "a-secret-administrator-key-0123456789\n").unwrap();
    let approval = dir.path().join("juggler.approved");
    let seg = format!("udp://127.0.0.1:{}", free_segment());
    let approve = || {
        let o = safety_approve(&rules, Some(&drives), &key, "alice", &approval);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    approve();
    let sup = safety_run(&rules, Some(&drives), &seg, &approval, &key);
    sup.wait_for(&["\"event\":\"integrity\"", "\"ok\":true"], Duration::from_secs(10));
    // The thrower's quick-stop deceleration lowered on disk, without approval: named.
    std::fs::write(&drives, shipped.replace("a_stop = 20000000.0", "a_stop = 15000000.0")).unwrap();
    let blocked = sup.wait_for(&["\"event\":\"integrity\"", "\"ok\":false"], Duration::from_secs(10));
    assert!(blocked.contains("drive[thrower].a_stop: 20000000.0 -> 15000000.0"), "{blocked}");
    // The administrator approves the change (the approval names it): accepted again.
    let stderr = approve();
    assert!(stderr.contains("approving change: drive[thrower].a_stop: 20000000.0 -> 15000000.0"), "{stderr}");
    sup.wait_for(&["\"event\":\"integrity\"", "\"ok\":true"], Duration::from_secs(10));
}
