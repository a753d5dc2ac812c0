//! The command-line grammar (clap).

use clap::{Args, Parser, Subcommand, ValueEnum};
use std::path::PathBuf;

/// Motus: drive and supervise servo drives on field buses, and simulate them.
#[derive(Debug, Parser)]
#[command(name = "motus", version, about)]
pub struct Cli {
    /// Log debug messages to stderr (or set MOTUS_LOG, e.g. MOTUS_LOG=trace).
    #[arg(short, long, global = true)]
    pub verbose: bool,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Top-level commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Decode one frame given as hex bytes; prints one JSON object.
    Decode {
        /// Frame format.
        format: FrameFormat,
        /// Hex bytes, e.g. "03 00 00 03" or 03000003.
        hex: String,
        /// CRC checking (KV-01): strict rejects a bad CRC; lenient accepts it and reports it.
        #[arg(long, value_enum, default_value = "strict")]
        crc: CrcArg,
        /// Direction (KV-01): auto guesses from the frame's shape.
        #[arg(long, value_enum, default_value = "auto")]
        direction: DirectionArg,
        /// Protocol revision (NFv2): 2012, 2013, 2014 or latest.
        #[arg(long, default_value = "latest")]
        revision: String,
    },
    /// Encode one frame given as JSON; prints uppercase hex bytes.
    Encode {
        /// Frame format.
        format: FrameFormat,
        /// The frame as JSON (the form `decode` prints).
        json: String,
        /// Protocol revision (NFv2): 2012, 2013, 2014 or latest.
        #[arg(long, default_value = "latest")]
        revision: String,
    },
    /// Run a device simulator.
    #[command(subcommand)]
    Sim(SimCommand),
    /// Command one axis named by a URI, e.g. ps1a:///dev/ttyUSB0?addr=3.
    Axis(AxisArgs),
    /// PS1A line tools: scan for modules, parameters.
    Ps1a(Ps1aArgs),
    /// KV-01 arm: joints, voltages, brakes, Faulhaber pass-through, limit recovery, gripper.
    Kv01(Kv01Args),
    /// NFv2 line tools: send any frame and print the decoded answer.
    Nfv2(Nfv2Args),
    /// The pan-tilt camera head on two 1209A controllers.
    Pantilt(PanTiltArgs),
    /// The whole simulated cell with the station and its web HMI (no hardware, no root);
    /// `--ps1a-sequence` runs the older PS1A-only demonstration sequence instead.
    Demo(DemoArgs),
    /// The virtual CAN bus (socketcand hub).
    #[command(subcommand)]
    Canbus(crate::cli_can::CanbusCommand),
    /// CANopen master: NMT, SDO, PDO, LSS, scan, dump.
    Canopen(crate::cli_can::CanopenArgs),
    /// The omnidirectional robot on three CANopen drives.
    Robot(crate::cli_can::RobotArgs),
    /// The predictive collision supervisor.
    #[command(subcommand)]
    Safety(SafetyCommand),
    /// Ethernet POWERLINK tools.
    #[command(subcommand)]
    Epl(crate::cli_epl::EplCommand),
    /// G-code: check, canonical stream (diffable with LinuxCNC's rs274), plan, run.
    #[command(subcommand)]
    Gcode(crate::cli_cnc::GcodeCommand),
    /// Station users (offline; passwords from standard input).
    User(crate::cli_station::UserArgs),
    /// Run a station: the cell's devices, the supervisor, programs, and the web HMI/API.
    Serve(crate::cli_station::ServeArgs),
}

/// `motus safety` commands.
#[derive(Debug, Subcommand)]
pub enum SafetyCommand {
    /// Evaluate a recorded or generated trace offline: SafeToRun and the diagnosis for
    /// every sample (deterministic).
    Check {
        /// Rules file (TOML), e.g. crates/safety/examples/juggler.toml.
        #[arg(long)]
        rules: PathBuf,
        /// Trace (CSV: time, then position and speed per axis).
        #[arg(long)]
        trace: PathBuf,
    },
    /// Supervise a POWERLINK segment online: SafeToRun as a safety lease to every drive,
    /// quick stop (lease revoke) the moment a rule fails; prints every change as JSON lines.
    /// Standard input takes operator commands: `reset` (restart after a stop), `stop`.
    Run(crate::cli_epl::SafetyRunArgs),
    /// Administrator action: approve the rules and drive parameters (signed approval file).
    Approve(crate::cli_epl::SafetyApproveArgs),
}

