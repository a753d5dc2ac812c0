//! `motus gcode plan` and `motus gcode run`: the program through the look-ahead planner and
//! executor, without technology (plan) or on the simulated drilling machine (run).

use anyhow::{bail, Context, Result};
use motus_cnc::{DrillingTechnology, Limits3, NoTechnology, ProgramRun, RunStatus};
use motus_cnc_planner::AxisLimits;
use serde_json::json;

use super::gcode::{config, read_program};
use crate::cli_cnc::{GcodePlanArgs, GcodeRunArgs};

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
    let mut cfg = config(&a.program);
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

/// `motus gcode run` on the simulated drilling machine.
pub fn run(a: &GcodeRunArgs) -> Result<()> {
    if a.cell.is_some() {
        bail!("--cell: running on a configured cell needs the station (`motus serve`); without --cell the program runs on the simulated drilling machine");
    }
    let src = read_program(&a.program.file)?;
    let mut cfg = config(&a.program);
    cfg.require_program_end = false;
    let mut run = ProgramRun::new(&src, cfg, Limits3::default(), [0.0; 3])?;
    run.set_override(a.feed_override)?;
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
            json!({"hole": i + 1, "x": h.tool_xy[0], "y": h.tool_xy[1], "depth_mm": h.depth, "rpm": h.spindle_rpm, "feed_mm_min": h.feed})
        );
    }
    let report = result?;
    eprintln!("done in {:.3} s program time; {} holes", report.duration, tech.holes().len());
    Ok(())
}
