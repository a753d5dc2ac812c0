//! `motus safety check | run | approve`: the supervisor offline over a trace, online on a
//! POWERLINK segment, and the administrator's approval of its configuration.

use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::mpsc;
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{bail, Context, Result};
use motus_epl::{open_link, EthLink};
use motus_safety::{secret_hash, Approval, DriveParameters, Integrity, Mode, Restart, RuleSet, Snapshot};
use motus_safety_epl::{juggler, EplLeaseTarget, InputMap, OnlineConfig, OnlineEvent, OnlineSupervisor};
use serde::Deserialize;
use serde_json::json;

use super::epl::{read_map, read_rules};
use crate::cli::SafetyCommand;
use crate::cli_epl::{SafetyApproveArgs, SafetyRunArgs};

/// Runs a `safety` command.
pub fn run(cmd: SafetyCommand) -> Result<()> {
    match cmd {
        SafetyCommand::Check { rules, trace } => {
            let set = read_rules(&rules)?;
            let csv = std::fs::read_to_string(&trace)
                .with_context(|| format!("cannot read {}", trace.display()))?;
            let rows = motus_safety::trace::evaluate(&set, &csv)
                .with_context(|| format!("invalid trace {}", trace.display()))?;
            print!("{}", motus_safety::trace::format_rows(&set, &rows));
            Ok(())
        }
        SafetyCommand::Run(a) => online(a),
        SafetyCommand::Approve(a) => approve(a),
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DrivesFile {
    #[serde(default)]
    drive: Vec<DriveParameters>,
}

fn read_drives(path: Option<&Path>) -> Result<Vec<DriveParameters>> {
    let Some(path) = path else { return Ok(Vec::new()) };
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let f: DrivesFile =
        toml::from_str(&text).with_context(|| format!("invalid drive parameters {}", path.display()))?;
    Ok(f.drive)
}

fn read_key(path: &Path) -> Result<Vec<u8>> {
    let mut key = std::fs::read(path).with_context(|| format!("cannot read the key {}", path.display()))?;
    while key.last().is_some_and(|b| b.is_ascii_whitespace()) {
        key.pop();
    }
    Ok(key)
}

fn snapshot(rules: &Path, drives: Option<&Path>) -> Result<(RuleSet, Snapshot)> {
    let set = read_rules(rules)?;
    let d = read_drives(drives)?;
    let snap = Snapshot::new(&set, &d);
    Ok((set, snap))
}

fn approve(a: SafetyApproveArgs) -> Result<()> {
    let key = read_key(&a.key)?;
    let (_, snap) = snapshot(&a.rules, a.drives.as_deref())?;
    if let Ok(text) = std::fs::read_to_string(&a.out) {
        match Approval::from_toml(&text).and_then(|old| old.verify(&key)) {
            Ok(old) => {
                let changes = snap.diff(&old);
                if changes.is_empty() {
                    eprintln!("no change from the current approval");
                }
                for c in changes {
                    eprintln!("approving change: {c}");
                }
            }
            Err(e) => eprintln!("replacing {} ({e})", a.out.display()),
        }
    }
    let at = SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0);
    let approval = Approval::sign(&snap, &a.admin, &format!("unix:{at}"), &key)?;
    std::fs::write(&a.out, approval.to_toml()?)
        .with_context(|| format!("cannot write {}", a.out.display()))?;
    println!("{}", json!({ "approved": approval.fingerprint, "admin": a.admin, "file": a.out }));
    Ok(())
}

/// Checks the current files against the approval; `Err` names what is wrong.
fn integrity_check(
    rules: &Path,
    drives: Option<&Path>,
    approval: &Path,
    key: &[u8],
) -> std::result::Result<RuleSet, String> {
    let text =
        std::fs::read_to_string(approval).map_err(|e| format!("approval {}: {e}", approval.display()))?;
    let approved = Approval::from_toml(&text).and_then(|a| a.verify(key)).map_err(|e| e.to_string())?;
    let (set, current) = snapshot(rules, drives).map_err(|e| crate::error_text::error_text(&e))?;
    let mut integrity = Integrity::new(approved, secret_hash(key));
    integrity.check(&current).map_err(|e| e.to_string())?;
    Ok(set)
}

struct Watch {
    rules: PathBuf,
    drives: Option<PathBuf>,
    approval: PathBuf,
    key: Vec<u8>,
}

fn build(
    set: RuleSet,
    map: &Option<PathBuf>,
    link: &Arc<dyn EthLink>,
    origin: Instant,
    wire_lease: Duration,
    config: OnlineConfig,
) -> Result<OnlineSupervisor> {
    let vmap = match map {
        Some(p) => read_map(p)?,
        None => juggler::value_map(&set),
    };
    let inputs = InputMap::new(&set, vmap, motus_epl::sim::pdo::STATUS_HOMED)?;
    let renew = Duration::from_secs_f64(set.config().supervisor.cycle_time.max(0.0001));
    let target = EplLeaseTarget::new(Arc::clone(link), origin, wire_lease, renew, [0; 8]);
    Ok(OnlineSupervisor::new(set, inputs, vec![Box::new(target)], origin, config))
}

fn online(a: SafetyRunArgs) -> Result<()> {
    let set = read_rules(&a.rules)?;
    let watch = match (&a.approval, &a.key, a.no_integrity) {
        (_, _, true) => None,
        (Some(approval), Some(key), false) => Some(Watch {
            rules: a.rules.clone(),
            drives: a.drives.clone(),
            approval: approval.clone(),
            key: read_key(key)?,
        }),
        _ => bail!("--approval and --key are needed (or --no-integrity for commissioning)"),
    };
    let link = open_link(&a.interface, true).with_context(|| format!("cannot open {}", a.interface))?;
    let origin = Instant::now();
    let mode = if a.homing { Mode::Homing } else { Mode::Normal };
    let wire_lease = Duration::from_millis(a.wire_lease_ms);
    let restart = if a.auto_restart { Restart::Automatic } else { Restart::Manual };
    let config = OnlineConfig { mode, restart };
    let mut sup = build(set, &a.map, &link, origin, wire_lease, config)?;
    // Operator commands on standard input.
    let (op_tx, op_rx) = mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in std::io::stdin().lines().map_while(|l| l.ok()) {
            if op_tx.send(line.trim().to_owned()).is_err() {
                break;
            }
        }
    });

    // Integrity: checked now and re-checked every second on a helper thread.
    let (tx, rx) = mpsc::channel::<std::result::Result<RuleSet, String>>();
    let stop = super::stop_flag()?;
    match &watch {
        None => sup.set_integrity(Ok(())),
        Some(w) => {
            let first = integrity_check(&w.rules, w.drives.as_deref(), &w.approval, &w.key);
            sup.set_integrity(first.map(|_| ()));
            let (rules, drives, approval, key) =
                (w.rules.clone(), w.drives.clone(), w.approval.clone(), w.key.clone());
            let stop = Arc::clone(&stop);
            std::thread::spawn(move || {
                while !stop.load(Ordering::Relaxed) {
                    std::thread::sleep(Duration::from_secs(1));
                    if tx.send(integrity_check(&rules, drives.as_deref(), &approval, &key)).is_err() {
                        break;
                    }
                }
            });
        }
    }
    eprintln!(
        "supervising {} with {} ({} axes, {} rules){}; Ctrl-C to stop",
        link.describe(),
        a.rules.display(),
        sup.supervisor().rules().axes().len(),
        sup.supervisor().rules().rules().len(),
        if watch.is_none() { "; INTEGRITY CHECK DISABLED" } else { "" }
    );
    let end = a.duration.map(|s| Instant::now() + Duration::from_secs_f64(s.max(0.0)));
    let mut buf = vec![0u8; motus_epl::transport::MAX_FRAME];
    let mut last_integrity: std::result::Result<(), String> = Ok(());
    let poll = Duration::from_millis(1);
    while !stop.load(Ordering::Relaxed) && end.is_none_or(|e| Instant::now() < e) {
        if let Ok(result) = rx.try_recv() {
            let now_ok = result.as_ref().map(|_| ()).map_err(Clone::clone);
            match result {
                Ok(new_set) if new_set.config() != sup.supervisor().rules().config() => {
                    eprintln!("approved rules changed: reloading");
                    sup = build(new_set, &a.map, &link, origin, wire_lease, config)?;
                }
                _ => {}
            }
            if now_ok != last_integrity {
                if let Err(why) = &now_ok {
                    println!("{}", json!({ "event": "integrity", "ok": false, "diagnosis": why }));
                } else {
                    println!("{}", json!({ "event": "integrity", "ok": true }));
                }
            }
            sup.set_integrity(now_ok.clone());
            last_integrity = now_ok;
        }
        if let Ok(cmd) = op_rx.try_recv() {
            match cmd.as_str() {
                "reset" => {
                    sup.reset();
                    println!("{}", json!({ "event": "reset" }));
                }
                "stop" => {
                    sup.stop_all();
                    println!("{}", json!({ "event": "operator_stop" }));
                }
                "" => {}
                other => eprintln!("unknown command {other:?} (known: reset, stop)"),
            }
        }
        let event = match link.recv(&mut buf, poll)? {
            Some((n, at)) => {
                sup.on_frame(buf.get(..n).unwrap_or(&[]), at).or_else(|| sup.tick(Instant::now()))
            }
            None => sup.tick(Instant::now()),
        };
        let t = origin.elapsed().as_secs_f64();
        match event {
            Some(OnlineEvent::Safe { cycle, held }) => {
                println!("{}", json!({ "t": t, "event": "safe", "cycle": cycle, "held": held }));
            }
            Some(OnlineEvent::Unsafe { cycle, diagnosis, reaction, errors }) => {
                println!(
                    "{}",
                    json!({
                        "t": t, "event": "unsafe", "cycle": cycle, "diagnosis": diagnosis,
                        "reaction_us": reaction.map(|r| r.as_secs_f64() * 1e6), "errors": errors,
                    })
                );
            }
            None => {}
        }
    }
    sup.stop_all();
    let p = sup.reaction().percentiles();
    eprintln!(
        "{} frames, {} stops; reaction p50 {:.1} us p99 {:.1} us max {:.1} us over {} stops",
        sup.frames(),
        sup.stops(),
        p.p50 as f64 / 1e3,
        p.p99 as f64 / 1e3,
        p.max as f64 / 1e3,
        p.count
    );
    Ok(())
}
