//! Shared scenario for the UDP and veth tests: an MN and five drive CNs, a monitor on its own
//! link reading positions and speeds every cycle, then a quick stop.
//!
//! The tests check function only (boot-up, every drive read and following its cam, the quick
//! stop), with generous liveness time-outs. The real-time figures of the same scenario (cycles
//! with a missed node, MN start jitter, PReq -> PRes) are printed here and measured by
//! `cargo bench -p motus-epl --bench monitor` (it includes this module), which
//! `scripts/realtime.sh` runs and compares with the targets.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, dead_code)]

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use motus_epl::sim::{CamAxis, CamProgram, DriveParams, MnConfig, MnStats, Segment};
use motus_epl::{CycleSample, EthLink, Monitor, MonitorConfig};
use motus_epl_protocol::{NmtState, Value, ValueMap};

pub const NODES: [u8; 5] = [1, 2, 3, 4, 5];

/// The acopos map (position at PRes payload offset 16, speed at 20) for nodes 1..=5.
pub fn map() -> ValueMap {
    let mut text = String::new();
    for n in NODES {
        text.push_str(&format!(
            "[[node]]\nnode = {n}\nvalues = [{{ name = \"status\", offset = 0, type = \"u16\" }}, {{ name = \"position\", offset = 16, type = \"i32\" }}, {{ name = \"speed\", offset = 20, type = \"i32\" }}]\n"
        ));
    }
    ValueMap::from_toml(&text).unwrap()
}

/// Length of the monitored run in seconds: MOTUS_EPL_SECONDS, else `default`.
pub fn seconds(default: f64) -> f64 {
    std::env::var("MOTUS_EPL_SECONDS").ok().and_then(|s| s.parse().ok()).unwrap_or(default)
}

pub fn cam() -> Vec<CamAxis> {
    NODES
        .iter()
        .map(|&n| CamAxis {
            center: 1000.0 * f64::from(n),
            amplitude: 2000.0,
            period: 1.0,
            phase: 0.1 * f64::from(n),
        })
        .collect()
}

pub fn drive_params(axis: &CamAxis) -> DriveParams {
    DriveParams { initial_position: axis.at(0.0), ..DriveParams::default() }
}

fn as_i32(v: Option<Value>) -> i32 {
    match v {
        Some(Value::I32(x)) => x,
        other => panic!("expected an i32, got {other:?}"),
    }
}

#[derive(Default)]
struct Shared {
    latest: Option<CycleSample>,
    counting: bool,
    counted: u64,
    misses: Vec<String>,
    min_max: Vec<(i32, i32)>,
    missed_cycles: u64,
    stopping: bool,
    after_stop: Vec<CycleSample>,
}

/// What a run measured (real-time figures: printed by the tests, compared with their targets
/// by the bench).
pub struct Outcome {
    /// The MN's statistics over the monitored window.
    pub mn: MnStats,
    /// Cycles the monitor saw in the window.
    pub monitored_cycles: u64,
    /// Nominal cycles in the window (its length / the cycle time).
    pub nominal_cycles: f64,
    /// Monitored cycles with at least one node stale or invalid.
    pub missed_cycles: u64,
    /// Stale or invalid node readings (each listed in the report file).
    pub node_misses: u64,
}

impl Outcome {
    /// Monitored cycles with a missed node, in percent.
    pub fn missed_percent(&self) -> f64 {
        100.0 * self.missed_cycles as f64 / self.monitored_cycles.max(1) as f64
    }
}

