//! Interop: `motus epl mn` (the Motus Managing Node, from openPOWERLINK's own concise DCF)
//! boots openPOWERLINK's demo CN (`bin/demo_cn_console -n 1`) over a veth pair between two
//! network namespaces, configures it by SDO, exchanges the demo's process data both ways, and
//! boots it again after its process is killed and restarted (issue 20, acceptance 2).
//!
//! Needs root and the openPOWERLINK binaries (`MOTUS_OPLK_DIR`, default
//! `<workspace>/../shared/oracles/openpowerlink`); skipped with a printed reason otherwise.
//! The hold time in OPERATIONAL is `MOTUS_OPLK_SECONDS` (default 5 s; the 60 s in CI); `MOTUS_OPLK_REALTIME`
//! is the MN's `--realtime` (default auto). The CN runs through
//! the directory's `run-node.sh` (its own IPC namespace and /dev/shm). Every time-out is a
//! generous liveness bound; the namespaces and processes are removed also when it fails.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use common::oplk::{oplk_dir, skip_reason};
use common::MOTUS;

fn sh(args: &[&str]) {
    let out = Command::new(args[0]).args(&args[1..]).output().unwrap();
    assert!(out.status.success(), "{}: {}", args.join(" "), String::from_utf8_lossy(&out.stderr));
}

/// Lines a process printed (stdout and stderr), collected by reader threads.
#[derive(Clone, Default)]
struct Log(Arc<Mutex<Vec<String>>>);

impl Log {
    fn follow(&self, r: impl std::io::Read + Send + 'static, prefix: &'static str) {
        let lines = Arc::clone(&self.0);
        std::thread::spawn(move || {
            for line in BufReader::new(r).lines() {
                let Ok(line) = line else { break };
                if std::env::var_os("MOTUS_OPLK_VERBOSE").is_some() {
                    eprintln!("{prefix}{line}");
                }
                lines.lock().unwrap().push(line);
            }
        });
    }

    fn len(&self) -> usize {
        self.0.lock().unwrap().len()
    }

    fn since(&self, from: usize) -> Vec<String> {
        self.0.lock().unwrap().get(from..).map(<[String]>::to_vec).unwrap_or_default()
    }

    fn find_since(&self, from: usize, pred: impl Fn(&str) -> bool) -> Option<String> {
        self.since(from).into_iter().find(|l| pred(l))
    }

