//! `motus kv01 <port> ...`: the KV-01 arm from the command line.
//!
//! Each invocation starts the arm controller (which keeps every module alive), runs one
//! action, stops motion and exits. The modules then latch their 700 ms safety time-out:
//! `session` keeps the arm alive across many commands read from stdin.

use crate::cli::{CrcArg, GripperOp, Kv01Action, Kv01Args, OnOff};
use anyhow::{bail, Context, Result};
use motus_kv01::{ArmConfig, Kv01Arm, Kv01Bus};
use motus_kv01_protocol::CrcMode;
use motus_serial::{BusConfig, BusMaster, SerialLink, Traced};
use std::io::BufRead;
use std::sync::Arc;
use std::time::Duration;

/// Opens the arm on `port`.
pub fn open_arm(port: &str, baud: u32, crc: CrcArg) -> Result<Arc<Kv01Arm>> {
    let link = SerialLink::open(port, baud)?;
    let mode = match crc {
        CrcArg::Strict => CrcMode::Strict,
        CrcArg::Lenient => CrcMode::Lenient,
    };
    let bus = Kv01Bus::new(Arc::new(BusMaster::new(Box::new(Traced::new(link)), BusConfig::default())), mode);
    Ok(Arc::new(Kv01Arm::start(bus, ArmConfig::default())?))
}

/// Runs one KV-01 action.
pub fn run(a: Kv01Args) -> Result<()> {
    let arm = open_arm(&a.port, a.baud, a.crc)?;
    let result = match &a.action {
        Kv01Action::Session => session(&arm, a.json),
        action => act(&arm, action, a.json),
    };
    arm.shutdown();
    result
}

/// Runs the commands of standard input, one per line. A failed command is reported and the
/// session goes on (the arm stays alive); the same error again is named in one short line
/// (a latched module refuses every later command); the exit status says how many failed.
fn session(arm: &Kv01Arm, json: bool) -> Result<()> {
    #[derive(clap::Parser)]
    #[command(no_binary_name = true)]
    struct Line {
        #[command(subcommand)]
        action: Kv01Action,
    }
    use clap::Parser;
    eprintln!("KV-01 session: one command per line (joints, move 2=30, ...); end with EOF");
    let (mut commands, mut failed) = (0usize, 0usize);
    let mut reported: Vec<String> = Vec::new();
    for line in std::io::stdin().lock().lines() {
        let line = line?;
        let words: Vec<&str> = line.split_whitespace().collect();
        if words.is_empty() || words.first().is_some_and(|w| w.starts_with('#')) {
            continue;
        }
        commands += 1;
        let error = match Line::try_parse_from(words) {
            Ok(Line { action: Kv01Action::Session }) => Some("already in a session".to_string()),
            Ok(l) => act(arm, &l.action, json).err().map(|e| crate::error_text::error_text(&e)),
            Err(e) => Some(e.to_string().lines().next().unwrap_or("invalid command").to_string()),
        };
        if let Some(text) = error {
            failed += 1;
            if reported.contains(&text) {
                println!("error: `{}`: the same error as before", line.trim());
            } else {
                println!("error: `{}`: {text}", line.trim());
                reported.push(text);
            }
        }
    }
    if failed > 0 {
        bail!("{failed} of {commands} session commands failed (see the errors above)");
    }
    Ok(())
}

fn print_joints(arm: &Kv01Arm, json: bool) -> Result<()> {
    let joints = arm.joints();
    if json {
        let list: Vec<_> = joints
            .iter()
            .map(|s| {
                serde_json::json!({
                    "joint": s.joint, "angle_deg": s.angle_deg, "raw": s.raw, "enabled": s.enabled,
                    "brake_released": s.status.brake_released, "limit_switch": s.status.limit_switch,
                    "lsstop": s.status.lsstop, "restricted_mode": s.status.restricted_mode,
                    "moving": s.moving, "fault": s.fault,
                })
            })
            .collect();
        println!("{}", serde_json::to_string(&list)?);
    } else {
        for s in &joints {
            println!(
                "joint {}: {:>9.3} deg  raw {:>5}  {}{}{}{}{}",
                s.joint,
                s.angle_deg,
                s.raw,
                if s.enabled { "enabled " } else { "" },
                if s.status.brake_released { "brake-released " } else { "" },
                if s.status.limit_switch { "LIMIT-SWITCH " } else { "" },
                if s.status.lsstop { "LSSTOP " } else { "" },
                s.fault.as_deref().map(short_fault).unwrap_or_default()
            );
        }
    }
    if let Some(f) = joints.iter().find_map(|s| s.fault.as_ref().filter(|f| f.contains("700 ms"))) {
        bail!("{f}");
    }
    Ok(())
}

