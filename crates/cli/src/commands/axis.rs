//! `motus axis <uri> ...`: the common axis commands for any device family.

use crate::cli::{AxisAction, AxisArgs};
use crate::progress::Progress;
use anyhow::{bail, Context, Result};
use motus_axis::{wait_until, Axis, AxisCommand, AxisState, Direction, MotionProfile, WaitOutcome};
use motus_serial::DeviceUri;
use std::time::Duration;

/// Opens the axis a URI names.
pub fn open(uri_text: &str) -> Result<Box<dyn Axis>> {
    if let Some(rest) = uri_text.strip_prefix("cia402://") {
        return open_cia402(rest);
    }
    let uri: DeviceUri = uri_text.parse()?;
    match uri.scheme.as_str() {
        "ps1a" => Ok(Box::new(motus_ps1a::open_axis(&uri).map_err(|e| anyhow::anyhow!("{e}"))?)),
        "kv01" => {
            uri.check_known(&["joint", "baud", "crc"])?;
            let joint = uri.get::<u8>("joint")?.context("kv01 URIs need ?joint=1..6")?;
            let baud = uri.get::<u32>("baud")?.unwrap_or(115_200);
            let crc = match uri.params.get("crc").map(String::as_str) {
                None | Some("strict") => crate::cli::CrcArg::Strict,
                Some("lenient") => crate::cli::CrcArg::Lenient,
                Some(other) => bail!("crc={other}: expected strict or lenient"),
            };
            let arm = super::kv01::open_arm(&uri.path, baud, crc)?;
            Ok(Box::new(motus_kv01::Kv01JointAxis::new(arm, joint)?))
        }
        "nfv2" => Ok(Box::new(motus_nfv2::open_axis(&uri).map_err(|e| anyhow::anyhow!("{e}"))?)),
        other => {
            bail!("unknown device family {other:?} in {uri_text:?} (supported: ps1a, kv01, nfv2, cia402)")
        }
    }
}

