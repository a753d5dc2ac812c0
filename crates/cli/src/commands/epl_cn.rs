//! `motus epl cn`: a standards-based Controlled Node for a foreign Managing Node.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use motus_clock::SystemClock;
use motus_epl::node::cn::{CnEvent, CnRuntimeConfig, CnRuntimeStats, ControlledNode, ControlledNodeRuntime};
use motus_epl::open_link;
use motus_epl_protocol::{DeviceIdentity, ObjectDictionary};

use crate::cli_epl::EplCnArgs;

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

/// Runs `motus epl cn`.
pub fn run(a: EplCnArgs) -> Result<()> {
    if let Some(s) = a.seconds {
        if !(s.is_finite() && s > 0.0) {
            bail!("--seconds must be a positive number, got {s}");
        }
    }
    let obtained = motus_realtime::set_policy(a.realtime.into());
    let memory = motus_realtime::lock_memory();
    eprintln!("real-time: {obtained}; {memory}");
    let link = open_link(&a.interface, false).with_context(|| format!("cannot open {}", a.interface))?;
    let clock = SystemClock::shared();
    let identity = DeviceIdentity { mac_address: link.mac().0, ..DeviceIdentity::default() };
    let od = ObjectDictionary::controlled_node(a.node, &identity);
    let mut node = ControlledNode::new(a.node, link.mac(), od, clock.now())?;
    node.set_reset_time(Duration::from_millis(a.reset_ms));
    eprintln!(
        "POWERLINK CN {} on {}{}; Ctrl-C to stop",
        a.node,
        link.describe(),
        if a.spin { ", busy polling" } else { "" }
    );
    let config = CnRuntimeConfig { spin: a.spin, ..CnRuntimeConfig::default() };
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
