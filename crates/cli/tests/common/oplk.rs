//! Shared by the interop tests with openPOWERLINK's demo nodes (`cli_epl_oplk_cn.rs`,
//! `cli_epl_oplk_monitor.rs`): where the binaries are, why a test cannot run, the scenario
//! shell in a private mount namespace, and the MN log lines the tests read.

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// One openPOWERLINK segment at a time: two MNs must never share a bridge, and the timing
/// figures are for one pair on the machine.
pub static SERIAL: Mutex<()> = Mutex::new(());

/// The openPOWERLINK directory: `MOTUS_OPLK_DIR`, default
/// `<workspace>/../shared/oracles/openpowerlink`.
pub fn oplk_dir() -> PathBuf {
    std::env::var_os("MOTUS_OPLK_DIR").map(PathBuf::from).unwrap_or_else(|| {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/oracles/openpowerlink")
    })
}

/// Why the test cannot run here, if it cannot.
pub fn skip_reason(oplk: &Path) -> Option<String> {
    let uid = Command::new("id")
        .arg("-u")
        .output()
        .ok()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned());
    if uid.as_deref() != Some("0") {
        return Some("needs root (network namespaces, raw sockets)".into());
    }
    for f in
        ["segment.sh", "run-node.sh", "bin/demo_mn_console", "bin/demo_cn_console", "cdc/demo_3cn_50ms.cdc"]
    {
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
pub fn mn_prefix() -> String {
    match std::env::var("MOTUS_OPLK_MN_FIFO").ok().as_deref() {
        None | Some("off") => String::new(),
        Some(p) => format!("chrt -f {p}"),
    }
}

/// How long a test holds its segment in operation: `MOTUS_OPLK_SECONDS`, default 5 s on a
/// developer's machine (CI sets the 60 s).
pub fn hold() -> Duration {
    seconds_env("MOTUS_OPLK_SECONDS", 5)
}

/// A number of seconds from the environment variable `name`, else `default`.
pub fn seconds_env(name: &str, default: u64) -> Duration {
    Duration::from_secs(std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default))
}

/// A scenario shell (in a private mount namespace with its own `/run/netns`, so its
/// namespaces are invisible to any other user of `segment.sh` and disappear with it); killed
/// with its process group on drop. Its logs are files in [`Rig::dir`].
pub struct Rig {
    /// The shell.
    pub shell: Child,
    /// Its working directory (`$W` in the script).
    pub dir: tempfile::TempDir,
}

