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
    /// Run a Managing Node for foreign CNs (openPOWERLINK's among them) from a concise DCF:
    /// boots each CN (identity check, SDO configuration by the CDC, NMT commands), runs the
    /// cycle with process data by the CNs' mappings, boots again a CN that leaves
    /// OPERATIONAL; prints state changes, configuration progress and errors, the process data
    /// both ways every second, and the SoC jitter on exit.
    Mn(EplMnArgs),
    /// Run a standards-based Controlled Node that a foreign Managing Node (openPOWERLINK's)
    /// boots, configures by SDO and keeps OPERATIONAL (communication profile and CiA 401
    /// digital I/O of openPOWERLINK's demo CN); prints NMT state changes, NMT commands and
    /// SDO writes received, and the PReq -> PRes turnaround on exit.
    Cn(EplCnArgs),
}

/// How `motus epl cn` waits for frames (`--wait`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CnWaitArg {
    /// Asleep until shortly before each PReq is due, then polling until it is there.
    Anticipate,
    /// Asleep until a frame wakes the thread.
    Sleep,
    /// Polling without ever sleeping.
    Spin,
}

/// Options of `motus epl cn`.
#[derive(Debug, Args)]
pub struct EplCnArgs {
    /// Interface of the segment (raw socket, needs CAP_NET_RAW), or `mem://NAME` /
    /// `udp://127.0.0.1:PORT` for in-process and loopback segments.
    #[arg(long = "if")]
    pub interface: String,
    /// Node ID (1-239).
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=239))]
    pub node: u8,
    /// How the node's thread waits for frames: sleep (asleep until a frame wakes it: no CPU
    /// between frames), anticipate (asleep until shortly before each PReq is due, polling the
    /// link from 150 µs before until 250 µs after: no wake-up by the frame; not on a CPU
    /// shared with the MN, whose SoC it would hold up), or spin (polls without ever
    /// sleeping: one busy core).
    #[arg(long, value_enum, default_value_t = CnWaitArg::Sleep)]
    pub wait: CnWaitArg,
    /// Pin the node's thread to this CPU: best the one where the segment's frames arrive
    /// (the NIC's interrupt; on a veth segment the MN's CPU, CPU 1 for openPOWERLINK's Linux
    /// demos), so that the PReq wakes it without crossing CPUs.
    #[arg(long)]
    pub cpu: Option<usize>,
    /// The same as `--wait spin`.
    #[arg(long, conflicts_with = "wait")]
    pub spin: bool,
    /// Real-time scheduling of the node's thread: auto (SCHED_FIFO and locked memory when
    /// permitted, else nice), nice, or off.
    #[arg(long, value_enum, default_value_t = crate::cli_station::RealtimeArg::Auto)]
    pub realtime: crate::cli_station::RealtimeArg,
    /// Run this many seconds, then stop and print the summary (default: until Ctrl-C).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// How long an NMT reset takes, in milliseconds (the node is silent meanwhile): a CN that
    /// is back at once is configured by openPOWERLINK's MN during its reduced PRE_OPERATIONAL_1
    /// cycle, which makes that MN fail at a 1 ms cycle; openPOWERLINK's own CN takes 0.5-0.8 s.
    #[arg(long, default_value_t = 1000)]
    pub reset_ms: u64,
    /// The object dictionary from a POWERLINK device description (XDD, or an XDC whose
    /// actualValue attributes are the configured values) instead of the built-in one
    /// (openPOWERLINK's demo CN); its identity objects are the node's, and the node ID goes
    /// into 0x1F93/1 when the file has it.
    #[arg(long, value_name = "FILE")]
    pub od: Option<PathBuf>,
}

/// Options of `motus epl mn`.
#[derive(Debug, Args)]
pub struct EplMnArgs {
    /// Interface of the segment (raw socket, needs CAP_NET_RAW), or `mem://NAME` /
    /// `udp://127.0.0.1:PORT` for in-process and loopback segments.
    #[arg(long = "if")]
    pub interface: String,
    /// The concise DCF (`.cdc`, openCONFIGURATOR's binary format), e.g. openPOWERLINK's
    /// `demo_3cn_1ms.cdc`: CNs (0x1F81), cycle length (0x1006), PRes time-outs (0x1F92), each
    /// CN's configuration (0x1F22).
    #[arg(long)]
    pub cdc: std::path::PathBuf,
    /// Real-time scheduling of the cycle thread: auto (SCHED_FIFO and locked memory when
    /// permitted, else nice), nice, or off.
    #[arg(long, value_enum, default_value_t = crate::cli_station::RealtimeArg::Auto)]
    pub realtime: crate::cli_station::RealtimeArg,
    /// Run this many seconds, then stop and print the summary (default: until Ctrl-C).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// A fixed output value instead of the running counter, `NODE:INDEX/SUB=VALUE` (hex with
    /// 0x), e.g. `1:0x6200/1=0x55`; an object the CN's PReq mapping does not hold is written by
    /// SDO at the end of its configuration. Repeatable.
    #[arg(long = "set", value_name = "NODE:INDEX/SUB=VALUE")]
    pub set: Vec<String>,
    /// Minimum PRes time-out in microseconds (the CDC's 0x1F92 is used when larger).
    #[arg(long, default_value_t = 0)]
    pub min_pres_timeout_us: u64,
    /// The running-counter outputs advance every this many cycles.
    #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u64).range(1..))]
    pub counter_every: u64,
    /// PRes missed in a row before a CN is booted again.
    #[arg(long, default_value_t = 20)]
    pub lost_after: u32,
    /// Poll the link without sleeping while waiting for PRes and ASnd (one busy core).
    #[arg(long)]
    pub spin: bool,
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
    /// Size of the TPACKET_V3 receive ring on an interface, in MiB (blocks of 32 KiB, handed
    /// over when full or 4 ms after their first frame): 64 MiB hold about 460,000 small frames.
    #[arg(
        long,
        default_value_t = 64,
        value_parser = clap::value_parser!(u32).range(1..=4095),
        conflicts_with = "no_ring"
    )]
    pub ring_mb: u32,
    /// Read the interface with a plain raw socket (one receive call per frame, queue of
    /// `--rcvbuf` bytes) instead of the TPACKET_V3 ring.
    #[arg(long)]
    pub no_ring: bool,
    /// With `--no-ring`: receive queue asked for the raw socket, in bytes (SO_RCVBUFFORCE when
    /// permitted, else SO_RCVBUF up to net.core.rmem_max); a larger queue drops fewer frames
    /// when the monitor falls behind.
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
    /// The drives take their lease from the PRes of this safety node (the supervisor as a
    /// CN: `motus safety run --node N`), which the MN boots and polls after the drives; lease
    /// ASnds are then ignored. Without it, the drives take the lease ASnd of node 253.
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=239))]
    pub safety_node: Option<u8>,
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
    /// Take part in the segment as the CN with this node ID (a safety node): SafeToRun and a
    /// lease counter travel in its PRes, in the POWERLINK schedule, to every node. Without it,
    /// the supervisor broadcasts lease ASnds from node 253 outside the schedule.
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=239))]
    pub node: Option<u8>,
    /// As a safety node: the cycle length (object 0x1006) until the MN configures it.
    #[arg(long, default_value_t = 1000, requires = "node")]
    pub cycle_us: u32,
    /// As a safety node: how late a SoC may come before it counts as lost (object 0x1C14),
    /// microseconds. Losses drop the node to PRE_OPERATIONAL_1 and the drives stop.
    #[arg(long, default_value_t = 5000, requires = "node")]
    pub soc_tolerance_us: u32,
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
