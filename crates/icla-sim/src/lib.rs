//! A faithful simulated **IclA D065** integrated servo drive (Berger Lahr / SIG Positec) on
//! CANopen: CiA 301 communication (SDO server, NMT, heartbeat, PDOs with SYNC and event
//! timers, EMCY), a CiA 305 LSS slave and the CiA 402 drive profile (power state machine,
//! profile position / velocity, homing) over a simple motor model (12 Inc per motor
//! revolution, gear 160:9). The same host code runs against it and against real drives.
//!
//! * [`SimDrive`]: one node, sans-IO: [`SimDrive::handle`] a received frame,
//!   [`SimDrive::poll`] the timers; both take `now` and return the frames to send.
//! * [`run`] / [`run_shared`]: serve several nodes on one [`motus_can::CanBus`].
//! * [`pair()`]: the nodes as the in-process peer of a [`motus_can::PairBus`], answering
//!   synchronously on a [`motus_clock::Clock`] (driver-versus-simulator tests on virtual time);
//!   [`pair_threaded`] and [`run_pair`] for a clock several threads take part in.
//! * [`eds::export`]: the dictionary as an EDS that python-canopen imports.
//!
//! Defaults (see [`objects`] for the dictionary and the PDO set): node id 127 (or
//! LSS-unconfigured), 20 kbit/s (LSS index 7), heartbeat 1000 ms, profile 248 Inc/s,
//! 1000 / 400 Inc/s^2, quick stop option 2, following error window 50 Inc for 100 ms.
#![forbid(unsafe_code)]

mod access;
pub mod cia402;
pub mod config;
pub mod drive;
pub mod eds;
pub mod emcy;
pub mod heartbeat_consumer;
pub mod lss;
pub mod motion;
pub mod motor;
pub mod nmt;
pub mod objects;
pub mod od;
pub mod pair;
pub mod pdo;
pub mod runtime;
pub mod sdo_server;

pub use access::HOMING_METHODS;
pub use config::{parse_nodes, Identity, SimConfig};
pub use drive::SimDrive;
pub use pair::{pair, pair_threaded, run_pair};
pub use runtime::{lock, run, run_shared, SharedDrives};
