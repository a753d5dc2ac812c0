//! Interop: openPOWERLINK's Managing Node (`bin/demo_mn_console`, with its demo concise DCF
//! `demo_3cn_50ms.cdc` and then `demo_3cn_1ms.cdc`) boots `motus epl cn --node 1`,
//! configures it by SDO and keeps it OPERATIONAL (issue 20, acceptance 1 and 5): at 50 ms
//! with the CN's dictionary read from openPOWERLINK's XDD (`--od`), at 1 ms with the built-in
//! one.
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
//! Pass: the MN's log shows node 1 OPERATIONAL within a generous liveness time-out, configured
//! by SDO. At 50 ms, for the hold time (`MOTUS_OPLK_SECONDS`, default 5 s; 60 s in CI) no
//! error event and no other state of node 1 (a reset or a fall-back would show as one), and
//! the Motus CN's own log shows no state change away from OPERATIONAL. At 1 ms both nodes
//! must answer within 200 us every cycle, which a loaded host's scheduler can break (the
//! openPOWERLINK MN logs its own cycle overruns, E_DLL_CYCLE_EXCEED 0x8232, then a lost PRes,
//! 0x8243, and resets the node): there the resets in the hold and the CN's turnaround are
//! real-time figures, written to `target/realtime/from-suite/oplk_cn_1ms.log` for
//! `scripts/realtime.sh` (target: 0 resets, turnaround p99 < 100 us) and not asserted; what
//! is asserted is that the MN boots and configures the CN, and that after every reset the CN
//! is booted again and OPERATIONAL at the end of the hold. The CN's PReq -> PRes turnaround
//! (p50/p99/max) is printed. The CN runs with `--cpu 1` (`MOTUS_OPLK_CN_CPU=<n>` another
//! CPU, `none` unpinned): openPOWERLINK's Linux demos bind all their threads to CPU 1, and a
//! CN there is woken by the PReq on its own CPU; unpinned on the 2-core VM it was sometimes
//! not running for 4-8 ms after the PReq arrived (the idle CPU it slept on ran it only at its
//! next timer tick), 1-5 resets in 60 s, against none pinned. `MOTUS_OPLK_CN_WAIT=<mode>`
//! passes `--wait` (sleep, anticipate, spin); `MOTUS_OPLK_VERBOSE=1` prints
//! the logs; `MOTUS_OPLK_KEEP=<dir>` keeps them (and with `MOTUS_OPLK_CAPTURE=1` the CN's
//! traffic, `cn.pcapng`, taken by `dumpcap`); `MOTUS_OPLK_MN_FIFO=<prio>` runs the MN under `chrt -f <prio>`. On a 2-core
//! host `--wait spin` starves the MN (the spinning SCHED_FIFO thread takes a core), and on
//! the MN's CPU so does `--wait anticipate` (its polling holds up the MN's SoC): not the
//! default.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::time::{Duration, Instant};

use common::oplk::{
    hold, is_operational, node1_error, node1_resets, node1_state, oplk_dir, percentile_us, skip_reason,
    write_figures, ResetCause, Rig, SERIAL,
};

const SCENARIO: &str = r#"
set -u
mount -t tmpfs motus-netns /run/netns || exit 90
sh "$OPLK/segment.sh" up "$MNP" "$CNP" > "$W/segment.log" 2>&1 || { cat "$W/segment.log" >&2; exit 91; }
[ -n "${MOTUS_OPLK_CAPTURE:-}" ] && { ip netns exec "oplk-$CNP" dumpcap -q -i "${CNP}0" -w "$W/cn.pcapng" 2> "$W/dumpcap.log" & sleep 1; }
ip netns exec "oplk-$CNP" "$MOTUS" epl cn --if "${CNP}0" --node 1 $CNARGS > "$W/cn.log" 2>&1 &
CN=$!
sh "$OPLK/run-node.sh" "oplk-$MNP" "$W/mn" $MNPRE "$OPLK/bin/demo_mn_console" -c "$CDC" -d "${MNP}0" < /dev/null > "$W/mn.log" 2>&1 &
MN=$!
stop() { kill -TERM $CN $MN 2>/dev/null; wait $CN; wait $MN; for n in $MNP $CNP br; do ip netns del "oplk-$n" 2>/dev/null; done; exit 0; }
trap stop TERM INT
wait
"#;

const LOGS: [&str; 2] = ["mn.log", "cn.log"];

