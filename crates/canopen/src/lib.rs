//! CANopen master for Motus: CiA 301 (NMT, SDO client, PDO, SYNC, heartbeat consumer,
//! EMCY consumer), CiA 305 LSS master and CiA 306 EDS loading.
//!
//! Two layers:
//! * sans-IO state machines, one per service ([`sdo_client`], [`nmt`], [`heartbeat`],
//!   [`sync`], [`pdo`], [`emcy`], [`lss`], [`eds`]): frames in, frames and events out,
//!   `now: Instant` passed in, no threads or clocks;
//! * the runtime [`Master`]: one receive thread over any [`motus_can::CanBus`], blocking
//!   thread-safe calls (`&self`), SDO transfers to different nodes in parallel.
//!
//! Frame encodings come from `motus-canopen-protocol`.
#![forbid(unsafe_code)]

pub mod eds;
pub mod emcy;
pub mod error;
pub mod heartbeat;
pub mod lss;
pub mod nmt;
pub mod pdo;
pub mod runtime;
pub mod sdo_client;
pub mod sync;

pub use eds::{Access, DataType, ObjectDictionary, Value, Variable};
pub use emcy::{Emergency, ErrorRegister};
pub use error::MasterError;
pub use lss::{LssIdentity, LssMode};
pub use motus_canopen_protocol::{NmtCommand, NmtState, SdoAbortCode};
pub use pdo::{PdoConfig, PdoDirection};
pub use runtime::{
    consumer_entry, CobFilter, DumpRow, HeartbeatProducer, Master, MasterEvent, MasterStats, NodeInfo,
    SyncProducer,
};
pub use sdo_client::SdoError;