/// Runs the scenario for `seconds` of monitoring; asserts boot-up, every drive read and
/// following its cam, and the quick stop (each drive at rest within its braking distance).
/// The misses, the MN's jitter and its PReq -> PRes round trips are printed and returned,
/// not asserted: they follow the host's load.
pub fn run_scenario(
    label: &str,
    mn_link: Arc<dyn EthLink>,
    cn_links: Vec<Arc<dyn EthLink>>,
    monitor_link: Arc<dyn EthLink>,
    config: MnConfig,
    seconds: f64,
) -> Outcome {
    assert_eq!(cn_links.len(), NODES.len());
    let axes = cam();
    let shared = Arc::new(Mutex::new(Shared {
        min_max: vec![(i32::MAX, i32::MIN); NODES.len()],
        ..Shared::default()
    }));
    let stop = Arc::new(AtomicBool::new(false));
    let monitor_thread = {
        let shared = Arc::clone(&shared);
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            let mut monitor = Monitor::new(map(), MonitorConfig { stale_after: 0 });
            monitor
                .run(&*monitor_link, &stop, |s| {
                    let mut sh = shared.lock().unwrap();
                    if sh.counting {
                        sh.counted += 1;
                        if !s.all_fresh() {
                            sh.missed_cycles += 1;
                        }
                        for n in &s.nodes {
                            if n.stale || !n.valid || n.error.is_some() {
                                let m = format!(
                                    "cycle {}: node {} age {:?} valid {} state {:?} err {:?} (polled {:?}, pres {:?})",
                                    s.index,
                                    n.node,
                                    n.age,
                                    n.valid,
                                    n.nmt_state,
                                    n.error,
                                    s.report.polled,
                                    s.report.pres.iter().map(|p| p.node).collect::<Vec<_>>()
                                );
                                sh.misses.push(m);
                            } else {
                                let i = NODES.iter().position(|x| *x == n.node).unwrap();
                                let p = as_i32(n.value("position"));
                                let (lo, hi) = sh.min_max[i];
                                sh.min_max[i] = (lo.min(p), hi.max(p));
                            }
                        }
                    }
                    if sh.stopping {
                        sh.after_stop.push(s.clone());
                    }
                    sh.latest = Some(s.clone());
                    ControlFlow::Continue(())
                })
        })
    };

    let mut b = Segment::builder()
        .config(config)
        .spin_cns(config.spin_for_pres)
        .mn_link(mn_link)
        .program(Box::new(CamProgram::new(axes.clone())));
    for ((node, link), axis) in NODES.iter().zip(cn_links).zip(&axes) {
        b = b.drive(*node, link, drive_params(axis));
    }
    // The two polling threads on two CPUs, when there are two: the CNs on the first, the MN
    // on the second, where this VM's kernel does its periodic work (an interruption delays
    // the MN's cycle but loses the CNs' PRes: docs/decisions.md).
    if let (true, [first, second, ..]) =
        (config.spin_for_pres, motus_realtime::affinity::allowed_cpus().as_slice())
    {
        b = b.pin_mn(*second).pin_spinning_cns(*first);
    }
    let t0 = Instant::now();
    let segment = b.start().unwrap();
    // Boot-up: reduced PreOp1 cycles, IdentRequests, PreOp2, NMT commands, OPERATIONAL
    // (about a second; the time-out is liveness only).
    assert!(segment.wait_operational(Duration::from_secs(20)), "{label}: MN state {}", segment.mn_state());
    let boot = t0.elapsed();
    for n in NODES {
        assert_eq!(segment.cn_state(n), Some(NmtState::Operational), "{label}: node {n}");
    }
    // Let one full cycle pass with the operational state in every PRes, then count.
    std::thread::sleep(config.cycle * 5);
    segment.reset_stats();
    shared.lock().unwrap().counting = true;
    let window = Instant::now();
    std::thread::sleep(Duration::from_secs_f64(seconds));
    let window = window.elapsed().as_secs_f64();
    let mn_stats = segment.stats();
    let (counted, missed_cycles, misses, min_max, before) = {
        let mut sh = shared.lock().unwrap();
        sh.counting = false;
        (sh.counted, sh.missed_cycles, sh.misses.clone(), sh.min_max.clone(), sh.latest.clone().unwrap())
    };

    let j = mn_stats.jitter();
    let r = mn_stats.rtt();
    let nominal_cycles = window / config.cycle.as_secs_f64();
    eprintln!(
        "{label}: boot {:?}; {} cycles monitored of {:.0} nominal, {} with a stale/invalid node ({:.3} %, {} node misses); MN: {} cycles, jitter p50 {} us p99 {} us max {} us, \
         PReq->PRes p50 {} us p99 {} us max {} us, PRes misses {:?}, late {}, overruns {}",
        boot,
        counted,
        nominal_cycles,
        missed_cycles,
        100.0 * missed_cycles as f64 / counted.max(1) as f64,
        misses.len(),
        mn_stats.cycles,
        j.p50 / 1000,
        j.p99 / 1000,
        j.max / 1000,
        r.p50 / 1000,
        r.p99 / 1000,
        r.max / 1000,
        mn_stats.pres_missed,
        mn_stats.pres_late,
        mn_stats.overruns,
    );
    for m in misses.iter().take(20) {
        eprintln!("{label}: miss {m}");
    }
    // Every miss, one per line, in a report file.
    let report = std::env::temp_dir().join(format!("motus-epl-misses-{}.txt", label.replace(' ', "-")));
    if std::fs::write(&report, misses.join("\n")).is_ok() {
        eprintln!("{label}: all {} node misses listed in {}", misses.len(), report.display());
    }
    // Quick stop. The first PRes whose status word shows the quick-stop bit (set when the
    // drive received the flag in its PReq) gives position p_q and speed v_q; braking starts at
    // the next SoC, so the drive must come to rest within |v_q| * 1 cycle + v_q²/(2 a_b) of
    // p_q (plus 2 units of rounding).
    shared.lock().unwrap().stopping = true;
    segment.quick_stop(true);
    // Braking takes a few milliseconds at these speeds; wait (liveness only) until the monitor
    // shows every drive at rest with the quick-stop bit in its status word.
    let at_rest = |s: &CycleSample| {
        NODES.iter().all(|&n| {
            s.node(n).is_some_and(|x| {
                !x.stale
                    && x.valid
                    && matches!(x.value("speed"), Some(Value::I32(0)))
                    && matches!(x.value("status"), Some(Value::U16(w)) if w & 0x0002 != 0)
            })
        })
    };
    let t_stop = Instant::now();
    let (after, trace) = loop {
        std::thread::sleep(Duration::from_millis(20));
        let sh = shared.lock().unwrap();
        let latest = sh.latest.clone().unwrap();
        if at_rest(&latest) && sh.after_stop.len() > 5 {
            break (latest, sh.after_stop.clone());
        }
        assert!(
            t_stop.elapsed() < Duration::from_secs(10),
            "{label}: drives not at rest 10 s after the quick stop: {latest:?}"
        );
    };
    eprintln!("{label}: every drive at rest {:?} after the quick stop", t_stop.elapsed());
    let brake = DriveParams::default().brake_decel;
    for n in NODES {
        let first_qs = trace
            .iter()
            .find(|s| matches!(s.node(n).unwrap().value("status"), Some(Value::U16(w)) if w & 0x0002 != 0))
            .unwrap_or_else(|| panic!("{label}: node {n} never reported quick stop"));
        let q = first_qs.node(n).unwrap();
        let (pq, vq) = (f64::from(as_i32(q.value("position"))), f64::from(as_i32(q.value("speed"))));
        let a0 = after.node(n).unwrap();
        let (p1, v1) = (f64::from(as_i32(a0.value("position"))), as_i32(a0.value("speed")));
        assert_eq!(v1, 0, "{label}: node {n} still moving after quick stop");
        let allowed = vq * vq / (2.0 * brake) + vq.abs() * config.cycle.as_secs_f64() + 2.0;
        let moved = (p1 - pq).abs();
        assert!(moved <= allowed, "{label}: node {n} moved {moved} > {allowed} (v_q {vq})");
        eprintln!(
            "{label}: node {n}: quick stop seen {} cycles after the request, v_q {vq}, braked over {moved} (allowed {allowed:.1}), speed at request {:?}",
            first_qs.index.saturating_sub(before.index),
            before.node(n).unwrap().value("speed")
        );
    }
    stop.store(true, Ordering::Relaxed);
    let final_stats = segment.stop();
    monitor_thread.join().unwrap().unwrap();

    let _ = final_stats;
    // The segment cycled and the monitor read it (liveness: how many of the nominal cycles
    // ran follows the host's load, printed above).
    assert!(counted >= 10, "{label}: {counted} cycles monitored in {window:.1} s");
    // The monitor's misses beside the segment's (a PRes the MN also saw missing or late): a
    // monitor thread held off the CPU loses frames of its own. Printed, not asserted.
    let segment_misses = mn_stats.total_missed() + mn_stats.pres_late;
    eprintln!(
        "{label}: node misses seen by the monitor {}, by the MN (missed or late PRes) {segment_misses}",
        misses.len()
    );
    // Drives followed the cam: positions span most of the ±2000 amplitude.
    for (i, (lo, hi)) in min_max.iter().enumerate() {
        assert!(hi - lo > 3000, "{label}: node {} range {lo}..{hi}", NODES[i]);
    }
    Outcome {
        mn: mn_stats,
        monitored_cycles: counted,
        nominal_cycles,
        missed_cycles,
        node_misses: misses.len() as u64,
    }
}

