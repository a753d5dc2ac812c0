//! Command-line definitions of the G-code / CNC commands.

use clap::{Args, Subcommand, ValueEnum};
use std::path::PathBuf;

/// `motus gcode` commands.
#[derive(Debug, Subcommand)]
pub enum GcodeCommand {
    /// Check a program: prints nothing and exits 0 when valid; otherwise the first error as
    /// `file:line:col: message` and exit status 1.
    Check(GcodeFileArgs),
    /// Print the canonical command stream, one call per line, in the call names and argument
    /// order of LinuxCNC's standalone interpreter (`rs274`), with full precision.
    Canon(GcodeCanonArgs),
    /// Plan a program under axis limits: duration, peak velocities and accelerations, segment
    /// count (JSON).
    Plan(GcodePlanArgs),
    /// Run a program on the simulated drilling machine (or a cell), with progress.
    Run(GcodeRunArgs),
}

/// A program file.
#[derive(Debug, Args)]
pub struct GcodeFileArgs {
    /// The program (RS274/NGC, LinuxCNC dialect, plus M60-M64 and EX parameters).
    pub file: PathBuf,
    /// M-functions that do not pause the program (default: all are synchronous).
    #[arg(long, value_delimiter = ',')]
    pub async_m: Vec<u16>,
    /// The tool table for T, M6 and G43 (LinuxCNC's `.tbl` format, lengths in mm).
    #[arg(long)]
    pub tool_table: Option<PathBuf>,
    /// What M60-M68 mean: the seed's M-functions, or LinuxCNC's pallet, tool and I/O codes.
    #[arg(long, value_enum, default_value = "seed")]
    pub dialect: GcodeDialect,
    /// How canned cycles (G73, G81-G89) reach the machine: LinuxCNC's Z moves, or the
    /// drilling unit's M60 job per hole. Default: `drilling-technology` for `run` (the
    /// simulated drilling machine), `motion` for the other commands.
    #[arg(long, value_enum)]
    pub cycles: Option<GcodeCycles>,
}

/// Where canned cycles go (`--cycles`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum GcodeCycles {
    /// LinuxCNC's moves: rapids and feeds of Z on the path.
    Motion,
    /// The seed's drilling technology: per hole X/Y over it, EXW60 (S), EXF61 (F), EXF62
    /// (-Z, Z0 = the material surface), EXF63/EXB64 (pecks of G83/G73), M60; M6 -> M63.
    DrillingTechnology,
}

/// The machine's M-code dialect (`--dialect`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum GcodeDialect {
    /// M60-M68 are the seed's M-functions (`M_FUNCTION(62, SYNC)`).
    Seed,
    /// M60-M68 as in LinuxCNC: pallet shuttle, M61 Q, digital/analog outputs, M66 wait.
    #[value(name = "linuxcnc")]
    LinuxCnc,
}

/// Options of `motus gcode canon`.
#[derive(Debug, Args)]
pub struct GcodeCanonArgs {
    /// The program.
    #[command(flatten)]
    pub program: GcodeFileArgs,
    /// Number the lines and print 4 decimals exactly like `rs274` (`%5d N..... CALL`).
    #[arg(long)]
    pub rs274: bool,
}

/// Options of `motus gcode plan`.
#[derive(Debug, Args)]
pub struct GcodePlanArgs {
    /// The program.
    #[command(flatten)]
    pub program: GcodeFileArgs,
    /// Per-axis limits `vmax,amax` in mm/s and mm/s² for X, Y, Z (e.g. `--limits 200,2000`
    /// for all, or `--limits 200,2000 --limits 200,2000 --limits 50,500`).
    #[arg(long)]
    pub limits: Vec<String>,
    /// Path tolerance (mm) for corner blending.
    #[arg(long, default_value_t = 0.05)]
    pub tolerance: f64,
    /// Chord tolerance (mm) for arcs.
    #[arg(long, default_value_t = 0.01)]
    pub chord_tolerance: f64,
}

/// Options of `motus gcode run`.
#[derive(Debug, Args)]
pub struct GcodeRunArgs {
    /// The program.
    #[command(flatten)]
    pub program: GcodeFileArgs,
    /// Cell configuration: the program also moves the cell's gantry axes (X, Y, Z of its
    /// `gantry` group, homed first), in real time, planned within their limits. The drilling
    /// technology is simulated.
    #[arg(long)]
    pub cell: Option<PathBuf>,
    /// Feed override in percent (0..200).
    #[arg(long, default_value_t = 100.0)]
    pub feed_override: f64,
    /// Progress lines as JSON.
    #[arg(long)]
    pub json: bool,
}