/// Frame formats of `decode` / `encode`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FrameFormat {
    /// PS1A command, host -> module.
    Ps1aCmd,
    /// PS1A status reply, module -> host.
    Ps1aReply,
    /// KV-01 message, either direction.
    Kv01,
    /// NFv2 frame (any number of commands and queries).
    Nfv2,
    /// CANopen frame in candump notation, e.g. `581#4B64600000000000` (`<id>#<hex>`).
    Canopen,
    /// Ethernet POWERLINK frame: the whole Ethernet II frame as hex.
    Epl,
}

/// CRC checking of received frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CrcArg {
    /// Reject a bad CRC, showing the expected and received value.
    Strict,
    /// Accept a bad CRC but report it.
    Lenient,
}

/// Direction of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DirectionArg {
    /// Guess from the frame's shape.
    Auto,
    /// Host -> device.
    ToDevice,
    /// Device -> host.
    FromDevice,
}

/// Simulators.
#[derive(Debug, Subcommand)]
pub enum SimCommand {
    /// Simulated PS1A modules on one line.
    Ps1a(SimPs1aArgs),
    /// The simulated KV-01 arm: six communication modules on one line.
    Kv01(SimKv01Args),
    /// Simulated 1209A axis controllers (NFv2) on one line.
    Nfv2(SimNfv2Args),
    /// Simulated IclA CiA 402 drives on a CAN bus (optionally forming the robot).
    Icla(crate::cli_can::SimIclaArgs),
    /// The simulated optical-mouse odometry converter on a pty.
    Mouse(crate::cli_can::SimMouseArgs),
    /// A simulated POWERLINK segment: Managing Node and servo-drive CNs (the juggler).
    Epl(crate::cli_epl::SimEplArgs),
}

/// Options of `motus sim nfv2`.
#[derive(Debug, Args)]
pub struct SimNfv2Args {
    /// Where to serve: `pty:PATH` or `serial:DEVICE`.
    #[arg(long)]
    pub link: String,
    /// Controller addresses, comma-separated.
    #[arg(long, value_delimiter = ',', required = true)]
    pub addr: Vec<u8>,
    /// Nominal baud rate of the line (RS-485: 57600).
    #[arg(long, default_value_t = 57_600)]
    pub baud: u32,
    /// Bytes take their real wire time at --baud.
    #[arg(long)]
    pub baud_pacing: bool,
    /// Probability of dropping an answer (0..1).
    #[arg(long, default_value_t = 0.0)]
    pub drop_rate: f64,
    /// Probability of corrupting each byte, in both directions (0..1).
    #[arg(long, default_value_t = 0.0)]
    pub corrupt_rate: f64,
    /// Processing delay before an answer (ms).
    #[arg(long)]
    pub delay_ms: Option<f64>,
    /// Protocol revision: 2012, 2013, 2014 or latest.
    #[arg(long, default_value = "latest")]
    pub revision: String,
    /// Seed of the fault injection and the measurement noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Controller configuration (JSON of the simulator's ControllerConfig).
    #[arg(long)]
    pub controller: Option<String>,
}

/// Options of `motus sim kv01`.
#[derive(Debug, Args)]
pub struct SimKv01Args {
    /// Where to serve: `pty:PATH` or `serial:DEVICE`.
    #[arg(long)]
    pub link: String,
    /// Bytes take their real wire time at --baud.
    #[arg(long)]
    pub baud_pacing: bool,
    /// Nominal baud rate of the line.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// Probability of dropping a reply (0..1).
    #[arg(long, default_value_t = 0.0)]
    pub drop_rate: f64,
    /// Probability of corrupting each byte, in both directions (0..1).
    #[arg(long, default_value_t = 0.0)]
    pub corrupt_rate: f64,
    /// Faulhaber controllers answer this late (ms): the modules answer "TIMEOUT".
    #[arg(long)]
    pub slow_controller_ms: Option<u64>,
    /// Seed of the fault injection and the measurement noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Arm configuration (JSON of the simulator's ArmConfig).
    #[arg(long)]
    pub arm: Option<String>,
}

