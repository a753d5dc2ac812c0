//! `motus epl monitor` and `motus sim epl`.

use std::ops::ControlFlow;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use motus_epl::sim::{MnConfig, MotionProgram, Segment, SetpointList};
use motus_epl::{open_link, CycleSample, EthLink, Monitor, MonitorConfig, PcapLink};
use motus_epl_protocol::ValueMap;
use motus_safety::RuleSet;
use motus_safety_epl::juggler::{self, Pattern};
use serde_json::json;

use crate::cli_epl::{EplCommand, EplMonitorArgs, SimEplArgs};

/// Runs an `epl` command.
pub fn run(cmd: EplCommand) -> Result<()> {
    match cmd {
        EplCommand::Monitor(a) => monitor(a),
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
    json!({
        "cycle": s.index,
        "soc_ns": s.report.soc_at_ns,
        "polled": s.report.polled,
        "all_fresh": s.all_fresh(),
        "nodes": nodes,
    })
}

fn monitor(a: EplMonitorArgs) -> Result<()> {
    let map = read_map(&a.map)?;
    let mut monitor = Monitor::new(map, MonitorConfig { stale_after: u64::from(a.stale_after) });
    let limit = a.cycles.unwrap_or(u64::MAX);
    let mut printed = 0u64;
    let mut print = |s: &CycleSample| {
        println!("{}", cycle_json(s));
        printed += 1;
        if printed >= limit {
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
        let link = open_link(name, true).with_context(|| format!("cannot open {name}"))?;
        eprintln!("monitoring {}; Ctrl-C to stop", link.describe());
        let stop = super::stop_flag()?;
        monitor.run(&*link, &stop, &mut print)?
    };
    eprintln!("{} frames, {} undecoded, {} cycles", stats.frames, stats.undecoded, stats.cycles);
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
    let drives = juggler::drives(&rules, pattern, lease);
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
    let segment = b.start()?;
    eprintln!(
        "simulated POWERLINK segment on {}: MN 240 + drives {:?}, cycle {} us, program {}, lease {}",
        a.interface,
        rules.axes().iter().map(|x| x.id).collect::<Vec<_>>(),
        a.cycle_us,
        a.program,
        lease.map_or("ignored".into(), |l| format!("{l:?}")),
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
