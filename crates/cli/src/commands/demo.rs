//! `motus demo`: simulated devices started in-process (no hardware, no root) and moved
//! through a short sequence, printing status.

use crate::cli::DemoArgs;
use anyhow::{bail, Context, Result};
use motus_axis::{wait_until, Axis, AxisCommand, MotionProfile, Scale};
use motus_ps1a::{AxisConfig, Ps1aAxis, Ps1aBus};
use motus_ps1a_protocol::{Parameters, U24};
use motus_ps1a_sim::{LineOptions, SimLine};
use motus_serial::{BusConfig, BusMaster, LineSettings, PtyLink, SerialLink};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Runs the demonstration.
pub fn run(a: DemoArgs) -> Result<()> {
    let n = a.ps1a_modules;
    if !(1..=16).contains(&n) {
        bail!("--ps1a-modules must be 1..16, got {n}");
    }
    let stop = super::stop_flag()?;
    let dir = tempfile::tempdir().context("cannot create a temporary directory")?;
    let link_path = dir.path().join("ps1a-line");
    let pty = PtyLink::create(Some(&link_path), LineSettings::n81(115_200))?;
    let addresses: Vec<u8> = (1..=n).collect();
    let mut line = SimLine::new(
        Box::new(pty),
        LineOptions {
            addresses: addresses.clone(),
            state_file: Some(dir.path().join("ps1a-state.json")),
            ..LineOptions::default()
        },
    )?;
    let sim_stop = Arc::new(AtomicBool::new(false));
    let sim_flag = sim_stop.clone();
    let sim = std::thread::spawn(move || line.run(&sim_flag));
    println!("Motus demo: {n} simulated PS1A modules on {} (115200 Bd)", link_path.display());

    let link = SerialLink::open(&link_path.to_string_lossy(), 115_200)?;
    let bus = Ps1aBus::new(Arc::new(BusMaster::new(Box::new(link), BusConfig::default())));
    let found: Vec<u8> = bus.scan(0..=16).into_iter().map(|(a, _)| a).collect();
    println!("scan found modules {found:?}");
    bus.master().reset_stats();
    let mut axes = Vec::new();
    for &addr in &addresses {
        let params = Parameters {
            address: addr,
            max_position: U24::new(200_000).unwrap_or(U24::MAX),
            ..Parameters::default()
        };
        bus.write_parameters(addr, params)?;
        let config = AxisConfig {
            addr,
            max_position: params.max_position,
            speed: 2000,
            scale: Scale::HUNDREDTH_MM,
            ..AxisConfig::default()
        };
        let mut axis = Ps1aAxis::new(bus.clone(), config);
        axis.execute(&AxisCommand::Enable)?;
        axis.execute(&AxisCommand::Home)?;
        axes.push(axis);
    }
    wait_all(&mut axes, "homing", &stop)?;
    print_table(&mut axes)?;
    let sequence = [(0.25, 0.0), (0.5, 0.25), (0.05, 0.75), (0.0, 0.1)];
    for (step, (base, spread)) in sequence.iter().enumerate() {
        if stop.load(Ordering::Relaxed) {
            break;
        }
        for (i, axis) in axes.iter_mut().enumerate() {
            let target = base + spread * i as f64 / f64::from(n.max(1)) * 2.0;
            let target = (target.min(1.9) * 1.0e5).round() * 1e-5; // metres, 0.01 mm grid
            axis.execute(&AxisCommand::MoveAbsolute { target, profile: MotionProfile::default() })?;
        }
        println!("step {}: moving…", step + 1);
        wait_all(&mut axes, "move", &stop)?;
        print_table(&mut axes)?;
    }
    let stats = bus.master().stats();
    println!(
        "bus: {} transactions, {:.0}/s, {} time-outs, {} corrupt frames",
        stats.totals.ok,
        stats.transactions_per_second(),
        stats.totals.timeouts,
        stats.totals.corrupt_frames
    );
    if a.stay {
        println!("simulators keep running; Ctrl-C to stop");
        while !stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(100));
        }
    }
    for axis in &mut axes {
        let _ = axis.execute(&AxisCommand::Disable);
    }
    sim_stop.store(true, Ordering::Relaxed);
    sim.join().map_err(|_| anyhow::anyhow!("simulator thread panicked"))??;
    println!("demo finished");
    Ok(())
}

fn wait_all(axes: &mut [Ps1aAxis], what: &str, stop: &AtomicBool) -> Result<()> {
    let start = Instant::now();
    for axis in axes.iter_mut() {
        let left = Duration::from_secs(60).saturating_sub(start.elapsed());
        wait_until(
            &motus_clock::SystemClock,
            axis,
            what,
            left,
            Duration::from_millis(20),
            |s| !s.flags.moving || stop.load(Ordering::Relaxed),
            |_| {},
        )?;
    }
    Ok(())
}

fn print_table(axes: &mut [Ps1aAxis]) -> Result<()> {
    for axis in axes.iter_mut() {
        let s = axis.read_state()?;
        println!(
            "  {:<40} position {:>8} units = {:>9.5} m  {}{}",
            axis.name(),
            s.position_raw,
            s.position,
            if s.flags.homed { "homed " } else { "" },
            if s.flags.enabled { "enabled" } else { "" }
        );
    }
    Ok(())
}
