//! Command-line definitions of the station commands: `serve`, `user`.

use clap::{Args, Subcommand, ValueEnum};
use std::path::PathBuf;

/// Options of `motus user`.
#[derive(Debug, Args)]
pub struct UserArgs {
    /// The station's database (default: `<config stem>.lab.sqlite` beside `--config`).
    #[arg(long, global = true)]
    pub db: Option<PathBuf>,
    /// The cell configuration whose database to use.
    #[arg(long, global = true)]
    pub config: Option<PathBuf>,
    /// What to do.
    #[command(subcommand)]
    pub action: UserAction,
}

/// Roles on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RoleArg {
    /// Sees everything, commands nothing.
    Viewer,
    /// Commands during their own reserved slot, within student limits.
    Student,
    /// Everything, including safety configuration and users.
    Admin,
}

/// `motus user` actions (offline: the station may be stopped).
#[derive(Debug, Subcommand)]
pub enum UserAction {
    /// Add a user; the password is read from standard input (one line).
    Add {
        /// User name.
        name: String,
        /// Role.
        #[arg(long, value_enum, default_value = "student")]
        role: RoleArg,
    },
    /// Set a user's password (read from standard input); ends the user's sessions.
    Passwd {
        /// User name.
        name: String,
    },
    /// Change a user's role.
    Role {
        /// User name.
        name: String,
        /// New role.
        #[arg(value_enum)]
        role: RoleArg,
    },
    /// Delete a user.
    Del {
        /// User name.
        name: String,
    },
    /// List users.
    List,
}

/// Options of `motus serve`.
#[derive(Debug, Args)]
pub struct ServeArgs {
    /// The cell configuration.
    #[arg(long)]
    pub config: PathBuf,
    /// Address of the HMI and API (default: the cell's `[station] listen`).
    #[arg(long)]
    pub listen: Option<std::net::SocketAddr>,
    /// The station's database (default: `<config stem>.lab.sqlite` beside the config).
    #[arg(long)]
    pub db: Option<PathBuf>,
    /// Real-time priorities of the device and cyclic threads (docs/decisions.md): `auto` by
    /// default (SCHED_FIFO where permitted, else nice levels and a warning).
    #[arg(long, value_enum, default_value_t = RealtimeArg::Auto)]
    pub realtime: RealtimeArg,
}

/// `--realtime` of `motus serve` and `motus demo`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RealtimeArg {
    /// Nice levels only: web threads at nice +10, the machine's threads at the default
    /// priority.
    Nice,
    /// The default: SCHED_FIFO for device, cyclic and simulator threads and locked memory
    /// when permitted (root, CAP_SYS_NICE or RLIMIT_RTPRIO), else nice levels and a warning;
    /// web threads at nice +10.
    Auto,
    /// Every thread at the default priority.
    Off,
}

impl From<RealtimeArg> for motus_realtime::RealtimePolicy {
    fn from(a: RealtimeArg) -> Self {
        match a {
            RealtimeArg::Nice => motus_realtime::RealtimePolicy::Nice,
            RealtimeArg::Auto => motus_realtime::RealtimePolicy::Auto,
            RealtimeArg::Off => motus_realtime::RealtimePolicy::Off,
        }
    }
}