/// Options of `motus sim ps1a`.
#[derive(Debug, Args)]
pub struct SimPs1aArgs {
    /// Where to serve: `pty:PATH` creates a pseudo-terminal with a symlink at PATH;
    /// `serial:DEVICE` serves a real serial port.
    #[arg(long)]
    pub link: String,
    /// Factory addresses of the modules, comma-separated (1 to 16 modules).
    #[arg(long, value_delimiter = ',', required = true)]
    pub addr: Vec<u8>,
    /// State file: EEPROM parameters and machine positions survive a restart.
    #[arg(long)]
    pub state_file: Option<PathBuf>,
    /// Bytes take their real wire time at --baud.
    #[arg(long)]
    pub baud_pacing: bool,
    /// Nominal baud rate of the line.
    #[arg(long, default_value_t = 9600)]
    pub baud: u32,
    /// Probability of dropping a reply (0..1).
    #[arg(long, default_value_t = 0.0)]
    pub drop_rate: f64,
    /// Probability of corrupting each byte, in both directions (0..1).
    #[arg(long, default_value_t = 0.0)]
    pub corrupt_rate: f64,
    /// Seed of the fault injection.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulated machine (JSON object with MachineConfig fields, e.g. '{"limit_positive": 20000}').
    #[arg(long)]
    pub machine: Option<String>,
}

/// Options of `motus axis`.
#[derive(Debug, Args)]
pub struct AxisArgs {
    /// The axis, e.g. ps1a:///dev/ttyUSB0?addr=3&baud=9600.
    pub uri: String,
    /// What to do.
    #[command(subcommand)]
    pub action: AxisAction,
    /// Wait until the motion ends (home, moves, jog).
    #[arg(long, global = true)]
    pub wait: bool,
    /// Print JSON instead of text.
    #[arg(long, global = true)]
    pub json: bool,
    /// Positions in SI units (m or rad) instead of device units.
    #[arg(long, global = true)]
    pub si: bool,
    /// Velocity for moves and jogs (device units/s, or m/s with --si).
    #[arg(long, global = true)]
    pub velocity: Option<f64>,
    /// Acceleration (device units/s^2, or m/s^2 with --si).
    #[arg(long, global = true)]
    pub acceleration: Option<f64>,
    /// Give up waiting after this many seconds.
    #[arg(long, global = true, default_value_t = 120.0)]
    pub timeout: f64,
}

/// Axis actions.
#[derive(Debug, Subcommand)]
pub enum AxisAction {
    /// Print the axis state.
    Status,
    /// Switch the drive / power stage on.
    Enable,
    /// Switch the drive / power stage off.
    Disable,
    /// Run the homing procedure.
    Home,
    /// Move to an absolute position.
    #[command(allow_negative_numbers = true)]
    MoveAbs {
        /// Target position.
        position: f64,
    },
    /// Move by a distance.
    #[command(allow_negative_numbers = true)]
    MoveRel {
        /// Signed distance.
        distance: f64,
    },
    /// Move continuously: + or -.
    Jog {
        /// Direction: + or -.
        #[arg(allow_hyphen_values = true)]
        direction: String,
    },
    /// Decelerate to standstill.
    Stop,
    /// Stop as fast as the device can.
    QuickStop,
    /// Clear latched faults whose cause is gone.
    FaultReset,
}

/// Options of `motus ps1a`.
#[derive(Debug, Args)]
pub struct Ps1aArgs {
    /// Serial port or simulator pty link.
    pub port: String,
    /// Baud rate.
    #[arg(long, default_value_t = 9600, global = true)]
    pub baud: u32,
    /// Print JSON.
    #[arg(long, global = true)]
    pub json: bool,
    /// What to do.
    #[command(subcommand)]
    pub action: Ps1aAction,
}

/// PS1A line actions.
#[derive(Debug, Subcommand)]
pub enum Ps1aAction {
    /// Find the modules present on the line.
    Scan {
        /// Address range to probe, e.g. 0-15 (default 0-255).
        #[arg(long, default_value = "0-255")]
        range: String,
        /// Time-out margin per address in ms.
        #[arg(long, default_value_t = 5)]
        margin_ms: u64,
    },
    /// Module parameters (command 1).
    #[command(subcommand)]
    Params(ParamsAction),
}

/// Parameter actions.
#[derive(Debug, Subcommand)]
pub enum ParamsAction {
    /// Show the parameters Motus last wrote to a module (the PS1A cannot report them).
    Get {
        /// Module address.
        #[arg(long)]
        addr: u8,
    },
    /// Write parameters to a module (stored in its EEPROM). Fields not given keep the
    /// values last written by Motus, or the factory defaults.
    Set(ParamsSet),
}

