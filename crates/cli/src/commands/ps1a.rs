//! `motus ps1a <port> scan | params get | params set`.

use crate::cli::{ParamsAction, ParamsSet, Ps1aAction, Ps1aArgs};
use anyhow::{bail, Context, Result};
use motus_ps1a::Ps1aBus;
use motus_ps1a_protocol::{Acceleration, BaudRate, DdaCycle, Parameters, U24};
use motus_serial::{BusConfig, BusMaster, SerialLink};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

fn open(port: &str, baud: u32, margin: Duration, retries: u32) -> Result<Ps1aBus> {
    let link = SerialLink::open(port, baud)?;
    Ok(Ps1aBus::new(Arc::new(BusMaster::new(Box::new(link), BusConfig { margin, retries }))))
}

/// Where Motus records the parameter sets it wrote (the module cannot report them).
fn record_path() -> PathBuf {
    if let Ok(p) = std::env::var("MOTUS_PS1A_PARAMS") {
        return PathBuf::from(p);
    }
    let base = std::env::var("XDG_STATE_HOME")
        .map(PathBuf::from)
        .or_else(|_| std::env::var("HOME").map(|h| PathBuf::from(h).join(".local/state")))
        .unwrap_or_else(|_| std::env::temp_dir());
    base.join("motus").join("ps1a-params.json")
}

type Record = BTreeMap<String, Parameters>;

fn load_record() -> Result<Record> {
    let path = record_path();
    match std::fs::read(&path) {
        Ok(b) => {
            serde_json::from_slice(&b).with_context(|| format!("invalid parameter record {}", path.display()))
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Record::new()),
        Err(e) => Err(e).with_context(|| format!("cannot read {}", path.display())),
    }
}

fn save_record(r: &Record) -> Result<()> {
    let path = record_path();
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    std::fs::write(&path, serde_json::to_vec_pretty(r)?)
        .with_context(|| format!("cannot write {}", path.display()))
}

fn key(port: &str, addr: u8) -> String {
    format!("{port}#{addr}")
}

fn parse_range(r: &str) -> Result<std::ops::RangeInclusive<u8>> {
    let (a, b) = r.split_once('-').unwrap_or((r, r));
    let a: u8 = a.trim().parse().with_context(|| format!("invalid range start in {r:?}"))?;
    let b: u8 = b.trim().parse().with_context(|| format!("invalid range end in {r:?}"))?;
    if a > b {
        bail!("invalid range {r:?}: start after end");
    }
    Ok(a..=b)
}

/// Runs a PS1A line action.
pub fn run(p: Ps1aArgs) -> Result<()> {
    match p.action {
        Ps1aAction::Scan { range, margin_ms } => {
            let bus = open(&p.port, p.baud, Duration::from_millis(margin_ms), 0)?;
            let found = bus.scan(parse_range(&range)?);
            if p.json {
                let list: Vec<_> =
                    found.iter().map(|(a, r)| serde_json::json!({"addr": a, "status": r})).collect();
                println!("{}", serde_json::to_string(&list)?);
            } else if found.is_empty() {
                println!("no PS1A module answered on {} in {range}", p.port);
            } else {
                for (a, r) in &found {
                    println!("module {a}: position {} flags {:?}", r.position.get(), r.low.names());
                }
            }
            Ok(())
        }
        Ps1aAction::Params(ParamsAction::Get { addr }) => {
            let record = load_record()?;
            let stored = record.get(&key(&p.port, addr));
            if p.json {
                println!(
                    "{}",
                    serde_json::to_string(&serde_json::json!({ "addr": addr, "written_by_motus": stored }))?
                );
            } else {
                match stored {
                    Some(params) => {
                        println!("parameters last written by Motus to module {addr} on {} (the PS1A cannot report its parameters):", p.port);
                        println!("{}", serde_json::to_string_pretty(params)?);
                    }
                    None => println!(
                        "Motus has not written parameters to module {addr} on {}; the PS1A cannot report them (factory defaults: {})",
                        p.port,
                        serde_json::to_string(&Parameters::default())?
                    ),
                }
            }
            Ok(())
        }
        Ps1aAction::Params(ParamsAction::Set(s)) => set(&p.port, p.baud, p.json, s),
    }
}

fn set(port: &str, baud: u32, json: bool, s: ParamsSet) -> Result<()> {
    let mut record = load_record()?;
    let mut params = record
        .get(&key(port, s.addr))
        .copied()
        .unwrap_or(Parameters { address: s.addr, ..Parameters::default() });
    if let Some(a) = s.new_addr {
        params.address = a;
    }
    if let Some(v) = s.ds {
        params.ds = v;
    }
    if let Some(v) = s.tvz {
        params.tvz = DdaCycle::from_code(v).with_context(|| format!("--tvz {v}: must be 0..3"))?;
    }
    if let Some(v) = s.coms {
        params.coms = BaudRate::from_code(v).with_context(|| format!("--coms {v}: must be 0..3"))?;
    }
    if let Some(v) = s.max {
        params.max_position = U24::new(v).with_context(|| format!("--max {v}: must be at most 16777215"))?;
    }
    if let Some(v) = s.vnrb {
        params.vnrb = v;
    }
    if let Some(v) = s.anrb {
        params.anrb = Acceleration::new(v).with_context(|| format!("--anrb {v}: must be 1..10"))?;
    }
    if let Some(v) = s.vnnb {
        params.vnnb = v;
    }
    if let Some(v) = s.annb {
        params.annb = Acceleration::new(v).with_context(|| format!("--annb {v}: must be 1..10"))?;
    }
    if params.ds == 0 {
        bail!("--ds 0 would make every speed zero");
    }
    let bus = open(port, baud, Duration::from_millis(s.margin_ms), 2)?;
    bus.write_parameters(s.addr, params)
        .with_context(|| format!("writing parameters to module {}", s.addr))?;
    record.remove(&key(port, s.addr));
    record.insert(key(port, params.address), params);
    save_record(&record)?;
    if json {
        println!("{}", serde_json::to_string(&serde_json::json!({"addr": s.addr, "written": params}))?);
    } else {
        println!("module {} stored: {}", s.addr, serde_json::to_string(&params)?);
        if params.address != s.addr {
            println!("the module now answers at address {}", params.address);
        }
    }
    Ok(())
}
