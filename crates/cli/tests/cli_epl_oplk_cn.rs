//! Interop: openPOWERLINK's Managing Node (`bin/demo_mn_console`, with its demo concise DCF
//! `demo_3cn_50ms.cdc` and then `demo_3cn_1ms.cdc`) boots `motus epl cn --node 1`,
//! configures it by SDO and keeps it OPERATIONAL (issue 20, acceptance 1 and 5).
//!
//! Needs root and the openPOWERLINK directory (`MOTUS_OPLK_DIR`, default
//! `<workspace>/../shared/oracles/openpowerlink`); skipped with a printed reason otherwise.
//! The segment is made by the directory's `segment.sh` (a bridge with ageing time 0 and one
//! namespace per port) with port names unique to the test, and the MN runs through its
//! `run-node.sh`. Everything runs in a private mount namespace with its own `/run/netns`
//! (`unshare --mount`): the test's namespaces are invisible to any other user of
//! `segment.sh` (whose bridge namespace is always `oplk-br`), and they disappear with the
//! test's processes, also when it fails (the test kills the whole process group).
//!
//! Pass: the MN's log shows node 1 OPERATIONAL within a generous liveness time-out, and then
//! for the hold time (`MOTUS_OPLK_SECONDS`, default 20 s) no error event and no other state
//! of node 1 (a reset or a fall-back would show as one), and the Motus CN's own log shows no
//! state change away from OPERATIONAL. The CN's PReq -> PRes turnaround (p50/p99/max) is
//! printed. `MOTUS_OPLK_CN_SPIN=1` runs the CN with `--spin`; `MOTUS_OPLK_VERBOSE=1` prints
//! the logs; `MOTUS_OPLK_MN_FIFO=<prio>` runs the MN under `chrt -f <prio>`. On a 2-core
//! host `--spin` starves the MN (the spinning SCHED_FIFO thread takes a core): not the
//! default.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use common::MOTUS;

/// One segment at a time: two MNs must never share a bridge, and the timing figures are for
/// one pair on the machine.
static SERIAL: Mutex<()> = Mutex::new(());

fn oplk_dir() -> PathBuf {
    std::env::var_os("MOTUS_OPLK_DIR").map(PathBuf::from).unwrap_or_else(|| {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/oracles/openpowerlink")
    })
}

/// Why the test cannot run here, if it cannot.
fn skip_reason(oplk: &Path) -> Option<String> {
    let uid = Command::new("id")
        .arg("-u")
        .output()
        .ok()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned());
    if uid.as_deref() != Some("0") {
        return Some("needs root (network namespaces, raw sockets)".into());
    }
    for f in ["segment.sh", "run-node.sh", "bin/demo_mn_console", "cdc/demo_3cn_50ms.cdc"] {
        if !oplk.join(f).exists() {
            return Some(format!("no {} (set MOTUS_OPLK_DIR)", oplk.join(f).display()));
        }
    }
    for tool in ["unshare", "ip"] {
        if Command::new(tool).arg("-V").output().is_err() {
            return Some(format!("no {tool}"));
        }
    }
    None
}

/// What runs the MN: nothing extra by default (openPOWERLINK's demo MN puts its own threads
/// under SCHED_RR 20), `chrt -f <prio>` with `MOTUS_OPLK_MN_FIFO=<prio>`.
fn mn_prefix() -> String {
    match std::env::var("MOTUS_OPLK_MN_FIFO").ok().as_deref() {
        None | Some("off") => String::new(),
        Some(p) => format!("chrt -f {p}"),
    }
}

fn seconds_env(name: &str, default: u64) -> Duration {
    Duration::from_secs(std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default))
}

/// The scenario's shell (in a private mount namespace); killed with its process group on
/// drop.
struct Rig {
    shell: Child,
    dir: tempfile::TempDir,
}