impl Drop for Rig {
    fn drop(&mut self) {
        let pid = self.shell.id().to_string();
        // The shell's trap stops the nodes with SIGTERM (they print their summaries)...
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

impl Rig {
    /// Runs `script` with `env` (plus `OPLK`, `W`, `MOTUS`, `MNPRE`) in a private mount namespace.
    pub fn start(oplk: &Path, script: &str, env: &[(&str, String)]) -> Rig {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all("/run/netns").unwrap();
        let mut c = Command::new("unshare");
        c.args(["--mount", "--propagation", "private", "sh", "-c", script])
            .env("OPLK", oplk)
            .env("W", dir.path())
            .env("MOTUS", super::MOTUS)
            .env("MNPRE", mn_prefix())
            .stdin(Stdio::null())
            .process_group(0);
        for (k, v) in env {
            c.env(k, v);
        }
        let shell = c.spawn().unwrap();
        Rig { shell, dir }
    }

    /// The lines of log file `name`.
    pub fn log(&self, name: &str) -> Vec<String> {
        std::fs::read_to_string(self.dir.path().join(name))
            .unwrap_or_default()
            .lines()
            .map(str::to_owned)
            .collect()
    }

    /// The last 30 lines of each of `names`.
    pub fn tails(&self, names: &[&str]) -> String {
        let mut out = String::new();
        for name in names {
            let l = self.log(name);
            out.push_str(&format!("--- {name}\n{}\n", l[l.len().saturating_sub(30)..].join("\n")));
        }
        out
    }

    /// Fails the test when the scenario's shell has ended.
    pub fn check_alive(&mut self, names: &[&str]) {
        if let Ok(Some(status)) = self.shell.try_wait() {
            panic!("the scenario ended early ({status}):\n{}", self.tails(names));
        }
    }

    /// Waits (liveness bound: 120 s; the openPOWERLINK MN takes 2-8 s) until the MN's log
    /// (`mn.log`) shows node 1 OPERATIONAL; returns the index of that line.
    pub fn wait_node1_operational(&mut self, names: &[&str]) -> usize {
        let boot = Instant::now();
        loop {
            self.check_alive(names);
            let mn = self.log("mn.log");
            if let Some(i) = mn.iter().position(|l| node1_state(l).is_some_and(|s| is_operational(&s))) {
                return i;
            }
            assert!(
                boot.elapsed() < Duration::from_secs(120),
                "node 1 not OPERATIONAL within 120 s:\n{}",
                self.tails(names)
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    /// Asks the shell to stop (its trap stops the nodes) and waits up to 15 s for it.
    pub fn stop(&mut self) {
        let shell_pid = self.shell.id().to_string();
        let _ = Command::new("kill").args(["-TERM", &shell_pid]).stderr(Stdio::null()).status();
        let stopped = Instant::now();
        while self.shell.try_wait().ok().flatten().is_none() && stopped.elapsed() < Duration::from_secs(15) {
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

/// An MN log line about node 1's NMT state ("Node 1 entered state NmtCsOperational",
/// "... Node=  1, NmtNodeEventNmtState State:NmtCsOperational"): the state named in it, in
/// lower case.
pub fn node1_state(line: &str) -> Option<String> {
    let l = line.trim();
    if let Some(rest) = l.strip_prefix("Node 1 entered state") {
        return Some(rest.trim().to_lowercase());
    }
    let (_, rest) = l.split_once("Node=  1,")?;
    rest.split_once("State:").map(|(_, s)| s.trim().to_lowercase())
}

/// Whether a state named by the MN's log is (CS_)OPERATIONAL.
pub fn is_operational(state: &str) -> bool {
    let s = state.replace('_', "");
    s.ends_with("operational") && !s.contains("preoperational")
}

/// An MN log line reporting an error event for node 1 (`NmtNodeEventError`, or a line of
/// severity ERROR). The configuration manager's progress lines ("... Error=0x0000") are not.
pub fn node1_error(line: &str) -> bool {
    line.contains("Node=  1,") && (line.contains("NmtNodeEventError") || line.contains(" ERROR "))
}

/// Why the MN took node 1 out of OPERATIONAL, from what it logged since node 1 was last
/// OPERATIONAL (openPOWERLINK's error codes, `oplk/errordefs.h`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ResetCause {
    /// The MN's own cycle overran its threshold (`E_DLL_CYCLE_EXCEED_TH` 0x8233, the MN
    /// leaving operation on `NmtEventNmtCycleError`): every node is reset, whatever it did.
    MnCycleOverrun,
    /// The MN missed node 1's PRes past its threshold (`E_DLL_LOSS_PRES_TH` 0x8243 for node
    /// 1): the CN answered late or not at all, or the MN heard it late.
    LostPres,
    /// Anything else.
    Other,
}

/// Each time node 1 left OPERATIONAL in `lines` (MN log lines that start while node 1 is
/// OPERATIONAL), with its cause.
pub fn node1_resets(lines: &[String]) -> Vec<ResetCause> {
    let mut resets = Vec::new();
    let mut operational = true;
    let (mut overrun, mut lost_pres) = (false, false);
    for l in lines {
        if l.contains("Code=0x8233") || l.contains("NmtEventNmtCycleError") {
            overrun = true;
        }
        if l.contains("Code=0x8243 (0x01 ") {
            lost_pres = true;
        }
        let Some(state) = node1_state(l) else { continue };
        match (operational, is_operational(&state)) {
            (true, false) => {
                resets.push(if overrun {
                    ResetCause::MnCycleOverrun
                } else if lost_pres {
                    ResetCause::LostPres
                } else {
                    ResetCause::Other
                });
                operational = false;
            }
            (false, true) => {
                operational = true;
                (overrun, lost_pres) = (false, false);
            }
            _ => {}
        }
    }
    resets
}

/// The value of percentile `p` ("p50", "p99") in a summary line such as "turnaround PReq ->
/// PRes p50 16.1 us p99 26.5 us max 206.8 us" or "SoC jitter p50 0.1 us p99 1.0 us".
pub fn percentile_us(line: &str, p: &str) -> Option<f64> {
    let mut words = line.split_whitespace();
    words.find(|w| *w == p)?;
    words.next()?.parse().ok()
}

/// Writes `REALTIME <name> <value> <unit>` lines to `target/realtime/from-suite/<file>.log`,
/// which `scripts/realtime.sh` puts in its table (a real-time figure of the suite, printed
/// and reported, not asserted).
pub fn write_figures(file: &str, figures: &[(String, f64, &str)]) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/realtime/from-suite");
    let text: String = figures.iter().map(|(k, v, u)| format!("REALTIME {k} {v} {u}\n")).collect();
    eprint!("{text}");
    if let Err(e) =
        std::fs::create_dir_all(&dir).and_then(|()| std::fs::write(dir.join(format!("{file}.log")), text))
    {
        eprintln!("cannot write the figures to {}: {e}", dir.display());
    }
}
