//! `motus gcode check | canon | plan | run`.

use std::io::Write;
use std::path::Path;

use anyhow::{Context, Result};
use motus_gcode::{
    format_canon, format_line, CycleOutput, Interpreter, InterpreterConfig, MCodeDialect, Precision,
};

use crate::cli_cnc::{GcodeCanonArgs, GcodeCommand, GcodeCycles, GcodeDialect, GcodeFileArgs};

/// Runs a `gcode` command.
pub fn run(cmd: GcodeCommand) -> Result<()> {
    match cmd {
        GcodeCommand::Check(a) => check(&a),
        GcodeCommand::Canon(a) => canon(&a),
        GcodeCommand::Plan(a) => super::cnc::plan(&a),
        GcodeCommand::Run(a) => super::cnc::run(&a),
    }
}

/// Reads a program file.
pub fn read_program(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))
}

/// The interpreter configuration of the command-line options (canned cycles as `cycles`
/// unless `--cycles` says otherwise).
///
/// # Errors
/// The tool table cannot be read or has a bad line.
pub fn config(a: &GcodeFileArgs, cycles: GcodeCycles) -> Result<InterpreterConfig> {
    let tools = match &a.tool_table {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read the tool table {}", path.display()))?;
            motus_gcode::parse_tool_table(&text, motus_gcode::Units::Mm)
                .with_context(|| format!("tool table {}", path.display()))?
        }
        None => Vec::new(),
    };
    let m_codes = match a.dialect {
        GcodeDialect::Seed => MCodeDialect::Seed,
        GcodeDialect::LinuxCnc => MCodeDialect::LinuxCnc,
    };
    let cycles = match a.cycles.unwrap_or(cycles) {
        GcodeCycles::Motion => CycleOutput::Motion,
        GcodeCycles::DrillingTechnology => CycleOutput::DrillingTechnology,
    };
    Ok(InterpreterConfig {
        async_m_functions: a.async_m.clone(),
        tools,
        m_codes,
        cycles,
        ..InterpreterConfig::default()
    })
}

fn check(a: &GcodeFileArgs) -> Result<()> {
    let src = read_program(&a.file)?;
    let mut calls = 0usize;
    for c in Interpreter::with_config(&src, config(a, GcodeCycles::Motion)?) {
        match c {
            Ok(_) => calls += 1,
            Err(e) => return Err(anyhow::anyhow!("{}", e.with_file(a.file.display().to_string()))),
        }
    }
    eprintln!("{}: ok ({} lines, {calls} canonical calls)", a.file.display(), src.lines().count());
    Ok(())
}

fn canon(a: &GcodeCanonArgs) -> Result<()> {
    let src = read_program(&a.program.file)?;
    let out = std::io::stdout();
    let mut out = std::io::BufWriter::new(out.lock());
    for (k, c) in Interpreter::with_config(&src, config(&a.program, GcodeCycles::Motion)?).enumerate() {
        match c {
            Ok(c) if a.rs274 => {
                let counter = u32::try_from(k + 1).unwrap_or(u32::MAX);
                writeln!(out, "{}", format_line(counter, &c, Precision::Rs274))?;
            }
            Ok(c) => writeln!(out, "{}", format_canon(&c.canon, Precision::Full))?,
            Err(e) => {
                out.flush()?;
                return Err(anyhow::anyhow!("{}", e.with_file(a.program.file.display().to_string())));
            }
        }
    }
    out.flush()?;
    Ok(())
}
