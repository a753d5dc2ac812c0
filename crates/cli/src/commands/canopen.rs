//! `motus canopen --bus <uri> ...`: the CANopen master from the command line.

use crate::cli_can::{CanopenAction, CanopenArgs, LssAction, PdoArgs, SdoAction};
use anyhow::{bail, Context, Result};
use motus_canopen::{DataType, LssIdentity, LssMode, Master, NmtCommand, ObjectDictionary, PdoConfig};
use motus_canopen_protocol::CanOpenMessage;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Parses a number written in hex (`0x6041`) or decimal.
pub fn number(text: &str) -> Result<u64> {
    let t = text.trim();
    let r = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        Some(h) => u64::from_str_radix(h, 16),
        None => t.parse(),
    };
    r.with_context(|| format!("{text:?} is not a number (decimal, or hex with 0x)"))
}

fn index(text: &str) -> Result<u16> {
    u16::try_from(number(text)?).with_context(|| format!("index {text} does not fit 16 bits"))
}

fn sub(text: &str) -> Result<u8> {
    u8::try_from(number(text)?).with_context(|| format!("sub-index {text} does not fit 8 bits"))
}

/// Opens a master on a bus URI.
pub fn open_master(uri: &str) -> Result<Arc<Master>> {
    let bus = motus_can::open_bus(uri).with_context(|| format!("cannot open the CAN bus {uri}"))?;
    Ok(Arc::new(Master::new(bus)))
}

/// Runs a `canopen` command.
pub fn run(a: CanopenArgs) -> Result<()> {
    let master = open_master(&a.bus)?;
    master.set_sdo_timeout(Duration::from_millis(a.timeout_ms));
    let od = match &a.eds {
        Some(p) => Some(master.load_eds(p).with_context(|| format!("--eds {}", p.display()))?),
        None => None,
    };
    match a.action {
        CanopenAction::Nmt { node, command } => {
            let c = match command.as_str() {
                "start" => NmtCommand::Start,
                "stop" => NmtCommand::Stop,
                "pre-op" | "preop" => NmtCommand::EnterPreOperational,
                "reset" => NmtCommand::ResetNode,
                "reset-comm" => NmtCommand::ResetCommunication,
                other => bail!("unknown NMT command {other:?} (start, stop, pre-op, reset, reset-comm)"),
            };
            master.nmt(node, c)?;
            println!(
                "NMT {c} sent to {}",
                if node == 0 { "all nodes".into() } else { format!("node {node}") }
            );
        }
        CanopenAction::Sdo(SdoAction::Read { node, index: i, sub: s, ty }) => {
            let (i, s) = (index(&i)?, sub(&s)?);
            let raw = master.sdo_upload(node, i, s)?;
            println!("{}", format_value(&raw, ty.as_deref(), od.as_deref(), i, s)?);
        }
        CanopenAction::Sdo(SdoAction::Write { node, index: i, sub: s, value, ty }) => {
            let (i, s) = (index(&i)?, sub(&s)?);
            let data = encode_value(&value, ty.as_deref(), od.as_deref(), i, s)?;
            master.sdo_download(node, i, s, &data)?;
            println!("0x{i:04X}:{s:02X} written ({} bytes)", data.len());
        }
        CanopenAction::Pdo(p) => pdo(&master, &p)?,
        CanopenAction::Lss(l) => lss(&master, l)?,
        CanopenAction::Scan { from, to } => {
            let nodes = master.scan(from..=to);
            if nodes.is_empty() {
                println!("no node answered between {from} and {to}");
            }
            for n in nodes {
                let id = n.identity.map_or("identity unreadable".into(), |i| {
                    format!(
                        "vendor 0x{:08X} product 0x{:08X} revision 0x{:08X} serial 0x{:08X}",
                        i.vendor, i.product, i.revision, i.serial
                    )
                });
                println!(
                    "node {:3}: device type 0x{:08X} {:?} {id}",
                    n.node,
                    n.device_type,
                    n.name.unwrap_or_default()
                );
            }
        }
        CanopenAction::Dump { node } => {
            if od.is_none() {
                bail!("dump needs --eds <file> to know which objects to read");
            }
            for row in master.dump(node)? {
                match row.value {
                    Ok(v) => println!("0x{:04X}:{:02X} {:40} = {v}", row.index, row.sub, row.name),
                    Err(e) => println!("0x{:04X}:{:02X} {:40} ! {e}", row.index, row.sub, row.name),
                }
            }
        }
        CanopenAction::Monitor { seconds } => {
            let rx = master.subscribe(motus_canopen::CobFilter::Range(0..=0x7FF));
            let end = Instant::now() + Duration::from_secs_f64(seconds.max(0.0));
            while let Some(left) = end.checked_duration_since(Instant::now()) {
                if let Ok(r) = rx.recv_timeout(left) {
                    println!("{:<24} {}", r.frame.to_string(), CanOpenMessage::decode(&r.frame));
                }
            }
        }
    }
    Ok(())
}