/// What the hold asserts.
#[derive(Clone, Copy, PartialEq)]
enum Hold {
    /// No error, no reset, no state change of node 1.
    Strict,
    /// Resets are a real-time figure (see the module documentation), written under this name.
    Measured(&'static str),
}

fn run(cdc: &str, tag: &str, policy: Hold) {
    run_with(cdc, tag, policy, "");
}

/// [`run`] with more arguments for `motus epl cn`.
fn run_with(cdc: &str, tag: &str, policy: Hold, extra_cn_args: &str) {
    let oplk = oplk_dir();
    if let Some(why) = skip_reason(&oplk) {
        eprintln!("skipped: {why}");
        return;
    }
    let _serial = SERIAL.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let hold = hold();
    let unique = std::process::id() % 10_000;
    let (mnp, cnp) = (format!("m{unique}{tag}"), format!("c{unique}{tag}"));
    let mut cn_args = format!("--realtime auto {extra_cn_args}");
    // openPOWERLINK's Linux demos bind all their threads to CPU 1: the CN's thread goes there
    // too, where the MN's frames arrive (see the module documentation).
    match std::env::var("MOTUS_OPLK_CN_CPU") {
        Ok(v) if v == "none" => {}
        Ok(v) => cn_args.push_str(&format!(" --cpu {v}")),
        Err(_) if motus_realtime::affinity::allowed_cpus().contains(&1) => cn_args.push_str(" --cpu 1"),
        Err(_) => {}
    }
    if let Ok(wait) = std::env::var("MOTUS_OPLK_CN_WAIT") {
        cn_args.push_str(&format!(" --wait {wait}"));
    }
    let cdc_path = oplk.join("cdc").join(cdc).to_string_lossy().into_owned();
    let mut rig = Rig::start(
        &oplk,
        SCENARIO,
        &[("MNP", mnp.clone()), ("CNP", cnp.clone()), ("CNARGS", cn_args), ("CDC", cdc_path)],
    );
    eprintln!("{cdc}: ports {mnp} {cnp}, logs in {}", rig.dir.path().display());
    if std::env::var_os("MOTUS_OPLK_VERBOSE").is_some() {
        eprintln!("{}", rig.tails(&LOGS));
    }
    let boot = Instant::now();
    let operational_at = rig.wait_node1_operational(&LOGS);
    eprintln!("{cdc}: node 1 OPERATIONAL after {:.1} s", boot.elapsed().as_secs_f64());
    let cn = rig.log("cn.log");
    assert!(
        cn.iter().any(|l| l.contains("SDO write 0x1006/0")),
        "the MN wrote the cycle length by SDO:\n{}",
        rig.tails(&LOGS)
    );
    assert!(cn.iter().any(|l| l.contains("-> OPERATIONAL")), "{}", rig.tails(&LOGS));
    let cn_operational = cn.iter().rposition(|l| l.contains("-> OPERATIONAL")).unwrap();
    // Hold.
    let end = Instant::now() + hold;
    while Instant::now() < end {
        rig.check_alive(&LOGS);
        std::thread::sleep(Duration::from_millis(500));
        if policy != Hold::Strict {
            continue;
        }
        let mn = rig.log("mn.log");
        let later = mn.get(operational_at + 1..).unwrap_or_default();
        if let Some(l) = later.iter().find(|l| node1_error(l)) {
            panic!("the MN reported an error for node 1: {l}\n{}", rig.tails(&LOGS));
        }
        if let Some(l) = later.iter().find(|l| node1_state(l).is_some_and(|s| !is_operational(&s))) {
            panic!("node 1 left OPERATIONAL (reset?): {l}\n{}", rig.tails(&LOGS));
        }
        let cn = rig.log("cn.log");
        if let Some(l) =
            cn.get(cn_operational + 1..).unwrap_or_default().iter().find(|l| l.contains(": state "))
        {
            panic!("the Motus CN left OPERATIONAL: {l}\n{}", rig.tails(&LOGS));
        }
    }
    // Measured: every reset in the hold was followed by a new boot; node 1 is OPERATIONAL at
    // the end of it (liveness bound: the MN re-boots a node within seconds).
    let mut resets = Vec::new();
    if let Hold::Measured(_) = policy {
        let settled = Instant::now() + Duration::from_secs(60);
        loop {
            rig.check_alive(&LOGS);
            let mn = rig.log("mn.log");
            let later = mn.get(operational_at + 1..).unwrap_or_default();
            resets = node1_resets(later);
            let last = later.iter().rev().find_map(|l| node1_state(l));
            if last.as_deref().is_none_or(is_operational) {
                break;
            }
            assert!(
                Instant::now() < settled,
                "node 1 was not booted again after {} reset(s): {last:?}\n{}",
                resets.len(),
                rig.tails(&LOGS)
            );
            std::thread::sleep(Duration::from_millis(500));
        }
    }
    // Stop: the CN prints its turnaround.
    rig.stop();
    if let Some(keep) = std::env::var_os("MOTUS_OPLK_KEEP") {
        let keep = std::path::PathBuf::from(keep).join(format!("{tag}-{unique}"));
        let _ = std::fs::create_dir_all(&keep);
        for name in LOGS.iter().chain(&["cn.pcapng"]) {
            let _ = std::fs::copy(rig.dir.path().join(name), keep.join(name));
        }
        eprintln!("{cdc}: logs kept in {}", keep.display());
    }
    let cn = rig.log("cn.log");
    let turnaround = cn.iter().find(|l| l.contains("turnaround")).cloned();
    let summary = cn.iter().find(|l| l.contains("summary")).cloned();
    let count = |cause| resets.iter().filter(|c| **c == cause).count();
    let lost_pres = count(ResetCause::LostPres);
    eprintln!(
        "{cdc}: held {} s, {} reset(s) by the MN ({} after its own cycle overruns, {lost_pres} for a lost PRes, {} other); {}",
        hold.as_secs(),
        resets.len(),
        count(ResetCause::MnCycleOverrun),
        count(ResetCause::Other),
        turnaround.as_deref().unwrap_or("no turnaround line")
    );
    eprintln!("{cdc}: {}", summary.as_deref().unwrap_or("no summary"));
    if std::env::var_os("MOTUS_OPLK_VERBOSE").is_some() {
        eprintln!("{}", rig.tails(&LOGS));
    }
    let turnaround =
        turnaround.unwrap_or_else(|| panic!("the CN printed no turnaround:\n{}", rig.tails(&LOGS)));
    match policy {
        Hold::Strict => {
            assert!(summary.is_some_and(|s| s.contains("cycle errors 0")), "{}", rig.tails(&LOGS));
        }
        Hold::Measured(name) => {
            let mut figures = vec![
                (format!("suite.{name}.resets"), resets.len() as f64, "count"),
                (format!("suite.{name}.resets_lost_pres"), lost_pres as f64, "count"),
            ];
            for p in ["p50", "p99"] {
                if let Some(v) = percentile_us(&turnaround, p) {
                    figures.push((format!("suite.{name}.turnaround.{p}"), v, "us"));
                }
            }
            write_figures(name, &figures);
        }
    }
}

/// At 50 ms, the CN's dictionary read from openPOWERLINK's own device description
/// (`--od`): the MN configures and holds it. The built-in dictionary equals it entry for
/// entry but for documented deviations (`motus-epl-protocol`'s `cn_profile` test) and is
/// booted, configured and held at 1 ms below, so one 50 ms boot (12-17 s of the suite,
/// alone on the machine) serves both.
#[test]
fn openpowerlink_mn_keeps_a_motus_cn_from_its_xdd_operational_50ms() {
    let xdd = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../epl-protocol/tests/data/00000000_POWERLINK_CiA401_CN.xdd");
    run_with("demo_3cn_50ms.cdc", "x", Hold::Strict, &format!("--od {}", xdd.display()));
}

#[test]
fn openpowerlink_mn_boots_motus_cn_at_1ms_and_its_resets_are_measured() {
    run("demo_3cn_1ms.cdc", "b", Hold::Measured("oplk_cn_1ms"));
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
    let progress = "2026/11/27-19:35:55 EVENT    CFM_PROGRESS   Node=  1, Object 0x1010/001,  158/ 162 Bytes -> SDO Abort=SDO_AC_OBJECT_NOT_EXIST(0x06020000), Error=0x0000";
    assert!(!node1_error(progress));
}

/// Resets are counted once each (the MN logs a state twice) and told apart by what the MN
/// logged before them (two excerpts of openPOWERLINK V2.7.2's demo MN at 1 ms).
#[test]
fn tells_resets_apart() {
    let log = |text: &str| text.lines().map(str::to_owned).collect::<Vec<_>>();
    let overrun = log("\
2026/11/27-19:36:58 EVENT    HISTORY        HistoryEntry: Type=0x3002 Code=0x8232 (0x1F 00 00 00 FD 02 00 00)
2026/11/27-19:36:58 EVENT    HISTORY        HistoryEntry: Type=0x3002 Code=0x8233 (0x1E 00 00 00 FD 02 00 00)
2026/11/27-19:36:58 EVENT    STATE_CHANGE   NmtMsOperational->NmtMsPreOperational1 Originating event:NmtEventNmtCycleError
2026/11/27-19:36:58 EVENT    NODE           Node=  1, NmtNodeEventNmtState State:NmtCsNotActive
Node 1 entered state NmtCsNotActive
2026/11/27-19:37:00 EVENT    NODE           Node=  1, NmtNodeEventNmtState State:NmtCsOperational
Node 1 entered state NmtCsOperational
2026/11/27-19:35:52 EVENT    HISTORY        HistoryEntry: Type=0x3002 Code=0x8243 (0x01 00 00 00 FD 02 00 00)
2026/11/27-19:35:52 EVENT    NODE           Node=  1, NmtNodeEventError State:NmtCsNotActive
2026/11/27-19:35:53 EVENT    NODE           Node=  1, NmtNodeEventNmtState State:NmtCsPreOperational2
Node 1 entered state NmtCsPreOperational2
2026/11/27-19:37:00 EVENT    NODE           Node=  1, NmtNodeEventNmtState State:NmtCsOperational");
    assert_eq!(node1_resets(&overrun), [ResetCause::MnCycleOverrun, ResetCause::LostPres]);
    assert!(node1_resets(&log("Node 1 entered state NmtCsOperational")).is_empty());
}
