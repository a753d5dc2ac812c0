//! `motus safety check | run | approve`: the supervisor offline over a trace, online on a
//! POWERLINK segment, and the administrator's approval of its configuration.

use std::ops::ControlFlow;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{bail, Context, Result};
use motus_clock::SystemClock;
use motus_epl::open_link;
use motus_epl::sim::pdo::STATUS_HOMED;
use motus_epl_protocol::SafetyNodeTiming;
use motus_safety::{config_files, ConfigFiles, Mode, Restart, RuleSet};
use motus_safety_epl::{
    juggler, Command, EplLeaseTarget, InputMap, InputsFor, IntegrityWatcher, OnlineConfig, OnlineEvent,
    OnlineSupervisor, SafetyNode, SafetyNodeConfig, ServeEvent,
};
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

fn approve(a: SafetyApproveArgs) -> Result<()> {
    let key = config_files::read_key(&a.key)?;
    let (_, snap) = config_files::read_snapshot(&a.rules, a.drives.as_deref())?;
    if a.out.exists() {
        let old = ConfigFiles {
            rules: a.rules.clone(),
            drives: a.drives.clone(),
            approval: a.out.clone(),
            key: a.key.clone(),
        };
        match old.approved(&key) {
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
    let approval = config_files::approve(&snap, &a.admin, &format!("unix:{at}"), &key, &a.out)?;
    println!("{}", json!({ "approved": approval.fingerprint, "admin": a.admin, "file": a.out }));
    Ok(())
}

/// How often `motus safety run` re-checks the configuration files.
const INTEGRITY_EVERY: Duration = Duration::from_secs(1);

fn online(a: SafetyRunArgs) -> Result<()> {
    let set = config_files::read_rules(&a.rules)?;
    let files = match (&a.approval, &a.key, a.no_integrity) {
        (_, _, true) => None,
        (Some(approval), Some(key), false) => Some(ConfigFiles {
            rules: a.rules.clone(),
            drives: a.drives.clone(),
            approval: approval.clone(),
            key: key.clone(),
        }),
        _ => bail!("--approval and --key are needed (or --no-integrity for commissioning)"),
    };
    let link = open_link(&a.interface, true).with_context(|| format!("cannot open {}", a.interface))?;
    let origin = Instant::now();
    let mode = if a.homing { Mode::Homing } else { Mode::Normal };
    let restart = if a.auto_restart { Restart::Automatic } else { Restart::Manual };
    let config = OnlineConfig { mode, restart };
    // The drives' value map: the --map file for every rule set, else the simulated drives'.
    let vmap = a.map.as_deref().map(read_map).transpose()?;
    let inputs_for: InputsFor = Box::new(move |r: &RuleSet| {
        InputMap::new(r, vmap.clone().unwrap_or_else(|| juggler::value_map(r)), STATUS_HOMED)
    });
    let inputs = inputs_for(&set)?;
    let renew = Duration::from_secs_f64(set.config().supervisor.cycle_time.max(0.0001));
    let wire_lease = Duration::from_millis(a.wire_lease_ms);
    let mut sup = match a.node {
        None => {
            let target = EplLeaseTarget::new(Arc::clone(&link), origin, wire_lease, renew, [0; 8]);
            OnlineSupervisor::new(set.clone(), inputs, vec![Box::new(target)], origin, config)
        }
        Some(node_id) => {
            let node_config = SafetyNodeConfig {
                node_id,
                timing: SafetyNodeTiming {
                    cycle: Duration::from_micros(u64::from(a.cycle_us)),
                    soc_tolerance: Duration::from_micros(u64::from(a.soc_tolerance_us)),
                },
                wire_lease,
                fingerprint: [0; 8],
            };
            let (node, target) =
                SafetyNode::new(&node_config, Arc::clone(&link), SystemClock::shared(), origin)?;
            OnlineSupervisor::new(set.clone(), inputs, vec![Box::new(target)], origin, config)
                .with_safety_node(node)
        }
    };
    let stop = super::stop_flag()?;
    let (commands, rx) = motus_realtime::mailbox::<Command>();
    // Operator commands on standard input.
    let op = commands.clone();
    std::thread::spawn(move || {
        for line in std::io::stdin().lines().map_while(|l| l.ok()) {
            let command = match line.trim() {
                "reset" => Command::Reset,
                "stop" => Command::StopAll,
                "" => continue,
                other => {
                    eprintln!("unknown command {other:?} (known: reset, stop)");
                    continue;
                }
            };
            if op.send(command).is_err() {
                break;
            }
        }
    });
    // Integrity: checked now and every second on the watcher's thread; newly approved rules
    // are installed (the drives are stopped and held until a reset).
    let watching = files.is_some();
    match files {
        None => sup.set_integrity(Ok(())),
        Some(files) => {
            IntegrityWatcher::new(files, INTEGRITY_EVERY).reload_rules(set, inputs_for).spawn(
                "safety-integrity",
                commands,
                Arc::clone(&stop),
            )?;
        }
    }
    eprintln!(
        "supervising {}{} with {} ({} axes, {} rules){}; Ctrl-C to stop",
        link.describe(),
        a.node.map_or(String::new(), |n| format!(" as safety node {n} (SafeToRun in its PRes)")),
        a.rules.display(),
        sup.supervisor().rules().axes().len(),
        sup.supervisor().rules().rules().len(),
        if watching { "" } else { "; INTEGRITY CHECK DISABLED" }
    );
    let end = a.duration.map(|s| Instant::now() + Duration::from_secs_f64(s.max(0.0)));
    let mut node_state = None;
    let result = sup.run(&*link, &rx, &stop, Duration::from_millis(1), |sup, event| {
        let t = origin.elapsed().as_secs_f64();
        match event {
            ServeEvent::Online(OnlineEvent::Safe { cycle, held }) => {
                println!("{}", json!({ "t": t, "event": "safe", "cycle": cycle, "held": held }));
            }
            ServeEvent::Online(OnlineEvent::Unsafe { cycle, diagnosis, reaction, errors }) => {
                println!(
                    "{}",
                    json!({
                        "t": t, "event": "unsafe", "cycle": cycle, "diagnosis": diagnosis,
                        "reaction_us": reaction.map(|r| r.as_secs_f64() * 1e6), "errors": errors,
                    })
                );
            }
            ServeEvent::Integrity(Ok(())) => println!("{}", json!({ "event": "integrity", "ok": true })),
            ServeEvent::Integrity(Err(why)) => {
                println!("{}", json!({ "event": "integrity", "ok": false, "diagnosis": why }));
            }
            ServeEvent::RulesInstalled => {
                eprintln!("approved rules changed: installed, the drives are held until reset");
                println!("{}", json!({ "t": t, "event": "rules_installed" }));
            }
            ServeEvent::Reset => println!("{}", json!({ "event": "reset" })),
            ServeEvent::Stopped => println!("{}", json!({ "event": "operator_stop" })),
            ServeEvent::Pass => {
                let state = sup.safety_node().map(SafetyNode::state);
                if state != node_state {
                    node_state = state;
                    if let Some(s) = state {
                        println!("{}", json!({ "t": t, "event": "node", "state": s.to_string() }));
                    }
                }
                if end.is_some_and(|e| Instant::now() >= e) {
                    return ControlFlow::Break(());
                }
            }
        }
        ControlFlow::Continue(())
    });
    sup.stop_all();
    // The watcher's thread ends with the flag (or when it finds the channel closed).
    stop.store(true, Ordering::Relaxed);
    result?;
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
    if let Some(node) = sup.safety_node() {
        let t = node.turnaround();
        let published = motus_epl::sim::Percentiles::of(node.stop_published_ns());
        eprintln!(
            "safety node {}: {} PRes, turnaround p50 {:.1} us p99 {:.1} us; stops published in the PRes \
             p50 {:.1} us max {:.1} us after the decision ({} stops)",
            node.node_id(),
            node.pres_sent(),
            t.p50 as f64 / 1e3,
            t.p99 as f64 / 1e3,
            published.p50 as f64 / 1e3,
            published.max as f64 / 1e3,
            published.count
        );
    }
    Ok(())
}
