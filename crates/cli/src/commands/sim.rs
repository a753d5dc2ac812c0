//! `motus sim ...`.

use crate::cli::{SimCommand, SimKv01Args, SimNfv2Args, SimPs1aArgs};
use anyhow::{bail, Context, Result};
use motus_ps1a_sim::{LineOptions, MachineConfig, SimLine};
use motus_serial::{FaultConfig, LineSettings, Link, PtyLink, SerialLink};
use std::path::Path;

/// Runs a simulator until SIGINT/SIGTERM.
pub fn run(cmd: SimCommand) -> Result<()> {
    match cmd {
        SimCommand::Ps1a(args) => ps1a(args),
        SimCommand::Kv01(args) => kv01(args),
        SimCommand::Nfv2(args) => nfv2(args),
        SimCommand::Icla(args) => super::sim_can::icla(args),
        SimCommand::Mouse(args) => super::sim_can::mouse(args),
        SimCommand::Epl(args) => super::epl::sim(args),
    }
}

/// Opens the simulator's side of a link spec: `pty:<path>` or `serial:<device>`.
pub fn open_sim_link(spec: &str, baud: u32) -> Result<Box<dyn Link>> {
    if let Some(path) = spec.strip_prefix("pty:") {
        let pty = PtyLink::create(Some(Path::new(path)), LineSettings::n81(baud))
            .with_context(|| format!("cannot create the pty link {path}"))?;
        eprintln!("simulator listening on {} ({})", path, pty.slave_path().display());
        Ok(Box::new(pty))
    } else if let Some(dev) = spec.strip_prefix("serial:") {
        Ok(Box::new(SerialLink::open(dev, baud)?))
    } else {
        bail!("invalid --link {spec:?}: expected pty:<path> or serial:<device>")
    }
}

fn ps1a(a: SimPs1aArgs) -> Result<()> {
    for (name, rate) in [("--drop-rate", a.drop_rate), ("--corrupt-rate", a.corrupt_rate)] {
        if !(0.0..=1.0).contains(&rate) {
            bail!("{name} must be between 0 and 1, got {rate}");
        }
    }
    let machine: MachineConfig = match &a.machine {
        Some(json) => serde_json::from_str(json).context("invalid --machine JSON")?,
        None => MachineConfig::default(),
    };
    let link = open_sim_link(&a.link, a.baud)?;
    let options = LineOptions {
        addresses: a.addr.clone(),
        state_file: a.state_file.clone(),
        baud_pacing: a.baud_pacing,
        faults: FaultConfig { drop_rate: a.drop_rate, corrupt_rate: a.corrupt_rate, seed: a.seed },
        machine,
    };
    let mut line = SimLine::new(link, options)?;
    let stop = super::stop_flag()?;
    eprintln!("simulating PS1A modules at addresses {:?}; Ctrl-C to stop", a.addr);
    line.run(&stop)?;
    Ok(())
}

fn kv01(a: SimKv01Args) -> Result<()> {
    for (name, rate) in [("--drop-rate", a.drop_rate), ("--corrupt-rate", a.corrupt_rate)] {
        if !(0.0..=1.0).contains(&rate) {
            bail!("{name} must be between 0 and 1, got {rate}");
        }
    }
    let arm = match &a.arm {
        Some(json) => {
            motus_kv01_sim::ArmConfig::from_json(json).map_err(|e| anyhow::anyhow!("invalid --arm: {e}"))?
        }
        None => motus_kv01_sim::ArmConfig::default(),
    };
    let link = open_sim_link(&a.link, a.baud)?;
    let options = motus_kv01_sim::LineOptions {
        baud_pacing: a.baud_pacing,
        faults: FaultConfig { drop_rate: a.drop_rate, corrupt_rate: a.corrupt_rate, seed: a.seed },
        slow_controller: a.slow_controller_ms.map(std::time::Duration::from_millis),
        arm,
    }
    .seeded(a.seed);
    let mut line = motus_kv01_sim::SimLine::new(link, options)?;
    let stop = super::stop_flag()?;
    eprintln!("simulating the KV-01 arm (modules 0xE1..0xE6); the 700 ms time-out latches until restart; Ctrl-C to stop");
    line.run(&stop)?;
    Ok(())
}

fn nfv2(a: SimNfv2Args) -> Result<()> {
    for (name, rate) in [("--drop-rate", a.drop_rate), ("--corrupt-rate", a.corrupt_rate)] {
        if !(0.0..=1.0).contains(&rate) {
            bail!("{name} must be between 0 and 1, got {rate}");
        }
    }
    let controller = match &a.controller {
        Some(json) => motus_nfv2_sim::ControllerConfig::from_json(json)
            .map_err(|e| anyhow::anyhow!("invalid --controller: {e}"))?,
        None => motus_nfv2_sim::ControllerConfig::default(),
    };
    let mut options = motus_nfv2_sim::LineOptions {
        addresses: a.addr.clone(),
        revision: super::codec::nfv2_revision(&a.revision)?,
        baud_pacing: a.baud_pacing,
        faults: FaultConfig { drop_rate: a.drop_rate, corrupt_rate: a.corrupt_rate, seed: a.seed },
        controller,
        ..motus_nfv2_sim::LineOptions::default()
    }
    .seeded(a.seed);
    if let Some(ms) = a.delay_ms {
        if !(0.0..=10_000.0).contains(&ms) {
            bail!("--delay-ms must be between 0 and 10000, got {ms}");
        }
        options.reply_delay = std::time::Duration::from_secs_f64(ms / 1000.0);
    }
    let link = open_sim_link(&a.link, a.baud)?;
    let mut line = motus_nfv2_sim::SimLine::new(link, options)?;
    let stop = super::stop_flag()?;
    eprintln!("simulating 1209A controllers at addresses {:?}; Ctrl-C to stop", a.addr);
    line.run(&stop)?;
    Ok(())
}