/// Fields of `params set`.
#[derive(Debug, Args)]
pub struct ParamsSet {
    /// Module address to write to.
    #[arg(long)]
    pub addr: u8,
    /// New module address (ADR).
    #[arg(long)]
    pub new_addr: Option<u8>,
    /// DS: fraction x/256 of a unit per DDA cycle at unit speed.
    #[arg(long)]
    pub ds: Option<u8>,
    /// TVZ: DDA cycle code 0..3 (1.54, 2.1, 2.66, 4.2 ms).
    #[arg(long)]
    pub tvz: Option<u8>,
    /// COMS: baud-rate code 0..3 (9600, 19200, 29070, 33784).
    #[arg(long)]
    pub coms: Option<u8>,
    /// Maximum position (units, 24 bit).
    #[arg(long)]
    pub max: Option<u32>,
    /// VNRB: reference approach speed.
    #[arg(long)]
    pub vnrb: Option<u8>,
    /// ANRB: reference approach acceleration number 1..10.
    #[arg(long)]
    pub anrb: Option<u8>,
    /// VNNB: zero-pulse approach speed.
    #[arg(long)]
    pub vnnb: Option<u8>,
    /// ANNB: zero-pulse approach acceleration number 1..10.
    #[arg(long)]
    pub annb: Option<u8>,
    /// Extra reply time-out on top of the wire time (ms): raise it for slow adapters or a
    /// loaded host.
    #[arg(long, default_value_t = 20)]
    pub margin_ms: u64,
}

/// Options of `motus kv01`.
#[derive(Debug, Args)]
pub struct Kv01Args {
    /// Serial port (or simulator pty link) of the arm's interface box.
    pub port: String,
    /// Baud rate.
    #[arg(long, default_value_t = 115_200, global = true)]
    pub baud: u32,
    /// Reply CRC checking.
    #[arg(long, value_enum, default_value = "strict", global = true)]
    pub crc: CrcArg,
    /// Print JSON.
    #[arg(long, global = true)]
    pub json: bool,
    /// What to do.
    #[command(subcommand)]
    pub action: Kv01Action,
}

/// KV-01 actions.
#[derive(Debug, Clone, Subcommand)]
pub enum Kv01Action {
    /// Read all six joint angles and status bits in one call.
    Joints,
    /// Read the supply voltages of one module (or all).
    Voltages {
        /// Joint 1..6 (all if omitted).
        joint: Option<u8>,
    },
    /// Enable a joint's drive ("EN") and release its brake, in the safe order.
    Enable {
        /// Joint 1..6.
        joint: u8,
    },
    /// Engage a joint's brake and disable its drive ("DI"), in the safe order.
    Disable {
        /// Joint 1..6.
        joint: u8,
    },
    /// Brake on (engage) or off (release; refused before "EN").
    Brake {
        /// Joint 1..5.
        joint: u8,
        /// on = engaged, off = released.
        state: OnOff,
    },
    /// Send a Faulhaber ASCII command through D0 and print the answer.
    Faulhaber {
        /// Joint 1..6.
        joint: u8,
        /// The command, e.g. "GN" or "V100".
        command: String,
    },
    /// Move joints to angles together, e.g. `move 2=30 3=-45.5`.
    #[command(allow_negative_numbers = true)]
    Move {
        /// JOINT=DEGREES pairs.
        targets: Vec<String>,
        /// Joint velocity (deg/s).
        #[arg(long)]
        velocity: Option<f64>,
        /// Joint acceleration (deg/s^2).
        #[arg(long)]
        acceleration: Option<f64>,
    },
    /// Drive a joint out of its limit switch with the documented procedure.
    RecoverLimit {
        /// Joint 1, 2, 3 or 5.
        joint: u8,
        /// + or -: the direction back into the working zone.
        #[arg(long, allow_hyphen_values = true)]
        direction: String,
    },
    /// Gripper: open, close (speed 0..31), or rotate to an angle in degrees.
    Gripper {
        /// open, close or rotate.
        op: GripperOp,
        /// Speed 0..31 for open/close (default 16); angle in degrees for rotate.
        #[arg(allow_negative_numbers = true)]
        value: Option<f64>,
    },
    /// Keep the arm alive and read commands (the actions above, one per line) from stdin.
    Session,
}

