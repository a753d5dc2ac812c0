//! `motus canbus serve`: the virtual CAN bus (a socketcand hub on loopback TCP).

use crate::cli_can::{CanbusCommand, CanbusServeArgs};
use anyhow::{Context, Result};
use motus_can::decorate::{CandumpLog, PcapCapture};
use motus_can::socketcand::{Hub, HubConfig, SocketcandBus};
use motus_can::CanBus;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

/// Runs a `canbus` command.
pub fn run(cmd: CanbusCommand) -> Result<()> {
    match cmd {
        CanbusCommand::Serve(a) => serve(a),
    }
}

fn serve(a: CanbusServeArgs) -> Result<()> {
    let listen = a.listen.parse().with_context(|| format!("--listen {:?}: expected HOST:PORT", a.listen))?;
    if a.bitrate == Some(0) {
        anyhow::bail!("--bitrate must be positive");
    }
    let hub = Hub::start(HubConfig { listen, bitrate: a.bitrate, channel: a.channel.clone() })
        .with_context(|| format!("cannot start the virtual CAN bus on {}", a.listen))?;
    let addr = hub.local_addr();
    // A recording client: it sees every frame the others send.
    let mut recorder: Option<Arc<dyn CanBus>> = None;
    if a.pcap.is_some() || a.candump.is_some() {
        let mut bus: Arc<dyn CanBus> = Arc::new(SocketcandBus::connect(addr, &a.channel)?);
        if let Some(p) = &a.pcap {
            bus = Arc::new(PcapCapture::create(bus, p).with_context(|| format!("--pcap {}", p.display()))?);
        }
        if let Some(p) = &a.candump {
            bus = Arc::new(
                CandumpLog::create(bus, p, &a.channel)
                    .with_context(|| format!("--candump {}", p.display()))?,
            );
        }
        recorder = Some(bus);
    }
    eprintln!(
        "virtual CAN bus ready: socketcand://{addr}/{} ({}); Ctrl-C to stop",
        a.channel,
        a.bitrate.map_or("no wire-time model".to_string(), |b| format!("{b} bit/s modelled"))
    );
    let stop = super::stop_flag()?;
    while !stop.load(Ordering::Relaxed) {
        match &recorder {
            Some(r) => {
                r.recv(Duration::from_millis(100))?;
            }
            None => std::thread::sleep(Duration::from_millis(100)),
        }
    }
    let stats = hub.stats();
    eprintln!("virtual CAN bus stopped: {} frames, {} bits", stats.frames, stats.bits);
    Ok(())
}
