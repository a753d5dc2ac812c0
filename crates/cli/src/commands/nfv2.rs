//! `motus nfv2 <port> raw '<json>'` and `motus pantilt <port> ...`.

use crate::cli::{Nfv2Action, Nfv2Args, PanTiltAction, PanTiltArgs};
use anyhow::{bail, Context, Result};
use motus_nfv2::{parse_track, HeadAxis, Nfv2Bus, PanTilt, PanTiltConfig};
use motus_nfv2_protocol::Frame;
use motus_serial::BusConfig;
use std::io::Read;
use std::time::{Duration, Instant};

/// Runs `motus nfv2 ...`.
pub fn run_nfv2(a: Nfv2Args) -> Result<()> {
    let rev = super::codec::nfv2_revision(&a.revision)?;
    match a.action {
        Nfv2Action::Raw { json } => {
            let frame: Frame = serde_json::from_str(&json).context(
                "invalid NFv2 JSON (e.g. {\"address\":1,\"commands\":[{\"kind\":\"query\",\"code\":\"read_drives_status\"}]})",
            )?;
            let bus = Nfv2Bus::open(&a.port, a.baud, bus_config(a.margin_ms))?.with_default_revision(rev);
            match bus.transact(&frame)? {
                Some(answer) => println!("{}", serde_json::to_string(&answer)?),
                None => println!("{{\"answer\":null}}"),
            }
        }
    }
    Ok(())
}

/// The longest wait for both drives' first status before acting.
const STATUS_WAIT: Duration = Duration::from_secs(10);

/// The bus settings with `margin_ms` of reply margin.
fn bus_config(margin_ms: u64) -> BusConfig {
    BusConfig { margin: Duration::from_millis(margin_ms), ..BusConfig::default() }
}

fn head_config(a: &PanTiltArgs) -> PanTiltConfig {
    let mut c = PanTiltConfig::default();
    c.pan = HeadAxis { address: a.pan_addr, ..c.pan };
    c.tilt = HeadAxis { address: a.tilt_addr, ..c.tilt };
    c.scheduler.silence = Duration::from_millis(a.silence_ms);
    c
}

/// Runs `motus pantilt ...`.
pub fn run_pantilt(a: PanTiltArgs) -> Result<()> {
    let head = PanTilt::open(&a.port, a.baud, bus_config(a.margin_ms), head_config(&a))?;
    // Let the scheduler read both drives' status (homed, faults) before acting on it (a
    // liveness bound: it is read within a few cycles).
    let t0 = Instant::now();
    while (head.pan().snapshot().status.is_none() || head.tilt().snapshot().status.is_none())
        && t0.elapsed() < STATUS_WAIT
    {
        std::thread::sleep(Duration::from_millis(5));
    }
    let result = pantilt_action(&head, &a.action, a.json);
    head.shutdown();
    result
}

fn show(pan: f64, tilt: f64, json: bool) {
    if json {
        println!("{}", serde_json::json!({"pan_deg": pan, "tilt_deg": tilt}));
    } else {
        println!("pan {pan:.3} deg  tilt {tilt:.3} deg");
    }
}

fn pantilt_action(head: &PanTilt, action: &PanTiltAction, json: bool) -> Result<()> {
    match action {
        PanTiltAction::Home => {
            head.home()?;
            let (p, t) = head.position()?;
            show(p, t, json);
        }
        PanTiltAction::Goto { pan, tilt } => {
            head.goto(*pan, *tilt)?;
            let (p, t) = head.wait_idle(Duration::from_secs(60))?;
            show(p, t, json);
        }
        PanTiltAction::Track { source } => {
            let mut text = String::new();
            if source == "-" {
                std::io::stdin().read_to_string(&mut text)?;
            } else {
                text = std::fs::read_to_string(source).with_context(|| format!("cannot read {source}"))?;
            }
            let points = parse_track(&text)?;
            let Some(last) = points.last().map(|p| p.t) else { bail!("the track has no points") };
            let feed = head.track(points)?;
            let end = feed.origin() + Duration::from_secs_f64(last.max(0.0));
            while Instant::now() < end {
                std::thread::sleep(Duration::from_millis(50));
            }
            let (p, t) = head.wait_idle(Duration::from_secs(30))?;
            show(p, t, json);
        }
        PanTiltAction::Where { t } => {
            if !t.is_finite() || *t < 0.0 {
                bail!("where <t>: t is seconds after the command starts (>= 0), got {t}");
            }
            let start = Instant::now();
            let at = start + Duration::from_secs_f64(*t);
            while Instant::now() < at + Duration::from_millis(100) {
                std::thread::sleep(Duration::from_millis(10));
            }
            let (p, tilt) = head.where_at(at)?;
            show(p, tilt, json);
        }
    }
    Ok(())
}
