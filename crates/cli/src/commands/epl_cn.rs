//! `motus epl cn`: a standards-based Controlled Node for a foreign Managing Node.

use std::path::Path;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use motus_clock::SystemClock;
use motus_epl::node::cn::{
    CnEvent, CnRuntimeConfig, CnRuntimeStats, CnWait, ControlledNode, ControlledNodeRuntime,
};
use motus_epl::open_link;
use motus_epl_protocol::{DeviceIdentity, ObjectDictionary};

use crate::cli_epl::{CnWaitArg, EplCnArgs};

fn us(ns: u64) -> f64 {
    ns as f64 / 1000.0
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect::<Vec<_>>().join(" ")
}

fn print_event(node: u8, e: &CnEvent) {
    match e {
        CnEvent::State { from, to, cause } => println!("cn {node}: state {from} -> {to} ({cause:?})"),
        CnEvent::NmtCommand(c) => println!("cn {node}: NMT command {c}"),
        CnEvent::SdoWrite { index, subindex, value } => {
            println!("cn {node}: SDO write {index:#06x}/{subindex} = {}", hex(value));
        }
        CnEvent::LossOfSoc => println!("cn {node}: loss of SoC"),
        CnEvent::LossOfPReq => println!("cn {node}: loss of PReq"),
    }
}

fn print_summary(node: u8, s: &CnRuntimeStats) {
    let t = s.turnaround;
    println!(
        "cn {node}: turnaround PReq -> PRes p50 {:.1} us p99 {:.1} us max {:.1} us over {} PReq",
        us(t.p50),
        us(t.p99),
        us(t.max),
        t.count
    );
    let c = s.counters;
    println!(
        "cn {node}: summary state {}, PRes sent {}, SoC {}, PReq {} (applied {}), SoA {}, IdentResponse {}, \
         StatusResponse {}, SDO received {} sent {}, loss of SoC {}, loss of PReq {}, cycle errors {}, \
         send errors {}, receive errors {}, undecodable frames {}",
        s.state,
        s.pres_sent,
        c.soc,
        c.preq,
        c.preq_applied,
        c.soa,
        c.ident_responses,
        c.status_responses,
        c.sdo_received,
        c.async_sent,
        c.loss_of_soc,
        c.loss_of_preq,
        c.cycle_errors,
        s.send_errors,
        s.recv_errors,
        c.decode_errors
    );
}

/// NMT_EPLNodeID_REC: subindex 1 is the node ID.
const NODE_ID_OBJECT: u16 = 0x1F93;

/// The dictionary a device description (`--od`) gives, with node ID `node` in 0x1F93/1 as its
/// default (so the NMT resets keep it) when the description has that entry.
fn dictionary_from_file(path: &Path, node: u8) -> Result<ObjectDictionary> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut od = ObjectDictionary::from_xdd(&text)
        .with_context(|| format!("{}: not a usable POWERLINK device description", path.display()))?;
    if od.entry(NODE_ID_OBJECT, 1).is_some() {
        od.set_default(NODE_ID_OBJECT, 1, &[node]).map_err(|e| {
            anyhow!("{}: 0x1F93/1 (NodeID_U8) cannot hold node ID {node}: {e:?}", path.display())
        })?;
    }
    Ok(od)
}

/// Runs `motus epl cn`.
pub fn run(a: EplCnArgs) -> Result<()> {
    if let Some(s) = a.seconds {
        if !(s.is_finite() && s > 0.0) {
            bail!("--seconds must be a positive number, got {s}");
        }
    }
    if let Some(cpu) = a.cpu {
        motus_realtime::affinity::check_cpu(cpu).context("--cpu")?;
    }
    // Read before anything else happens, so that a bad file stops at once.
    let from_file = match a.od.as_deref() {
        Some(path) => Some((path, dictionary_from_file(path, a.node)?)),
        None => None,
    };
    let obtained = motus_realtime::set_policy(a.realtime.into());
    let memory = motus_realtime::lock_memory();
    let wake = motus_realtime::wake_latency::hold_if_fifo();
    eprintln!("real-time: {obtained}; {memory}; {wake}");
    let link = open_link(&a.interface, false).with_context(|| format!("cannot open {}", a.interface))?;
    let clock = SystemClock::shared();
    let od = match from_file {
        Some((path, od)) => {
            eprintln!("object dictionary: {} ({} objects)", path.display(), od.len());
            od
        }
        None => {
            let identity = DeviceIdentity { mac_address: link.mac().0, ..DeviceIdentity::default() };
            ObjectDictionary::controlled_node(a.node, &identity)
        }
    };
    let mut node = ControlledNode::new(a.node, link.mac(), od, clock.now())?;
    node.set_reset_time(Duration::from_millis(a.reset_ms));
    let wait = match (a.spin, a.wait) {
        (true, _) | (false, CnWaitArg::Spin) => CnWait::Spin,
        (false, CnWaitArg::Sleep) => CnWait::Sleep,
        (false, CnWaitArg::Anticipate) => CnWait::Anticipate,
    };
    eprintln!(
        "POWERLINK CN {} on {}{}{}; Ctrl-C to stop",
        a.node,
        link.describe(),
        match wait {
            CnWait::Spin => ", busy polling",
            CnWait::Anticipate => ", polling around each PReq",
            CnWait::Sleep => ", woken by frames",
        },
        a.cpu.map(|c| format!(", pinned to CPU {c}")).unwrap_or_default()
    );
    let config = CnRuntimeConfig { wait, cpu: a.cpu, ..CnRuntimeConfig::default() };
    let rt = ControlledNodeRuntime::start(node, link, clock, config).context("cannot start the CN thread")?;
    let stop = super::stop_flag()?;
    let until = a.seconds.map(|s| Instant::now() + Duration::from_secs_f64(s));
    while !stop.load(Ordering::Relaxed) && until.is_none_or(|t| Instant::now() < t) {
        if let Some(e) = rt.next_event(Duration::from_millis(100)) {
            print_event(a.node, &e);
            for e in rt.take_events() {
                print_event(a.node, &e);
            }
        }
    }
    let stats = rt.stop();
    print_summary(a.node, &stats);
    Ok(())
}
