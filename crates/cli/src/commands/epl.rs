//! `motus epl monitor` and `motus sim epl`.

use std::ops::ControlFlow;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use motus_epl::sim::{MnConfig, MotionProgram, Segment, SetpointList};
use motus_epl::{
    open_link, CycleSample, EthLink, Monitor, MonitorConfig, MonitorStats, NodeCounters, PcapLink, RawSocket,
    RingConfig, RingSocket, TimingStats,
};
use motus_epl_protocol::ValueMap;
use motus_safety::RuleSet;
use motus_safety_epl::juggler::{self, Pattern};
use serde_json::json;

use crate::cli_epl::{EplCommand, EplMonitorArgs, SimEplArgs};

/// Runs an `epl` command.
pub fn run(cmd: EplCommand) -> Result<()> {
    match cmd {
        EplCommand::Monitor(a) => monitor(a),
        EplCommand::Mn(a) => super::epl_mn::run(a),
        EplCommand::Cn(a) => super::epl_cn::run(a),
    }
}

/// Reads a value map file.
pub fn read_map(path: &Path) -> Result<ValueMap> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    ValueMap::from_toml(&text).with_context(|| format!("invalid value map {}", path.display()))
}

/// Reads and validates a rules file.
pub fn read_rules(path: &Path) -> Result<RuleSet> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    RuleSet::from_toml(&text).with_context(|| format!("invalid rules file {}", path.display()))
}

fn us(ns: u64) -> f64 {
    ns as f64 / 1000.0
}

fn timing_json(t: &TimingStats) -> serde_json::Value {
    if t.count == 0 {
        return serde_json::Value::Null;
    }
    json!({
        "count": t.count,
        "min_us": us(t.min_ns),
        "mean_us": t.mean_ns().map(us),
        "max_us": us(t.max_ns),
    })
}

/// The frame counters: received = decoded + undecoded; dropped before reception; the kernel's.
fn frames_json(st: &MonitorStats) -> serde_json::Value {
    json!({
        "received": st.frames,
        "decoded": st.decoded,
        "undecoded": st.undecoded,
        "dropped": st.dropped,
        "kernel_packets": st.kernel.map(|k| k.packets),
        "kernel_drops": st.kernel.map(|k| k.drops),
    })
}

fn cycle_json(s: &CycleSample) -> serde_json::Value {
    let nodes: Vec<_> = s
        .nodes
        .iter()
        .map(|n| {
            let values: serde_json::Map<String, serde_json::Value> =
                n.values.iter().map(|(k, v)| (k.clone(), json!(v.as_f64()))).collect();
            json!({
                "node": n.node,
                "fresh": !n.stale && n.valid && n.error.is_none(),
                "age": n.age,
                "nmt_state": n.nmt_state.map(|s| s.to_string()),
                "values": values,
                "error": n.error.as_ref().map(ToString::to_string),
            })
        })
        .collect();
    let pres: Vec<_> = s
        .report
        .pres
        .iter()
        .map(|p| {
            json!({
                "node": p.node,
                "nmt_state": p.nmt_state.to_string(),
                "ready": p.ready,
                "after_soc_us": us(p.after_soc_ns),
            })
        })
        .collect();
    json!({
        "cycle": s.index,
        "soc_ns": s.report.soc_at_ns,
        "duration_us": s.report.duration_ns.map(us),
        "complete": s.complete(),
        "lost_frames": s.lost_frames,
        "polled": s.report.polled,
        "pres": pres,
        "missing": s.missing,
        "all_fresh": s.all_fresh(),
        "nodes": nodes,
        "frames": frames_json(&s.stats),
    })
}

fn node_json(c: &NodeCounters) -> serde_json::Value {
    json!({
        "node": c.node,
        "nmt_state": c.nmt_state.map(|s| s.to_string()),
        "polled": c.polled,
        "pres": c.pres,
        "expected": c.expected,
        "misses": c.misses,
        "pres_after_soc": timing_json(&c.pres_after_soc),
    })
}

fn summary_json(st: &MonitorStats, nodes: &[NodeCounters]) -> serde_json::Value {
    json!({
        "summary": {
            "frames": frames_json(st),
            "cycles": st.cycles,
            "cycles_with_loss": st.cycles_with_loss,
            "cycles_lost": st.cycles_lost,
            "cycle_time": timing_json(&st.cycle_time),
            "nodes": nodes.iter().map(node_json).collect::<Vec<_>>(),
        }
    })
}

fn timing_text(t: &TimingStats) -> String {
    match t.mean_ns() {
        Some(mean) => {
            format!("mean {:.1} us, min {:.1} us, max {:.1} us", us(mean), us(t.min_ns), us(t.max_ns))
        }
        None => "none".into(),
    }
}