impl Drop for Rig {
    fn drop(&mut self) {
        let pid = self.shell.id().to_string();
        // The shell's trap stops the nodes with SIGTERM (the CN prints its summary)...
        let _ = Command::new("kill").args(["-TERM", &pid]).stderr(Stdio::null()).status();
        let end = Instant::now() + Duration::from_secs(10);
        while Instant::now() < end {
            if let Ok(Some(_)) = self.shell.try_wait() {
                break;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        // ...and whatever is left of the group is killed.
        let _ = Command::new("kill").args(["-KILL", "--", &format!("-{pid}")]).stderr(Stdio::null()).status();
        let _ = self.shell.wait();
    }
}

const SCENARIO: &str = r#"
set -u
mount -t tmpfs motus-netns /run/netns || exit 90
sh "$OPLK/segment.sh" up "$MNP" "$CNP" > "$W/segment.log" 2>&1 || { cat "$W/segment.log" >&2; exit 91; }
ip netns exec "oplk-$CNP" "$MOTUS" epl cn --if "${CNP}0" --node 1 $CNARGS > "$W/cn.log" 2>&1 &
CN=$!
sh "$OPLK/run-node.sh" "oplk-$MNP" "$W/mn" $MNPRE "$OPLK/bin/demo_mn_console" -c "$CDC" -d "${MNP}0" < /dev/null > "$W/mn.log" 2>&1 &
MN=$!
stop() { kill -TERM $CN $MN 2>/dev/null; wait $CN; wait $MN; for n in $MNP $CNP br; do ip netns del "oplk-$n" 2>/dev/null; done; exit 0; }
trap stop TERM INT
wait
"#;

impl Rig {
    fn start(oplk: &Path, cdc: &str, tag: &str) -> Rig {
        let dir = tempfile::tempdir().unwrap();
        let unique = std::process::id() % 10_000;
        let (mnp, cnp) = (format!("m{unique}{tag}"), format!("c{unique}{tag}"));
        let mut cn_args = "--realtime auto".to_owned();
        if std::env::var_os("MOTUS_OPLK_CN_SPIN").is_some() {
            cn_args.push_str(" --spin");
        }
        std::fs::create_dir_all("/run/netns").unwrap();
        let shell = Command::new("unshare")
            .args(["--mount", "--propagation", "private", "sh", "-c", SCENARIO])
            .env("OPLK", oplk)
            .env("W", dir.path())
            .env("MNP", &mnp)
            .env("CNP", &cnp)
            .env("MOTUS", MOTUS)
            .env("CNARGS", &cn_args)
            .env("MNPRE", mn_prefix())
            .env("CDC", oplk.join("cdc").join(cdc))
            .stdin(Stdio::null())
            .process_group(0)
            .spawn()
            .unwrap();
        eprintln!("{cdc}: ports {mnp} {cnp}, logs in {}", dir.path().display());
        Rig { shell, dir }
    }

    fn log(&self, name: &str) -> Vec<String> {
        std::fs::read_to_string(self.dir.path().join(name))
            .unwrap_or_default()
            .lines()
            .map(str::to_owned)
            .collect()
    }

    fn tails(&self) -> String {
        let tail = |name: &str| {
            let l = self.log(name);
            l[l.len().saturating_sub(30)..].join("\n")
        };
        format!("--- mn.log\n{}\n--- cn.log\n{}", tail("mn.log"), tail("cn.log"))
    }

    /// Fails the test when the scenario's shell has ended.
    fn check_alive(&mut self) {
        if let Ok(Some(status)) = self.shell.try_wait() {
            panic!("the scenario ended early ({status}):\n{}", self.tails());
        }
    }
}

/// An MN log line about node 1's NMT state ("Node 1 entered state NmtCsOperational",
/// "... Node=  1, NmtNodeEventNmtState State:NmtCsOperational"): the state named in it, in
/// lower case.
fn node1_state(line: &str) -> Option<String> {
    let l = line.trim();
    if let Some(rest) = l.strip_prefix("Node 1 entered state") {
        return Some(rest.trim().to_lowercase());
    }
    let (_, rest) = l.split_once("Node=  1,")?;
    rest.split_once("State:").map(|(_, s)| s.trim().to_lowercase())
}

/// Whether a state named by the MN's log is (CS_)OPERATIONAL.
fn is_operational(state: &str) -> bool {
    let s = state.replace('_', "");
    s.ends_with("operational") && !s.contains("preoperational")
}

/// An MN log line reporting an error for node 1.
fn node1_error(line: &str) -> bool {
    line.contains("Node=  1,") && (line.contains("Error") || line.contains("ERROR"))
}

fn run(cdc: &str, tag: &str) {
    let oplk = oplk_dir();
    if let Some(why) = skip_reason(&oplk) {
        eprintln!("skipped: {why}");
        return;
    }
    let _serial = SERIAL.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let hold = seconds_env("MOTUS_OPLK_SECONDS", 20);
    let mut rig = Rig::start(&oplk, cdc, tag);
    if std::env::var_os("MOTUS_OPLK_VERBOSE").is_some() {
        eprintln!("{}", rig.tails());
    }
    // Boot: node 1 OPERATIONAL in the MN's log (liveness bound: the openPOWERLINK pair takes
    // 2-8 s).
    let boot = Instant::now();
    let operational_at = loop {
        rig.check_alive();
        let mn = rig.log("mn.log");
        if let Some(i) = mn.iter().position(|l| node1_state(l).is_some_and(|s| is_operational(&s))) {
            break i;
        }
        assert!(
            boot.elapsed() < Duration::from_secs(120),
            "node 1 not OPERATIONAL within 120 s:\n{}",
            rig.tails()
        );
        std::thread::sleep(Duration::from_millis(200));
    };
    eprintln!("{cdc}: node 1 OPERATIONAL after {:.1} s", boot.elapsed().as_secs_f64());
    let cn = rig.log("cn.log");
    assert!(
        cn.iter().any(|l| l.contains("SDO write 0x1006/0")),
        "the MN wrote the cycle length by SDO:\n{}",
        rig.tails()
    );
    assert!(cn.iter().any(|l| l.contains("-> OPERATIONAL")), "{}", rig.tails());
    let cn_operational = cn.iter().rposition(|l| l.contains("-> OPERATIONAL")).unwrap();
    // Hold.
    let end = Instant::now() + hold;
    while Instant::now() < end {
        rig.check_alive();
        std::thread::sleep(Duration::from_millis(500));
        let mn = rig.log("mn.log");
        let later = mn.get(operational_at + 1..).unwrap_or_default();
        if let Some(l) = later.iter().find(|l| node1_error(l)) {
            panic!("the MN reported an error for node 1: {l}\n{}", rig.tails());
        }
        if let Some(l) = later.iter().find(|l| node1_state(l).is_some_and(|s| !is_operational(&s))) {
            panic!("node 1 left OPERATIONAL (reset?): {l}\n{}", rig.tails());
        }
        let cn = rig.log("cn.log");
        if let Some(l) =
            cn.get(cn_operational + 1..).unwrap_or_default().iter().find(|l| l.contains(": state "))
        {
            panic!("the Motus CN left OPERATIONAL: {l}\n{}", rig.tails());
        }
    }
    // Stop: the CN prints its turnaround.
    let shell_pid = rig.shell.id().to_string();
    let _ = Command::new("kill").args(["-TERM", &shell_pid]).stderr(Stdio::null()).status();
    let stopped = Instant::now();
    while rig.shell.try_wait().ok().flatten().is_none() && stopped.elapsed() < Duration::from_secs(15) {
        std::thread::sleep(Duration::from_millis(100));
    }
    let cn = rig.log("cn.log");
    let turnaround = cn.iter().find(|l| l.contains("turnaround")).cloned();
    let summary = cn.iter().find(|l| l.contains("summary")).cloned();
    eprintln!(
        "{cdc}: held OPERATIONAL {} s; {}",
        hold.as_secs(),
        turnaround.as_deref().unwrap_or("no turnaround line")
    );
    eprintln!("{cdc}: {}", summary.as_deref().unwrap_or("no summary"));
    if std::env::var_os("MOTUS_OPLK_VERBOSE").is_some() {
        eprintln!("{}", rig.tails());
    }
    assert!(turnaround.is_some(), "the CN printed no turnaround:\n{}", rig.tails());
    assert!(summary.is_some_and(|s| s.contains("cycle errors 0")), "{}", rig.tails());
}

#[test]
fn openpowerlink_mn_keeps_motus_cn_operational_50ms() {
    run("demo_3cn_50ms.cdc", "a");
}

#[test]
fn openpowerlink_mn_keeps_motus_cn_operational_1ms() {
    run("demo_3cn_1ms.cdc", "b");
}

/// The MN log lines the test reads (as openPOWERLINK V2.7.2's demo MN prints them).
#[test]
fn reads_the_mn_log() {
    let entered = "Node 1 entered state NmtCsOperational";
    let event =
        "2026/11/27-11:17:54 EVENT    NODE           Node=  1, NmtNodeEventNmtState State:NmtCsOperational";
    assert_eq!(node1_state(entered).as_deref(), Some("nmtcsoperational"));
    assert!(node1_state(entered).is_some_and(|s| is_operational(&s)));
    assert!(node1_state(event).is_some_and(|s| is_operational(&s)));
    let ready = "2026/11/27-11:17:54 EVENT    NODE           Node=  1, NmtNodeEventNmtState State:NmtCsReadyToOperate";
    assert!(node1_state(ready).is_some_and(|s| !is_operational(&s)));
    let pre = "Node 1 entered state NmtCsPreOperational2";
    assert!(node1_state(pre).is_some_and(|s| !is_operational(&s)));
    assert_eq!(node1_state("Node 10 entered state NmtCsOperational"), None);
    assert!(node1_error("2026/11/27 EVENT NODE Node=  1, NmtNodeEventError State:NmtCsPreOperational2"));
    assert!(!node1_error("2026/11/27 EVENT NODE Node= 32, NmtNodeEventError State:NmtCsNotActive"));
}
