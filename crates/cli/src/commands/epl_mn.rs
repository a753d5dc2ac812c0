//! `motus epl mn`: a Managing Node for foreign CNs from a concise DCF.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use motus_epl::node::mn::runtime::{self, RuntimeConfig, RuntimeStats};
use motus_epl::node::mn::{CdcMn, EventKind, MnConfig, MnEvent, NodeReport, PdoValue};
use motus_epl::open_link;
use motus_epl_protocol::Cdc;

use crate::cli_epl::EplMnArgs;

/// Parses a number, hex with `0x`.
fn number(s: &str) -> Result<u64> {
    let s = s.trim();
    match s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        Some(h) => u64::from_str_radix(h, 16).with_context(|| format!("bad hex number {s:?}")),
        None => s.parse().with_context(|| format!("bad number {s:?}")),
    }
}

/// Parses `NODE:INDEX/SUB=VALUE`.
fn parse_set(s: &str) -> Result<(u8, u16, u8, u64)> {
    let parse = || -> Result<(u8, u16, u8, u64)> {
        let (node, rest) = s.split_once(':').context("missing ':'")?;
        let (object, value) = rest.split_once('=').context("missing '='")?;
        let (index, sub) = object.split_once('/').context("missing '/'")?;
        Ok((
            u8::try_from(number(node)?).context("node out of range")?,
            u16::try_from(number(index)?).context("index out of range")?,
            u8::try_from(number(sub)?).context("subindex out of range")?,
            number(value)?,
        ))
    };
    parse().with_context(|| format!("--set {s:?}: expected NODE:INDEX/SUB=VALUE, e.g. 1:0x6200/1=0x55"))
}

fn values(v: &[PdoValue]) -> String {
    if v.is_empty() {
        return "-".into();
    }
    v.iter()
        .map(|p| {
            let value = p.value.map_or("?".into(), |x| format!("{x:#04x}"));
            format!("{:#06x}/{}={value}", p.index, p.subindex)
        })
        .collect::<Vec<_>>()
        .join(",")
}

fn print_event(e: &MnEvent) {
    let n = e.node;
    match &e.kind {
        EventKind::State(s) => println!("node {n}: state {s}"),
        EventKind::Phase(p) => println!("node {n}: boot {p}"),
        EventKind::Identified { vendor_id, product_code, revision, serial } => println!(
            "node {n}: identified (vendor {vendor_id:#x}, product {product_code:#x}, revision {revision:#x}, serial {serial:#x})"
        ),
        EventKind::IdentityMismatch(why) => println!("node {n}: identity mismatch: {why}"),
        EventKind::ConfigurationCurrent => println!("node {n}: configuration current (0x1020 matches the CDC)"),
        EventKind::Configured { index, subindex, done, total } => {
            println!("node {n}: configured {index:#06x}/{subindex} ({done}/{total})");
        }
        EventKind::ConfigurationError { index, subindex, error } => {
            println!("node {n}: configuration error {index:#06x}/{subindex}: {error}");
        }
        EventKind::Command(c) => println!("node {n}: {c}"),
        EventKind::Lost(why) => println!("node {n}: lost ({why}), booting it again"),
    }
}

fn print_nodes(nodes: &[NodeReport], all: bool) {
    for n in nodes.iter().filter(|n| all || n.mac.is_some()) {
        println!(
            "pd node {}: {} ({}) out {} in {} pres {} missed {} late {} boots {}",
            n.node,
            n.state,
            n.phase,
            values(&n.outputs),
            values(&n.inputs),
            n.pres_received,
            n.pres_missed,
            n.pres_late,
            n.boots
        );
    }
}

fn us(ns: u64) -> f64 {
    ns as f64 / 1000.0
}