fn summary_text(st: &MonitorStats, nodes: &[NodeCounters]) -> String {
    let mut out = format!(
        "frames: {} received = {} decoded + {} undecoded; {} dropped before reception",
        st.frames, st.decoded, st.undecoded, st.dropped
    );
    match st.kernel {
        Some(k) => out.push_str(&format!(
            " (kernel: {} packets, {} dropped, {} not read)",
            k.packets,
            k.drops,
            k.packets.saturating_sub(k.drops).saturating_sub(st.frames)
        )),
        None => out.push_str(" (no kernel counters for this source)"),
    }
    out.push_str(&format!(
        "\ncycles: {} ({} with lost frames, {} SoCs lost), cycle time {}",
        st.cycles,
        st.cycles_with_loss,
        st.cycles_lost,
        timing_text(&st.cycle_time)
    ));
    for c in nodes {
        out.push_str(&format!(
            "\nnode {}: {}, polled {}, PRes {}, misses {} of {} expected, PRes after SoC {}",
            c.node,
            c.nmt_state.map_or("state unknown".to_string(), |s| s.to_string()),
            c.polled,
            c.pres,
            c.misses,
            c.expected,
            timing_text(&c.pres_after_soc)
        ));
    }
    out
}

/// Opens the monitor's link: a raw interface read through a TPACKET_V3 ring of `ring_mb` MiB
/// (`None`: a plain raw socket with the asked receive queue), or a named segment.
fn open_monitor_link(name: &str, ring_mb: Option<u32>, rcvbuf: usize) -> Result<Arc<dyn EthLink>> {
    if name.starts_with("udp://") || name.starts_with("mem://") {
        return open_link(name, true).with_context(|| format!("cannot open {name}"));
    }
    if let Some(mb) = ring_mb {
        let config = RingConfig::with_mib(mb);
        let ring = RingSocket::open(name, true, config).with_context(|| format!("cannot open {name}"))?;
        eprintln!(
            "receive ring: {} MiB, {} blocks of {} KiB handed over after at most {} ms",
            config.bytes() >> 20,
            config.blocks,
            config.block_size >> 10,
            config.block_timeout_ms
        );
        return Ok(Arc::new(ring));
    }
    let raw = RawSocket::open(name, true).with_context(|| format!("cannot open {name}"))?;
    let granted =
        raw.set_recv_buffer(rcvbuf).with_context(|| format!("{name}: receive queue of {rcvbuf} bytes"))?;
    eprintln!("receive queue: {granted} bytes (asked {rcvbuf})");
    Ok(Arc::new(raw))
}

fn monitor(a: EplMonitorArgs) -> Result<()> {
    let config = MonitorConfig { stale_after: u64::from(a.stale_after) };
    let mut monitor = match &a.map {
        Some(path) => Monitor::new(read_map(path)?, config),
        None => Monitor::cycles_only(config),
    };
    let limit = a.cycles.unwrap_or(u64::MAX);
    let mut seen = 0u64;
    // Cycles to skip before the next regular line (one line in `--every`).
    let mut skip = 0u64;
    let mut print = |s: &CycleSample| {
        let regular = skip == 0;
        skip = if regular { a.every.saturating_sub(1) } else { skip - 1 };
        if regular || !s.missing.is_empty() || s.lost_frames > 0 {
            println!("{}", cycle_json(s));
        }
        seen += 1;
        if seen >= limit {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    };
    let stats = if let Some(pcap) = &a.pcap {
        let frames = motus_epl::replay::read_capture(pcap)
            .with_context(|| format!("cannot read the capture {}", pcap.display()))?;
        monitor.replay(&frames, print)
    } else {
        let name = a.interface.as_deref().unwrap_or_default();
        let link = open_monitor_link(name, (!a.no_ring).then_some(a.ring_mb), a.rcvbuf)?;
        eprintln!("monitoring {}; Ctrl-C to stop", link.describe());
        let stop = super::stop_flag()?;
        monitor.run(&*link, &stop, &mut print)?
    };
    let nodes = monitor.node_counters();
    println!("{}", summary_json(&stats, &nodes));
    eprintln!("{}", summary_text(&stats, &nodes));
    Ok(())
}

/// Reads a set-point CSV: `time_s,raw1,raw2,...` per row (a header row is skipped).
fn read_setpoints(path: &Path, axes: usize) -> Result<SetpointList> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut rows = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let Some((t, rest)) = fields.split_first() else { continue };
        let Ok(t) = t.parse::<f64>() else {
            if i == 0 {
                continue; // header
            }
            bail!("{}:{}: time {t:?} is not a number", path.display(), i + 1);
        };
        if !(t.is_finite() && t >= 0.0) {
            bail!("{}:{}: time {t} must be >= 0", path.display(), i + 1);
        }
        if rest.len() != axes {
            bail!("{}:{}: {} set-points, the config has {axes} axes", path.display(), i + 1, rest.len());
        }
        let sp = rest
            .iter()
            .map(|v| {
                v.parse::<i32>().with_context(|| format!("{}:{}: set-point {v:?}", path.display(), i + 1))
            })
            .collect::<Result<Vec<_>>>()?;
        rows.push((Duration::from_secs_f64(t), sp));
    }
    if rows.is_empty() {
        bail!("{}: no set-points", path.display());
    }
    Ok(SetpointList::new(rows))
}