    fn wait_for(&self, from: usize, what: &str, timeout: Duration, pred: impl Fn(&str) -> bool) -> String {
        let end = Instant::now() + timeout;
        while Instant::now() < end {
            if let Some(l) = self.find_since(from, &pred) {
                return l;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        panic!("{what}: not within {timeout:?}; last lines:\n{}", self.tail(40));
    }

    fn tail(&self, n: usize) -> String {
        let l = self.0.lock().unwrap();
        l[l.len().saturating_sub(n)..].join("\n")
    }
}

/// The namespaces and processes of the test; removed on drop (also after a failure).
struct Rig {
    ns: [String; 2],
    children: Vec<Child>,
    dir: tempfile::TempDir,
}

impl Drop for Rig {
    fn drop(&mut self) {
        for c in &mut self.children {
            let _ = c.kill();
            let _ = c.wait();
        }
        for n in &self.ns {
            let _ = Command::new("ip").args(["netns", "del", n]).status();
        }
    }
}

impl Rig {
    /// Two namespaces joined by one veth pair: `mn0` (the MN's) and `cn0` (the CN's).
    fn new() -> Rig {
        let id = std::process::id();
        let ns = [format!("motus-oplkmn-{id}-mn"), format!("motus-oplkmn-{id}-cn")];
        let rig = Rig { ns: ns.clone(), children: Vec::new(), dir: tempfile::tempdir().unwrap() };
        for n in &ns {
            sh(&["ip", "netns", "add", n]);
            sh(&["ip", "netns", "exec", n, "sysctl", "-qw", "net.ipv6.conf.all.disable_ipv6=1"]);
            sh(&["ip", "netns", "exec", n, "sysctl", "-qw", "net.ipv6.conf.default.disable_ipv6=1"]);
            sh(&["ip", "-n", n, "link", "set", "lo", "up"]);
        }
        sh(&[
            "ip",
            "-n",
            &ns[0],
            "link",
            "add",
            "mn0",
            "address",
            "02:00:00:00:20:f0",
            "type",
            "veth",
            "peer",
            "name",
            "cn0",
            "address",
            "02:00:00:00:20:01",
            "netns",
            &ns[1],
        ]);
        sh(&["ip", "-n", &ns[0], "link", "set", "mn0", "up"]);
        sh(&["ip", "-n", &ns[1], "link", "set", "cn0", "up"]);
        rig
    }

    /// Starts openPOWERLINK's CN 1 (fresh working directory `run`); returns its stdin and
    /// the index of its process in `children`.
    fn start_cn(&mut self, oplk: &Path, run: &str, log: &Log) -> (ChildStdin, usize) {
        let work = self.dir.path().join(run);
        let mut child = Command::new("sh")
            .arg(oplk.join("run-node.sh"))
            .arg(&self.ns[1])
            .arg(&work)
            .arg(oplk.join("bin/demo_cn_console"))
            .args(["-n", "1", "-d", "cn0"])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        log.follow(child.stdout.take().unwrap(), "cn| ");
        log.follow(child.stderr.take().unwrap(), "cn! ");
        let stdin = child.stdin.take().unwrap();
        self.children.push(child);
        (stdin, self.children.len() - 1)
    }
}

/// A CN log line, lower case without `_`: the stack prints states as `NMT_CS_OPERATIONAL`
/// or `NmtCsOperational` depending on where.
fn normalized(l: &str) -> String {
    l.to_lowercase().replace('_', "")
}

/// The CN's log says it is OPERATIONAL.
fn cn_operational(l: &str) -> bool {
    let l = normalized(l);
    l.contains("csoperational") && !l.contains("preoperational")
}

/// The CN's log says it left OPERATIONAL (a lower state, a reset).
fn cn_left_operational(l: &str) -> bool {
    let l = normalized(l);
    [
        "preoperational",
        "readytooperate",
        "notactive",
        "resetcommunication",
        "resetconfiguration",
        "resetapplication",
        "csstopped",
    ]
    .iter()
    .any(|s| l.contains(s))
}

/// The CN's digital outputs as it prints them after a 'p' ("Digital outputs: ..."): the hex
/// bytes of the line.
fn printed_outputs(lines: &[String]) -> Vec<String> {
    lines
        .iter()
        .filter(|l| l.contains("Digital outputs"))
        .map(|l| l.split_once("Digital outputs:").map_or("", |x| x.1).trim().to_owned())
        .collect()
}

#[test]
fn motus_mn_boots_configures_and_reboots_the_openpowerlink_cn() {
    let oplk = oplk_dir();
    if let Some(why) = skip_reason(&oplk) {
        eprintln!("skipped: {why}");
        return;
    }
    let cdc = oplk.join("cdc/demo_3cn_1ms.cdc");
    assert!(cdc.is_file(), "no {} in the openPOWERLINK directory", cdc.display());
    let hold = common::oplk::hold().as_secs();
    let mut rig = Rig::new();
    let cn_log = Log::default();
    let mn_log = Log::default();

    // The CN first (as on a machine: CNs power up, wait for the MN's SoA).
    let (mut cn_in, cn_index) = rig.start_cn(&oplk, "cn-a", &cn_log);
    std::thread::sleep(Duration::from_secs(1));
    let total = hold + 120;
    let mut mn = Command::new("ip")
        .args(["netns", "exec", &rig.ns[0], MOTUS, "epl", "mn", "--if", "mn0", "--cdc"])
        .arg(&cdc)
        .args(["--seconds", &total.to_string(), "--counter-every", "100"])
        .args(["--realtime", &std::env::var("MOTUS_OPLK_REALTIME").unwrap_or_else(|_| "auto".into())])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    mn_log.follow(mn.stdout.take().unwrap(), "mn| ");
    mn_log.follow(mn.stderr.take().unwrap(), "mn! ");
    rig.children.push(mn);
    let mn_index = rig.children.len() - 1;

    // 1. OPERATIONAL, configured by SDO (every CDC entry of node 1 written, no error).
    let boot = Instant::now();
    mn_log.wait_for(0, "Motus MN: node 1 OPERATIONAL", Duration::from_secs(60), |l| {
        l.contains("node 1: boot operational")
    });
    cn_log.wait_for(0, "openPOWERLINK CN: OPERATIONAL", Duration::from_secs(30), cn_operational);
    eprintln!("the openPOWERLINK CN is OPERATIONAL {:?} after the MN started", boot.elapsed());
    let mn_lines = mn_log.since(0);
    assert!(
        mn_lines.iter().any(|l| l.contains("node 1: configured 0x1a00/0 (14/14)")),
        "{}",
        mn_log.tail(80)
    );
    assert!(!mn_lines.iter().any(|l| l.contains("configuration error")), "{}", mn_log.tail(80));

    // 2. Hold: no loss, process data both ways.
    let hold_from_mn = mn_log.len();
    let hold_from_cn = cn_log.len();
    let hold_end = Instant::now() + Duration::from_secs(hold);
    let mut presses = 0u32;
    while Instant::now() < hold_end {
        std::thread::sleep(Duration::from_secs(1));
        // 'i' raises the CN's digital inputs, 'p' prints the outputs it received.
        let _ = cn_in.write_all(b"i");
        let _ = cn_in.write_all(b"p");
        let _ = cn_in.flush();
        presses += 1;
    }
    let mn_hold = mn_log.since(hold_from_mn);
    let cn_hold = cn_log.since(hold_from_cn);
    assert!(
        !mn_hold.iter().any(|l| l.contains("node 1: lost")),
        "CN lost during the hold:\n{}",
        mn_hold.join("\n")
    );
    assert!(
        !cn_hold.iter().any(|l| cn_left_operational(l)),
        "the CN left OPERATIONAL during the hold:\n{}",
        cn_hold.join("\n")
    );
    // Motus's outputs (a counter advancing every 100 cycles) arrive at the CN.
    let outs = printed_outputs(&cn_hold);
    let distinct: std::collections::BTreeSet<&String> = outs.iter().collect();
    eprintln!(
        "CN printed {} output lines, {} distinct: {:?}",
        outs.len(),
        distinct.len(),
        outs.iter().take(5).collect::<Vec<_>>()
    );
    assert!(distinct.len() >= 3, "outputs seen by the CN: {outs:?}\n{}", cn_log.tail(40));
    // The CN's inputs (raised by 'i') are read by Motus.
    let ins: std::collections::BTreeSet<String> = mn_hold
        .iter()
        .filter(|l| l.starts_with("pd node 1:"))
        .filter_map(|l| l.split(" in ").nth(1).map(|x| x.split(' ').next().unwrap_or("").to_owned()))
        .collect();
    eprintln!("Motus read the CN's inputs {ins:?} ({presses} presses)");
    assert!(ins.len() >= 3, "{}", mn_hold.join("\n"));

    // 3. Kill the CN's process and start it again: booted again automatically.
    let from = mn_log.len();
    {
        let c = &mut rig.children[cn_index];
        c.kill().unwrap();
        c.wait().unwrap();
    }
    mn_log.wait_for(from, "Motus MN: node 1 lost after the kill", Duration::from_secs(30), |l| {
        l.contains("node 1: lost")
    });
    let (_cn_in2, _) = rig.start_cn(&oplk, "cn-b", &cn_log);
    let restart = Instant::now();
    mn_log.wait_for(from, "Motus MN: node 1 OPERATIONAL again", Duration::from_secs(90), |l| {
        l.contains("node 1: boot operational")
    });
    eprintln!("restarted CN OPERATIONAL again {:?} after its restart", restart.elapsed());
    std::thread::sleep(Duration::from_secs(3));

    // 4. Stop the MN (SIGINT: it prints its summary) and report the SoC jitter.
    let pid = rig.children[mn_index].id();
    let _ = Command::new("kill").args(["-INT", &pid.to_string()]).status();
    let status = rig.children[mn_index].wait().unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let summary: Vec<String> = mn_log.since(0).into_iter().filter(|l| l.starts_with("summary")).collect();
    eprintln!("{}", summary.join("\n"));
    assert!(status.success(), "motus epl mn: {status}\n{}", mn_log.tail(40));
    assert!(summary.iter().any(|l| l.contains("SoC jitter")), "{}", mn_log.tail(40));
    // The MN's timing, a real-time figure for scripts/realtime.sh (target: SoC jitter p99
    // below 100 us with real-time scheduling).
    if let Some(line) = summary.iter().find(|l| l.contains("SoC jitter")) {
        let jitter = line.split_once("SoC jitter").map_or("", |(_, rest)| rest);
        let turnaround = line.split_once("PReq->PRes").map_or("", |(_, rest)| rest);
        let mut figures = Vec::new();
        if let Some(v) = common::oplk::percentile_us(jitter, "p99") {
            figures.push(("suite.oplk_mn_1ms.jitter.p99".to_owned(), v, "us"));
        }
        if let Some(v) = common::oplk::percentile_us(turnaround, "p99") {
            figures.push(("suite.oplk_mn_1ms.pres.p99".to_owned(), v, "us"));
        }
        common::oplk::write_figures("oplk_mn_1ms", &figures);
    }
}