fn print_summary(stats: &RuntimeStats, nodes: &[NodeReport]) {
    let j = stats.soc_late;
    println!(
        "summary: {} cycles ({} full), {} overruns, {} send errors, {} undecoded; SoC jitter p50 {:.1} us p99 {:.1} us max {:.1} us ({} SoCs); PReq->PRes p50 {:.1} us p99 {:.1} us max {:.1} us",
        stats.cycles,
        stats.full_cycles,
        stats.overruns,
        stats.send_errors,
        stats.decode_errors,
        us(j.p50),
        us(j.p99),
        us(j.max),
        j.count,
        us(stats.pres_rtt.p50),
        us(stats.pres_rtt.p99),
        us(stats.pres_rtt.max)
    );
    for n in nodes {
        println!(
            "summary node {}: {} ({}), boots {}, OPERATIONAL entries {}, PRes {} missed {} (late {}), configuration errors {}",
            n.node,
            n.state,
            n.phase,
            n.boots,
            n.operational_entries,
            n.pres_received,
            n.pres_missed,
            n.pres_late,
            n.config_errors
        );
    }
}

/// Runs `motus epl mn`.
pub fn run(a: EplMnArgs) -> Result<()> {
    let obtained = motus_realtime::set_policy(a.realtime.into());
    let memory = motus_realtime::lock_memory();
    let wake = motus_realtime::wake_latency::hold_if_fifo();
    eprintln!("real-time: {obtained}; {memory}; {wake}");
    let bytes = std::fs::read(&a.cdc).with_context(|| format!("cannot read {}", a.cdc.display()))?;
    let cdc = Cdc::parse(&bytes).with_context(|| format!("{} is not a concise DCF", a.cdc.display()))?;
    let overrides = a.set.iter().map(|s| parse_set(s)).collect::<Result<Vec<_>>>()?;
    let link = open_link(&a.interface, false).with_context(|| format!("cannot open {}", a.interface))?;
    let config = MnConfig {
        mac: link.mac(),
        overrides,
        counter_every: a.counter_every,
        lost_after: a.lost_after.max(1),
        min_pres_timeout: Duration::from_micros(a.min_pres_timeout_us),
        ..MnConfig::default()
    };
    let mn = CdcMn::new(&cdc, config).with_context(|| format!("{}", a.cdc.display()))?;
    let nodes = mn.nodes();
    println!(
        "MN 240 on {} ({}): cycle {:?}, CNs {:?}",
        a.interface,
        link.mac(),
        mn.cycle(),
        nodes.iter().map(|n| n.node).collect::<Vec<_>>()
    );
    let clock = motus_clock::SystemClock::shared();
    let rt = RuntimeConfig { spin: a.spin, ..RuntimeConfig::default() };
    let handle = runtime::spawn(link, clock, mn, rt).context("cannot start the MN thread")?;
    let stop = super::stop_flag()?;
    let started = Instant::now();
    let end = a.seconds.map(|s| started + Duration::from_secs_f64(s.max(0.0)));
    let mut last_print = Instant::now();
    while !stop.load(Ordering::Relaxed) && end.is_none_or(|e| Instant::now() < e) {
        std::thread::sleep(Duration::from_millis(50));
        for e in handle.take_events() {
            print_event(&e);
        }
        if last_print.elapsed() >= Duration::from_secs(1) {
            last_print = Instant::now();
            let st = handle.stats();
            println!(
                "t {:.1} s: MN {}, SoC jitter p50 {:.1} us p99 {:.1} us max {:.1} us",
                started.elapsed().as_secs_f64(),
                st.mn_state.map_or("?".into(), |s| s.to_string()),
                us(st.soc_late.p50),
                us(st.soc_late.p99),
                us(st.soc_late.max)
            );
            print_nodes(&handle.nodes(), false);
        }
        if handle.is_finished() {
            bail!("the MN thread ended unexpectedly");
        }
    }
    let nodes = handle.nodes();
    let stats = handle.stop();
    print_summary(&stats, &nodes);
    Ok(())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn set_parses_hex_and_decimal() {
        assert_eq!(parse_set("1:0x6200/1=0x55").unwrap(), (1, 0x6200, 1, 0x55));
        assert_eq!(parse_set("32:24576/2=7").unwrap(), (32, 0x6000, 2, 7));
        assert!(parse_set("1:0x6200=5").is_err());
        assert!(parse_set("300:0x6200/1=5").is_err());
    }
}
