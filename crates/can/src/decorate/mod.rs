//! Decorators: each wraps any [`CanBus`](crate::CanBus) and is itself one.
//!
//! - [`CandumpLog`]: appends every frame to a `candump -l` log.
//! - [`PcapCapture`]: writes a pcap capture (LINKTYPE_CAN_SOCKETCAN) Wireshark decodes.
//! - [`FaultyBus`]: drops, corrupts, mangles and delays frames (seeded).
//! - [`BusLoad`]: measures the bus load; [`cycle_load`]/[`check_cycle`] plan a cycle.

pub mod busload;
pub mod candump;
pub mod faulty;
pub mod pcap;

pub use busload::{check_cycle, cycle_load, BusLoad, CycleLoad, CycleTooLong, LoadReport};
pub use candump::{candump_line, CandumpLog};
pub use faulty::{FaultConfig, FaultStats, FaultyBus};
pub use pcap::{socketcan_record, PcapCapture};

use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// Wall-clock time since the Unix epoch (for log time stamps).
pub(crate) fn wall_clock() -> Duration {
    SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default()
}