fn data_type(ty: Option<&str>, od: Option<&ObjectDictionary>, i: u16, s: u8) -> Result<Option<DataType>> {
    Ok(match ty {
        Some("u8") => Some(DataType::Unsigned8),
        Some("u16") => Some(DataType::Unsigned16),
        Some("u32") => Some(DataType::Unsigned32),
        Some("i8") => Some(DataType::Integer8),
        Some("i16") => Some(DataType::Integer16),
        Some("i32") => Some(DataType::Integer32),
        Some("str") => Some(DataType::VisibleString),
        Some("hex") => None,
        Some(other) => bail!("--type {other}: expected u8, u16, u32, i8, i16, i32, str or hex"),
        None => od.and_then(|od| od.lookup(i, s)).map(|v| v.data_type),
    })
}

fn format_value(
    raw: &[u8],
    ty: Option<&str>,
    od: Option<&ObjectDictionary>,
    i: u16,
    s: u8,
) -> Result<String> {
    let hex = raw.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ");
    let name = od.and_then(|od| od.lookup(i, s)).map(|v| format!(" ({})", v.full_name())).unwrap_or_default();
    match data_type(ty, od, i, s)? {
        Some(t) => {
            let v = t.decode(raw).with_context(|| format!("0x{i:04X}:{s:02X} returned [{hex}]"))?;
            Ok(format!("0x{i:04X}:{s:02X}{name} = {v} [{hex}]"))
        }
        None => Ok(format!("0x{i:04X}:{s:02X}{name} = [{hex}]")),
    }
}

fn encode_value(
    text: &str,
    ty: Option<&str>,
    od: Option<&ObjectDictionary>,
    i: u16,
    s: u8,
) -> Result<Vec<u8>> {
    match data_type(ty, od, i, s)? {
        Some(t) => Ok(t.encode_text(text)?),
        None if ty == Some("hex") => crate::hex::parse(text),
        None => bail!("0x{i:04X}:{s:02X}: give --type (u8, u16, u32, i8, i16, i32, str, hex) or --eds"),
    }
}