/// A joint's fault for the joints table: a latched safety time-out in a few words (the full
/// explanation, with the way out, follows once below the table).
fn short_fault(fault: &str) -> String {
    if fault.contains("700 ms") {
        "\n  fault: latched its 700 ms safety time-out (see below)".to_string()
    } else {
        format!("\n  fault: {fault}")
    }
}

fn act(arm: &Kv01Arm, action: &Kv01Action, json: bool) -> Result<()> {
    match action {
        Kv01Action::Joints => print_joints(arm, json)?,
        Kv01Action::Voltages { joint } => {
            let joints: Vec<u8> = joint.map(|j| vec![j]).unwrap_or_else(|| (1..=6).collect());
            let mut out = vec![];
            for j in joints {
                let v = arm.voltages(j)?;
                out.push(serde_json::json!({"joint": j, "volts_24v": v.volts_24v(), "volts_12v": v.volts_12v(), "volts_5v": v.volts_5v()}));
                if !json {
                    println!(
                        "joint {j}: 24V {:.3} V  12V {:.3} V  5V {:.3} V",
                        v.volts_24v(),
                        v.volts_12v(),
                        v.volts_5v()
                    );
                }
            }
            if json {
                println!("{}", serde_json::to_string(&out)?);
            }
        }
        Kv01Action::Enable { joint } => {
            arm.power_up(*joint)?;
            println!("joint {joint}: enabled, brake released");
        }
        Kv01Action::Disable { joint } => {
            arm.disable(*joint)?;
            println!("joint {joint}: brake engaged, disabled");
        }
        Kv01Action::Brake { joint, state } => {
            match state {
                OnOff::On => arm.engage_brake(*joint)?,
                OnOff::Off => {
                    if !arm.joint(*joint)?.enabled {
                        // This process has not sent EN; the module's state is unknown to it.
                        bail!("joint {joint}: refusing to release the brake before the drive is enabled: run `enable {joint}` (EN, then brake release)");
                    }
                    arm.release_brake(*joint)?
                }
            }
            println!("joint {joint}: brake {}", if *state == OnOff::On { "engaged" } else { "released" });
        }
        Kv01Action::Faulhaber { joint, command } => {
            let answer = arm.faulhaber(*joint, command)?;
            if json {
                println!(
                    "{}",
                    serde_json::json!({"joint": joint, "command": command, "answer": answer.to_string()})
                );
            } else {
                println!("{answer}");
            }
        }
        Kv01Action::Move { targets, velocity, acceleration } => {
            let mut list = vec![];
            for t in targets {
                let (j, d) =
                    t.split_once('=').with_context(|| format!("expected JOINT=DEGREES, got {t:?}"))?;
                let j: u8 = j.trim().parse().with_context(|| format!("invalid joint in {t:?}"))?;
                let d: f64 = d.trim().parse().with_context(|| format!("invalid angle in {t:?}"))?;
                list.push((j, d));
            }
            if list.is_empty() {
                bail!("give at least one JOINT=DEGREES target");
            }
            arm.move_joints(&list, *velocity, *acceleration)?;
            let joints: Vec<u8> = list.iter().map(|(j, _)| *j).collect();
            arm.wait_idle(&joints, Duration::from_secs(120))?;
            print_joints(arm, json)?;
        }
        Kv01Action::RecoverLimit { joint, direction } => {
            let dir = match direction.as_str() {
                "+" => 1,
                "-" => -1,
                other => bail!("--direction must be + or -, got {other:?}"),
            };
            let s = arm.recover_limit(*joint, dir, Duration::from_secs(60), |_| {})?;
            println!(
                "joint {joint}: recovered at {:.3} deg, limit switch free, normal mode, ENPROG",
                s.angle_deg
            );
        }
        Kv01Action::Gripper { op, value } => match op {
            GripperOp::Open | GripperOp::Close => {
                let speed = value.unwrap_or(16.0).clamp(0.0, 31.0) as u8;
                let reply = arm.gripper(speed, *op == GripperOp::Open)?;
                println!("{}", serde_json::to_string(&reply)?);
            }
            GripperOp::Rotate => {
                let deg = value.context("rotate needs an angle in degrees")?;
                arm.move_joints(&[(6, deg)], None, None)?;
                arm.wait_idle(&[6], Duration::from_secs(60))?;
                print_joints(arm, json)?;
            }
        },
        Kv01Action::Session => bail!("already in a session"),
    }
    Ok(())
}