/// Segment scenarios take both cores for their cycle threads: one at a time per test
/// binary, or they would measure each other.
pub fn exclusive() -> std::sync::MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Cycle `k` of a 1 ms segment with one CN: SoC (RelativeTime k ms), PReq, PRes, SoA.
pub fn cycle_frames(k: u64) -> Vec<Vec<u8>> {
    use motus_epl_protocol::{
        EplFrame, Flags, MacAddr, Message, PReq, PRes, PrRs, RequestedService, Soa, Soc,
    };
    let mn = MacAddr([2, 0, 0, 0, 0, 240]);
    let cn = MacAddr([2, 0, 0, 0, 0, 1]);
    let soc = Soc { relative_time: 1000 * k, ..Soc::default() };
    let preq = PReq { flags: Flags::RD, payload: vec![0; 4], ..PReq::default() };
    let pres = PRes {
        nmt_state: NmtState::Operational,
        flags: Flags::RD,
        pr_rs: PrRs::default(),
        pdo_version: 0,
        payload: vec![1, 2, 3, 4],
        reserved: 0,
    };
    let soa = Soa::new(NmtState::Operational, RequestedService::NoService, 0);
    [
        EplFrame::new(mn, MacAddr::SOC, 255, 240, Message::Soc(soc)),
        EplFrame::new(mn, cn, 1, 240, Message::PReq(preq)),
        EplFrame::new(cn, MacAddr::PRES, 255, 1, Message::PRes(pres)),
        EplFrame::new(mn, MacAddr::SOA, 255, 240, Message::Soa(soa)),
    ]
    .iter()
    .map(|f| f.encode().unwrap())
    .collect()
}
