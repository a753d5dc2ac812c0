//! Command-line definitions of the POWERLINK and online-supervisor commands.

use clap::{Args, Subcommand};
use std::path::PathBuf;

/// `motus epl` commands.
#[derive(Debug, Subcommand)]
pub enum EplCommand {
    /// Watch a segment passively and print every cycle as a JSON line (PRes seen, missing
    /// nodes, lost frames, frame counters; with --map, per mapped node fresh/stale, NMT state
    /// and values), then a summary (frames received/decoded/undecoded/dropped, the kernel's
    /// counters, per-node PRes, misses and NMT states).
    Monitor(EplMonitorArgs),
}

/// Options of `motus epl monitor`.
#[derive(Debug, Args)]
pub struct EplMonitorArgs {
    /// Link to listen on: an interface name (raw socket, needs CAP_NET_RAW; promiscuous) or
    /// `udp://127.0.0.1:3819` (the unprivileged UDP segment of `motus sim epl`).
    #[arg(long = "if", conflicts_with = "pcap", required_unless_present = "pcap")]
    pub interface: Option<String>,
    /// Replay a capture (pcap or pcapng) instead of listening.
    #[arg(long)]
    pub pcap: Option<PathBuf>,
    /// Value map (TOML `[[node]]` tables: node, values = [{ name, offset, type }]); without
    /// it, a cycle-only watch (cycles, PRes, misses, NMT states, timing).
    #[arg(long)]
    pub map: Option<PathBuf>,
    /// A value older than this many cycles is stale.
    #[arg(long, default_value_t = 0)]
    pub stale_after: u32,
    /// Stop after this many cycles (default: until Ctrl-C or the end of the capture).
    #[arg(long)]
    pub cycles: Option<u64>,
    /// Print one cycle line in N (cycles with a missing node or lost frames are always
    /// printed; every line carries the cumulative counters).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
    pub every: u64,
    /// Receive queue asked for the raw socket, in bytes (SO_RCVBUFFORCE when permitted, else
    /// SO_RCVBUF up to net.core.rmem_max); a larger queue drops fewer frames when the monitor
    /// falls behind.
    #[arg(long, default_value_t = 4 << 20)]
    pub rcvbuf: usize,
}

/// Options of `motus sim epl`.
#[derive(Debug, Args)]
pub struct SimEplArgs {
    /// Where the segment runs: `udp://127.0.0.1:3819` (every node joins the unprivileged UDP
    /// segment there), or a comma-separated list of interfaces, the Managing Node's first and
    /// then one per drive in the config's axis order (raw sockets, needs CAP_NET_RAW).
    #[arg(long = "if")]
    pub interface: String,
    /// Machine config: a supervisor rules file (each `[[axis]]` becomes the drive whose node ID
    /// is its `id`), e.g. crates/safety/examples/juggler.toml.
    #[arg(long)]
    pub config: PathBuf,
    /// Motion program: juggle (safe cam), limit or collide (student errors), or a CSV file of
    /// timed set-points (`time_s,raw_axis1,raw_axis2,...`, held between rows).
    #[arg(long, default_value = "juggle")]
    pub program: String,
    /// Cycle time in microseconds (down to 400).
    #[arg(long, default_value_t = 1000)]
    pub cycle_us: u64,
    /// Drives run only under the supervisor's safety lease, and stop this many milliseconds
    /// after the last renewal (0: leases ignored).
    #[arg(long, default_value_t = 20)]
    pub lease_ms: u64,
    /// Record the Managing Node's view (every frame it sends and receives) to a pcap file.
    #[arg(long)]
    pub pcap: Option<PathBuf>,
}

/// Options of `motus safety run`.
#[derive(Debug, Args)]
pub struct SafetyRunArgs {
    /// Rules file (TOML); re-read every second: a change without a new approval blocks motion.
    #[arg(long)]
    pub rules: PathBuf,
    /// Link to the segment: an interface name (raw socket) or `udp://127.0.0.1:3819`.
    #[arg(long = "if")]
    pub interface: String,
    /// Value map of the drives' PRes (default: the simulated drives' layout for the rules' nodes).
    #[arg(long)]
    pub map: Option<PathBuf>,
    /// Approval file written by `motus safety approve` (required unless --no-integrity).
    #[arg(long, required_unless_present = "no_integrity")]
    pub approval: Option<PathBuf>,
    /// Administrator key file that signed the approval.
    #[arg(long, required_unless_present = "no_integrity")]
    pub key: Option<PathBuf>,
    /// Drive parameters read from the amplifiers (TOML `[[drive]]`), watched with the rules.
    #[arg(long)]
    pub drives: Option<PathBuf>,
    /// Skip the configuration integrity check (commissioning only; says so in every diagnosis).
    #[arg(long)]
    pub no_integrity: bool,
    /// Homing mode (un-homed axes may move slowly; rules on them are skipped).
    #[arg(long)]
    pub homing: bool,
    /// Validity of each lease renewal on the wire, milliseconds (the drives' watchdog).
    #[arg(long, default_value_t = 20)]
    pub wire_lease_ms: u64,
    /// After a safety stop, let the drives run again as soon as it is safe (default: they
    /// stay stopped until the operator types `reset` on standard input).
    #[arg(long)]
    pub auto_restart: bool,
    /// Stop after this many seconds (default: until Ctrl-C).
    #[arg(long = "for")]
    pub duration: Option<f64>,
}

/// Options of `motus safety approve`.
#[derive(Debug, Args)]
pub struct SafetyApproveArgs {
    /// Rules file to approve.
    #[arg(long)]
    pub rules: PathBuf,
    /// Drive parameters to approve with it (TOML `[[drive]]`).
    #[arg(long)]
    pub drives: Option<PathBuf>,
    /// Administrator key file (at least 16 bytes; keep it readable by the administrator and
    /// the supervisor service only).
    #[arg(long)]
    pub key: PathBuf,
    /// Name of the approving administrator.
    #[arg(long)]
    pub admin: String,
    /// Approval file to write.
    #[arg(long)]
    pub out: PathBuf,
}
