//! `motus gcode plan` and `motus gcode run`: the program through the look-ahead planner and
//! executor, without technology (plan) or on the simulated drilling machine (run).

use anyhow::{bail, Context, Result};
use motus_cnc::{DrillingTechnology, Limits3, NoTechnology, ProgramRun, RunStatus};
use motus_cnc_planner::{AxisLimits, AxisSink, METRES_PER_MM};
use serde_json::json;
use std::time::Duration;

use super::gcode::{config, read_program};
use crate::cli_cnc::{GcodeCycles, GcodePlanArgs, GcodeRunArgs};

/// Cycle of the executor (s).
const DT: f64 = 0.001;

fn limits(specs: &[String], tolerance: f64, chord: f64) -> Result<Limits3> {
    let mut l = Limits3::default();
    let parse = |s: &str| -> Result<AxisLimits> {
        let (v, a) = s.split_once(',').with_context(|| format!("--limits {s:?}: expected vmax,amax"))?;
        let velocity: f64 = v.trim().parse().with_context(|| format!("--limits {s:?}: velocity"))?;
        let acceleration: f64 = a.trim().parse().with_context(|| format!("--limits {s:?}: acceleration"))?;
        if !(velocity.is_finite() && velocity > 0.0 && acceleration.is_finite() && acceleration > 0.0) {
            bail!("--limits {s:?}: velocity and acceleration must be positive");
        }
        Ok(AxisLimits { velocity, acceleration })
    };
    match specs {
        [] => {}
        [one] => l.axes = [parse(one)?; 3],
        [x, y, z] => l.axes = [parse(x)?, parse(y)?, parse(z)?],
        _ => bail!("--limits: give one (all axes) or three (X, Y, Z)"),
    }
    if !(tolerance.is_finite() && tolerance >= 0.0 && chord.is_finite() && chord > 0.0) {
        bail!("--tolerance must be >= 0 and --chord-tolerance > 0");
    }
    l.path_tolerance = tolerance;
    l.chord_tolerance = chord;
    Ok(l)
}

/// `motus gcode plan`.
pub fn plan(a: &GcodePlanArgs) -> Result<()> {
    let src = read_program(&a.program.file)?;
    let l = limits(&a.limits, a.tolerance, a.chord_tolerance)?;
    let mut cfg = config(&a.program, GcodeCycles::Motion)?;
    cfg.require_program_end = false;
    let mut run = ProgramRun::new(&src, cfg, l, [0.0; 3])?;
    let t0 = std::time::Instant::now();
    let report = run
        .run_to_end(DT, &mut NoTechnology::default(), 24.0 * 3600.0, |_, _, _| {})
        .with_context(|| format!("{}", a.program.file.display()))?;
    let wall = t0.elapsed().as_secs_f64();
    println!(
        "{}",
        json!({
            "file": a.program.file,
            "duration_s": report.duration,
            "segments": report.segments,
            "items": report.items,
            "peak_velocity_mm_s": report.peak_velocity,
            "peak_acceleration_mm_s2": report.peak_acceleration,
            "limits": l.axes.iter().map(|x| json!({"velocity": x.velocity, "acceleration": x.acceleration})).collect::<Vec<_>>(),
            "planning_wall_s": wall,
        })
    );
    Ok(())
}

/// A cell's gantry group (X, Y, Z) and the planner limits of its axes (mm, mm/s, mm/s²).
fn gantry_of(cell_file: &std::path::Path) -> Result<(motus_station::config::Cell, Vec<String>, Limits3)> {
    let cell = motus_station::config::load(cell_file).map_err(|e| anyhow::anyhow!("{e}"))?;
    let group = cell
        .groups
        .iter()
        .find(|g| g.kind == motus_station::config::GroupKind::Gantry)
        .with_context(|| format!("{}: no [[group]] of kind \"gantry\"", cell_file.display()))?
        .axes
        .clone();
    let mut limits = Limits3::default();
    for (slot, name) in limits.axes.iter_mut().zip(&group) {
        let a = cell.axis(name).with_context(|| format!("gantry axis {name} not configured"))?;
        *slot = AxisLimits { velocity: a.max_velocity * 1000.0, acceleration: a.max_acceleration * 1000.0 };
    }
    Ok((cell, group, limits))
}

/// The gantry axes of a cell, homed, as an [`AxisSink`] for the executor.
fn gantry_sink(
    cell: &motus_station::config::Cell,
    group: &[String],
    run: &ProgramRun<'_>,
) -> Result<(motus_cell::RunningCell, AxisSink<3>)> {
    use motus_axis::{wait_until, AxisCommand, WaitOutcome};
    let running = motus_cell::open_cell(cell, motus_cell::CellOptions::default())?;
    let mut sink = AxisSink::new(run.executor().planner().config(), 1e-4);
    for (index, name) in group.iter().enumerate() {
        let mut axis = running.axis(name).with_context(|| format!("gantry axis {name} not found"))?;
        axis.execute(&AxisCommand::Enable).ok();
        axis.execute(&AxisCommand::Home).with_context(|| format!("homing {name}"))?;
        let WaitOutcome::Done(_) = wait_until(
            &motus_clock::SystemClock,
            &mut *axis,
            "homing",
            Duration::from_secs(60),
            Duration::from_millis(20),
            |s| s.flags.homed && !s.flags.moving,
            |_| {},
        )
        .with_context(|| format!("{name}: not homed"))?;
        sink.map(index, axis, METRES_PER_MM)?;
    }
    Ok((running, sink))
}