fn pdo(master: &Master, p: &PdoArgs) -> Result<()> {
    let node = u32::from(p.node);
    let n = u32::from(p.number);
    let (tx, default) = match p.direction.as_str() {
        "rpdo" => (false, 0x100 + 0x100 * n + node),
        "tpdo" => (true, 0x80 + 0x100 * n + node),
        other => bail!("{other:?}: expected rpdo or tpdo"),
    };
    if !(1..=4).contains(&n) && p.cob_id.is_none() {
        bail!("PDO {n} has no pre-defined COB-ID: give --cob-id");
    }
    let mut cob = match &p.cob_id {
        Some(c) => u32::try_from(number(c)?).context("--cob-id does not fit 32 bits")?,
        None => default,
    };
    if p.disabled {
        cob |= 0x8000_0000;
    }
    let mut mapping = Vec::new();
    for m in &p.map {
        let parts: Vec<&str> = m.split(':').collect();
        let [i, s, bits] = parts.as_slice() else {
            bail!("--map {m:?}: expected index:sub:bits, e.g. 0x6041:0:16")
        };
        mapping.push((index(i)?, sub(s)?, u8::try_from(number(bits)?).context("bits")?));
    }
    let cfg = PdoConfig {
        cob_id: cob,
        transmission_type: p.transmission_type,
        inhibit_100us: p.inhibit,
        event_timer_ms: p.event_timer,
        sync_start: None,
        mapping,
    };
    if tx {
        master.configure_tpdo(p.node, p.number, &cfg)?;
    } else {
        master.configure_rpdo(p.node, p.number, &cfg)?;
    }
    println!(
        "{} {} of node {} configured: COB-ID 0x{cob:08X}, type {}",
        p.direction.to_uppercase(),
        n,
        p.node,
        p.transmission_type
    );
    Ok(())
}

fn lss(master: &Master, a: LssAction) -> Result<()> {
    match a {
        LssAction::Switch { mode } => {
            let m = match mode.as_str() {
                "config" | "configuration" => LssMode::Configuration,
                "wait" | "waiting" => LssMode::Waiting,
                other => bail!("{other:?}: expected config or wait"),
            };
            master.lss_switch_global(m)?;
            println!("LSS switch state global: {mode}");
        }
        LssAction::Select { vendor, product, revision, serial } => {
            let id = LssIdentity {
                vendor: u32::try_from(number(&vendor)?)?,
                product: u32::try_from(number(&product)?)?,
                revision: u32::try_from(number(&revision)?)?,
                serial: u32::try_from(number(&serial)?)?,
            };
            master.lss_switch_selective(&id)?;
            println!("slave selected");
        }
        LssAction::SetNode { node } => {
            master.lss_configure_node_id(node)?;
            println!("node-ID {node} configured (takes effect at the next reset communication)");
        }
        LssAction::SetBitrate { bitrate } => {
            master.lss_configure_bit_timing(bitrate)?;
            println!("bit rate {bitrate} configured (activate with `lss activate`)");
        }
        LssAction::Activate { delay_ms } => {
            master.lss_activate_bit_timing(delay_ms)?;
            println!("bit timing activated (switch delay {delay_ms} ms)");
        }
        LssAction::Store => {
            master.lss_store()?;
            println!("configuration stored");
        }
        LssAction::Inquire => {
            let id = master.lss_inquire_identity()?;
            let node = master.lss_inquire_node_id()?;
            println!(
                "vendor 0x{:08X} product 0x{:08X} revision 0x{:08X} serial 0x{:08X} node-ID {node}",
                id.vendor, id.product, id.revision, id.serial
            );
        }
        LssAction::Fastscan => match master.lss_fastscan(Duration::from_millis(30))? {
            Some(id) => println!(
                "found vendor 0x{:08X} product 0x{:08X} revision 0x{:08X} serial 0x{:08X} (now in configuration state)",
                id.vendor, id.product, id.revision, id.serial
            ),
            None => println!("no unconfigured slave answered"),
        },
        LssAction::Assign { nodes, bitrate } => {
            for node in nodes {
                let Some(id) = master.lss_fastscan(Duration::from_millis(30))? else {
                    bail!("no unconfigured slave left for node-ID {node}");
                };
                master.lss_configure_node_id(node)?;
                if let Some(b) = bitrate {
                    master.lss_configure_bit_timing(b)?;
                }
                master.lss_store()?;
                master.lss_switch_global(LssMode::Waiting)?;
                master.wait_boot(node, Duration::from_secs(5))?;
                println!("serial 0x{:08X} -> node {node} (booted)", id.serial);
            }
        }
    }
    Ok(())
}