/// Runs `motus sim epl`.
pub fn sim(a: SimEplArgs) -> Result<()> {
    if a.cycle_us < 400 {
        bail!("--cycle-us must be at least 400, got {}", a.cycle_us);
    }
    let rules = read_rules(&a.config)?;
    let n = rules.axes().len();
    let (pattern, program): (Pattern, Box<dyn MotionProgram>) = match a.program.parse::<Pattern>() {
        Ok(p) => (p, Box::new(juggler::program(&rules, p))),
        Err(_) if Path::new(&a.program).is_file() => {
            (Pattern::Juggle, Box::new(read_setpoints(Path::new(&a.program), n)?))
        }
        Err(e) => bail!("--program: {e}, and no file {:?}", a.program),
    };
    let lease = (a.lease_ms > 0).then(|| Duration::from_millis(a.lease_ms));
    let mut drives = juggler::drives(&rules, pattern, lease);
    if a.safety_node.is_some() && lease.is_none() {
        bail!("--safety-node needs a lease (--lease-ms > 0)");
    }
    if let Some(n) = a.safety_node {
        if drives.iter().any(|(node, _)| *node == n) {
            bail!("--safety-node {n} is one of the drives' node IDs");
        }
    }
    for (_, params) in &mut drives {
        params.safety_node = a.safety_node;
    }
    let links: Vec<Arc<dyn EthLink>> = if a.interface.starts_with("udp://") {
        (0..=n)
            .map(|_| open_link(&a.interface, false).with_context(|| format!("cannot join {}", a.interface)))
            .collect::<Result<_>>()?
    } else {
        let names: Vec<&str> = a.interface.split(',').collect();
        if names.len() != n + 1 {
            bail!("--if: {} interfaces given; need {} (the MN's, then one per axis)", names.len(), n + 1);
        }
        names
            .iter()
            .map(|i| open_link(i, false).with_context(|| format!("cannot open interface {i}")))
            .collect::<Result<_>>()?
    };
    let mut links = links.into_iter();
    let mut mn = links.next().context("no link for the MN")?;
    if let Some(path) = &a.pcap {
        let rec = PcapLink::create(mn, path).with_context(|| format!("cannot create {}", path.display()))?;
        mn = Arc::new(rec);
    }
    let config = MnConfig {
        cycle: Duration::from_micros(a.cycle_us),
        pres_timeout: Duration::from_micros((a.cycle_us / 4).clamp(100, 300)),
        ..MnConfig::default()
    };
    let mut b = Segment::builder().config(config).mn_link(mn).program(program);
    for ((node, params), link) in drives.into_iter().zip(links) {
        b = b.drive(node, link, params);
    }
    if let Some(n) = a.safety_node {
        b = b.polled_node(n);
    }
    let segment = b.start()?;
    eprintln!(
        "simulated POWERLINK segment on {}: MN 240 + drives {:?}, cycle {} us, program {}, lease {}",
        a.interface,
        rules.axes().iter().map(|x| x.id).collect::<Vec<_>>(),
        a.cycle_us,
        a.program,
        match (lease, a.safety_node) {
            (None, _) => "ignored".to_owned(),
            (Some(l), Some(n)) => format!("{l:?} from the PRes of safety node {n}"),
            (Some(l), None) => format!("{l:?} from the lease ASnd of node 253"),
        },
    );
    let stop = super::stop_flag()?;
    let mut reported = false;
    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(100));
        if !reported && segment.mn_state() == motus_epl_protocol::NmtState::Operational {
            eprintln!("segment OPERATIONAL");
            reported = true;
        }
    }
    let stats = segment.stop();
    let j = stats.jitter();
    eprintln!(
        "{} cycles, SoC jitter p50 {} us p99 {} us max {} us, PRes missed {}, overruns {}",
        stats.cycles,
        j.p50 / 1000,
        j.p99 / 1000,
        j.max / 1000,
        stats.total_missed(),
        stats.overruns
    );
    Ok(())
}