/// `cia402://<bus uri>?node=N[&inc_per_rev=213.33][&pdo=1]`: a CiA 402 drive on a CANopen
/// bus, e.g. `cia402://socketcand://127.0.0.1:29536/can0?node=2`. Positions are in
/// increments; SI is radians of the output shaft (`inc_per_rev` increments per turn).
fn open_cia402(rest: &str) -> Result<Box<dyn Axis>> {
    let (bus, query) = rest
        .rsplit_once('?')
        .context("cia402 URIs need ?node=N, e.g. cia402://socketcand://127.0.0.1:29536/can0?node=2")?;
    let mut node = None;
    let mut inc_per_rev = 12.0 * 160.0 / 9.0;
    let mut pdo = true;
    for kv in query.split('&') {
        let (k, v) = kv.split_once('=').with_context(|| format!("{kv:?}: expected key=value"))?;
        match k {
            "node" => node = Some(v.parse::<u8>().with_context(|| format!("node={v}: expected 1..127"))?),
            "inc_per_rev" => inc_per_rev = v.parse::<f64>().with_context(|| format!("inc_per_rev={v}"))?,
            "pdo" => pdo = v != "0",
            other => bail!("unknown parameter {other:?} in a cia402 URI (node, inc_per_rev, pdo)"),
        }
    }
    let node = node.filter(|n| (1..=127).contains(n)).context("cia402 URIs need ?node=1..127")?;
    let master = super::canopen::open_master(bus)?;
    let deadline = std::time::Instant::now() + Duration::from_secs(5);
    while master.node_state(node).is_none() {
        if std::time::Instant::now() > deadline {
            bail!("node {node} on {bus}: no boot-up or heartbeat within 5 s");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let mut io = motus_cia402::CanopenDrive::new(master, node);
    if pdo {
        io.use_pdos().map_err(|e| anyhow::anyhow!("{e}"))?;
    }
    let drive = motus_cia402::Drive::new(io, motus_cia402::DriveSettings::default());
    let scale = motus_axis::Scale::new(motus_axis::UnitKind::Rotary, std::f64::consts::TAU / inc_per_rev)?;
    Ok(Box::new(motus_cia402::Cia402Axis::new(
        drive,
        format!("cia402:{bus}#{node}"),
        scale,
        motus_cia402::Profile::ICLA_SEED,
    )))
}

struct Units {
    si: bool,
}

impl Units {
    fn position_in(&self, axis: &dyn Axis, v: f64) -> f64 {
        if self.si {
            v
        } else {
            axis.scale().position_to_si(v)
        }
    }
    fn rate_in(&self, axis: &dyn Axis, v: f64) -> f64 {
        if self.si {
            v
        } else {
            axis.scale().rate_to_si(v)
        }
    }
    fn show(&self, axis: &dyn Axis, s: &AxisState) -> String {
        if self.si {
            format!("{:.6} {}", s.position, axis.scale().kind().symbol())
        } else {
            format!("{} units", s.position_raw)
        }
    }
}

fn describe(axis: &dyn Axis, s: &AxisState, units: &Units) -> String {
    let f = &s.flags;
    let mut flags = vec![];
    for (on, name) in [
        (f.enabled, "enabled"),
        (f.homed, "homed"),
        (f.moving, "moving"),
        (f.target_reached, "target-reached"),
        (f.limit_negative, "limit-"),
        (f.limit_positive, "limit+"),
    ] {
        if on {
            flags.push(name);
        }
    }
    let mut text = format!("{}: position {} [{}]", axis.name(), units.show(axis, s), flags.join(" "));
    for fault in &s.faults {
        text.push_str(&format!("\n  fault: {}", fault.reason));
    }
    text
}

/// Runs one axis action.
pub fn run(a: AxisArgs) -> Result<()> {
    let mut axis = open(&a.uri)?;
    let units = Units { si: a.si };
    let profile = MotionProfile {
        velocity: a.velocity.map(|v| units.rate_in(axis.as_ref(), v)),
        acceleration: a.acceleration.map(|v| units.rate_in(axis.as_ref(), v)),
        deceleration: None,
    };
    let mut target_raw = None;
    let command = match &a.action {
        AxisAction::Status => None,
        AxisAction::Enable => Some(AxisCommand::Enable),
        AxisAction::Disable => Some(AxisCommand::Disable),
        AxisAction::Home => Some(AxisCommand::Home),
        AxisAction::MoveAbs { position } => {
            let target = units.position_in(axis.as_ref(), *position);
            target_raw = Some(axis.scale().position_from_si(target).round() as i64);
            Some(AxisCommand::MoveAbsolute { target, profile })
        }
        AxisAction::MoveRel { distance } => {
            Some(AxisCommand::MoveRelative { distance: units.rate_in(axis.as_ref(), *distance), profile })
        }
        AxisAction::Jog { direction } => {
            let direction = match direction.as_str() {
                "+" | "plus" | "positive" => Direction::Positive,
                "-" | "minus" | "negative" => Direction::Negative,
                other => bail!("jog direction must be + or -, got {other:?}"),
            };
            Some(AxisCommand::Jog { direction, profile })
        }
        AxisAction::Stop => Some(AxisCommand::Stop),
        AxisAction::QuickStop => Some(AxisCommand::QuickStop),
        AxisAction::FaultReset => Some(AxisCommand::FaultReset),
    };
    if let Some(cmd) = &command {
        if matches!(cmd, AxisCommand::MoveRelative { .. }) {
            // Resolve the absolute target for the final check.
            let s = axis.read_state()?;
            if let AxisCommand::MoveRelative { distance, .. } = cmd {
                target_raw = Some(s.position_raw + axis.scale().rate_from_si(*distance).round() as i64);
            }
        }
        axis.execute(cmd).with_context(|| format!("{} refused", cmd.name()))?;
    }
    let waits = a.wait && command.as_ref().is_some_and(AxisCommand::starts_motion);
    let state = if waits {
        let is_home = matches!(command, Some(AxisCommand::Home));
        let mut progress = Progress::new();
        let what = command.as_ref().map(AxisCommand::name).unwrap_or("motion");
        let name = axis.name().to_string();
        let res = wait_until(
            &motus_clock::SystemClock,
            axis.as_mut(),
            what,
            Duration::from_secs_f64(a.timeout.max(0.0)),
            Duration::from_millis(20),
            |s| !s.flags.moving && (!is_home || s.flags.homed),
            |s| progress.update(&format!("{name}: {what}: position {}", s.position_raw)),
        );
        progress.finish();
        let WaitOutcome::Done(state) = res?;
        if let Some(t) = target_raw {
            if !state.flags.target_reached {
                bail!("{}: motion ended at {} instead of the target {t}", axis.name(), state.position_raw);
            }
        }
        state
    } else {
        axis.read_state()?
    };
    if a.json {
        println!("{}", serde_json::to_string(&serde_json::json!({ "axis": axis.name(), "state": state }))?);
    } else {
        println!("{}", describe(axis.as_ref(), &state, &units));
    }
    Ok(())
}