/// Brake state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OnOff {
    /// Engaged.
    On,
    /// Released.
    Off,
}

/// Gripper operations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum GripperOp {
    /// Open.
    Open,
    /// Close.
    Close,
    /// Rotate to an angle.
    Rotate,
}

/// Options of `motus nfv2`.
#[derive(Debug, Args)]
pub struct Nfv2Args {
    /// Serial port (or simulator pty link).
    pub port: String,
    /// Baud rate (RS-485: 57600).
    #[arg(long, default_value_t = 57_600, global = true)]
    pub baud: u32,
    /// Protocol revision: 2012, 2013, 2014 or latest.
    #[arg(long, default_value = "latest", global = true)]
    pub revision: String,
    /// Extra reply time-out on top of the wire time (ms): raise it for slow adapters or a
    /// loaded host.
    #[arg(long, default_value_t = 20, global = true)]
    pub margin_ms: u64,
    /// What to do.
    #[command(subcommand)]
    pub action: Nfv2Action,
}

/// NFv2 actions.
#[derive(Debug, Subcommand)]
pub enum Nfv2Action {
    /// Send a frame given as JSON (the `decode nfv2` form) and print the answer as JSON.
    Raw {
        /// The frame.
        json: String,
    },
}

/// Options of `motus pantilt`.
#[derive(Debug, Args)]
pub struct PanTiltArgs {
    /// Serial port (or simulator pty link) of the RS-485 bus.
    pub port: String,
    /// Baud rate.
    #[arg(long, default_value_t = 57_600, global = true)]
    pub baud: u32,
    /// Address of the pan controller.
    #[arg(long, default_value_t = 1, global = true)]
    pub pan_addr: u8,
    /// Address of the tilt controller.
    #[arg(long, default_value_t = 2, global = true)]
    pub tilt_addr: u8,
    /// No valid answer from a controller for this long (ms) is a communication fault.
    #[arg(long, default_value_t = 500, global = true)]
    pub silence_ms: u64,
    /// Extra reply time-out on top of the wire time (ms): raise it for slow adapters or a
    /// loaded host.
    #[arg(long, default_value_t = 20, global = true)]
    pub margin_ms: u64,
    /// Print JSON.
    #[arg(long, global = true)]
    pub json: bool,
    /// What to do.
    #[command(subcommand)]
    pub action: PanTiltAction,
}

/// Pan-tilt actions.
#[derive(Debug, Subcommand)]
pub enum PanTiltAction {
    /// Home both axes.
    Home,
    /// Move to (pan, tilt) in degrees; both axes arrive together.
    #[command(allow_negative_numbers = true)]
    Goto {
        /// Pan angle, degrees.
        pan: f64,
        /// Tilt angle, degrees.
        tilt: f64,
    },
    /// Track a target stream: lines `t pan tilt` (s, deg, deg) from a file or `-` (stdin).
    Track {
        /// File, or `-` for stdin.
        source: String,
    },
    /// Where the head was `t` seconds after the command started (from timestamped samples).
    Where {
        /// Seconds after the start (>= 0).
        t: f64,
    },
}

/// Options of `motus demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Address of the HMI.
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub listen: String,
    /// Run the PS1A-only demonstration sequence instead (simulated modules moved through a
    /// few steps, printed as a table).
    #[arg(long)]
    pub ps1a_sequence: bool,
    /// Number of simulated PS1A modules (with --ps1a-sequence).
    #[arg(long, default_value_t = 4)]
    pub ps1a_modules: u8,
    /// Keep the simulators running after the sequence until Ctrl-C (with --ps1a-sequence).
    #[arg(long)]
    pub stay: bool,
    /// Write the demo cell into this new (or empty) directory and exit, to run it with
    /// `motus serve --config DIR/demo-cell.toml`: the cell file, its programs, the juggler's
    /// rules and drive parameters approved with a fresh administrator key (`DIR/data`).
    #[arg(long, value_name = "DIR", conflicts_with = "ps1a_sequence")]
    pub write_cell: Option<std::path::PathBuf>,
    /// Real-time priorities of the device and cyclic threads (docs/decisions.md): `auto` by
    /// default (SCHED_FIFO where permitted, else nice levels and a warning).
    #[arg(long, value_enum, default_value_t = crate::cli_station::RealtimeArg::Auto)]
    pub realtime: crate::cli_station::RealtimeArg,
}