/// `motus gcode run` on the simulated drilling machine, optionally moving a cell's gantry.
pub fn run(a: &GcodeRunArgs) -> Result<()> {
    let src = read_program(&a.program.file)?;
    let mut cfg = config(&a.program, GcodeCycles::DrillingTechnology)?;
    cfg.require_program_end = false;
    let cell = a.cell.as_deref().map(gantry_of).transpose()?;
    let limits = cell.as_ref().map_or_else(Limits3::default, |(_, _, l)| *l);
    let mut run = ProgramRun::new(&src, cfg, limits, [0.0; 3])?;
    run.set_override(a.feed_override)?;
    let mut gantry = match &cell {
        Some((cell, group, _)) => Some(gantry_sink(cell, group, &run)?),
        None => None,
    };
    let mut next = std::time::Instant::now();
    let mut tech = DrillingTechnology::simulated();
    let stop = super::stop_flag()?;
    let mut last_print = -1.0;
    let mut last_state = String::new();
    let result = loop {
        if stop.load(std::sync::atomic::Ordering::Relaxed) {
            run.stop();
        }
        let (sp, status) = match run.step(DT, &mut tech) {
            Ok(x) => x,
            Err(e) => break Err(e),
        };
        if let Some((_, sink)) = gantry.as_mut() {
            // Real axes: one set-point per cycle, in real time; on doubt, stop them.
            if let Err(e) = sink.send(&sp) {
                let _ = sink.stop_all();
                run.stop();
                return Err(anyhow::anyhow!("gantry: {e}"));
            }
            next += Duration::from_secs_f64(DT);
            if let Some(wait) = next.checked_duration_since(std::time::Instant::now()) {
                std::thread::sleep(wait);
            }
        }
        let state = tech.info().state.name().to_string();
        let report = run.report();
        if sp.time - last_print >= 0.5 || state != last_state || status == RunStatus::Done {
            last_print = sp.time;
            if a.json {
                println!(
                    "{}",
                    json!({"t": sp.time, "line": report.line, "progress": report.progress(), "status": status,
                           "xyz": sp.positions, "technology": state, "holes": tech.holes().len()})
                );
            } else {
                println!(
                    "t {:7.3} s  line {:4}  {:5.1} %  {:?}  X {:8.3} Y {:8.3} Z {:8.3}  drilling: {}",
                    sp.time,
                    report.line,
                    100.0 * report.progress(),
                    status,
                    sp.positions[0],
                    sp.positions[1],
                    sp.positions[2],
                    state
                );
            }
            last_state = state;
        }
        if status == RunStatus::Done
            || (status == RunStatus::Stopped && stop.load(std::sync::atomic::Ordering::Relaxed))
        {
            break Ok(run.report().clone());
        }
    };
    for (i, h) in tech.holes().iter().enumerate() {
        println!(
            "{}",
            json!({"hole": i + 1, "x": h.tool_xy[0], "y": h.tool_xy[1], "depth_mm": h.depth, "rpm": h.spindle_rpm, "feed_mm_min": h.feed, "entries": h.entries})
        );
    }
    if let (Some((running, _)), Some((_, group, _)), Ok(_)) = (&gantry, &cell, &result) {
        // In position: the last set-point once more at the axes' own profile (a streamed
        // path's final set-points carry a near-zero speed), then where the axes ended, in mm.
        let end = run.executor().path_position();
        let mut at = serde_json::Map::new();
        for (name, target) in group.iter().zip(end) {
            if let Some(mut axis) = running.axis(name) {
                let settle = motus_axis::AxisCommand::MoveAbsolute {
                    target: target * METRES_PER_MM,
                    profile: motus_axis::MotionProfile::default(),
                };
                let _ = axis.execute(&settle);
                let _ = motus_axis::wait_until(
                    &motus_clock::SystemClock,
                    &mut *axis,
                    "in position",
                    Duration::from_secs(10),
                    Duration::from_millis(10),
                    |s| !s.flags.moving,
                    |_| {},
                );
                let pos = axis.read_state().map(|s| s.position * 1000.0).ok();
                at.insert(name.clone(), json!(pos));
            }
        }
        println!("{}", json!({ "gantry_mm": at }));
    }
    let report = result?;
    eprintln!("done in {:.3} s program time; {} holes", report.duration, tech.holes().len());
    Ok(())
}
