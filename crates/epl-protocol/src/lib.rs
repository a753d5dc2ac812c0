//! Sans-IO codec for Ethernet POWERLINK V2 (EPL, EtherType 0x88AB), after `specs/powerlink.md`.
//!
//! Bytes in, typed frames out and back; no IO, threads or clocks.
//!
//! * [`EplFrame`]: one Ethernet frame carrying a POWERLINK message: the [`EthernetHeader`]
//!   (optional 802.1Q tag tolerated), destination and source node IDs, the [`Message`]
//!   ([`Soc`], [`PReq`], [`PRes`], [`Soa`], [`Asnd`], or a raw AMNI/AInv) and the
//!   [`Padding`] that followed the message.
//! * Decoding is total and lossless for every frame it accepts: reserved bytes, unknown flag
//!   bits, unknown codes and unknown ASnd services are kept, so `encode(decode(x)) == x` byte
//!   for byte. Frames shorter than 60 bytes are accepted (openPOWERLINK sends 36-byte SoC and
//!   54-byte SoA on a veth, which does not pad).
//! * Encoding a frame built by hand pads it with zeros to 60 bytes ([`Padding::Auto`]).
//! * [`CycleTracker`]: fed decoded frames and capture timestamps, reports per SoC cycle which
//!   nodes were polled and which answered with a PRes.
//! * [`SafetyLease`]: the Motus safety lease (a manufacturer-specific ASnd) that grants or
//!   revokes drives' permission to run.
//! * [`ValueMap`]: per-node process values at PRes payload offsets (TOML `--map` files).
//! * [`ObjectDictionary`] ([`od`]): an object dictionary serving [`ObjectAccess`], with the
//!   built-in CN dictionary ([`ObjectDictionary::controlled_node`]) and the PDO mappings that
//!   build the PRes payload and take the PReq payload, or a dictionary read from a POWERLINK
//!   device description ([`ObjectDictionary::from_xdd`], XDD/XDC).
//! * [`Cdc`] ([`cdc`]): the concise DCF (`.cdc`) an MN reads, with each CN's configuration.
//! * [`SdoServer`] / [`SdoClient`] ([`sdo_transfer`]): SDO over ASnd transfer engines (the
//!   sequence layer and the command layer), with time as an input.
//!
//! ```
//! use motus_epl_protocol::{EplFrame, Message, NmtState};
//! // Captured PRes of CN 1 in OPERATIONAL with a one-byte payload (specs/powerlink.md §3.4).
//! let mut bytes = vec![0x01, 0x11, 0x1e, 0x00, 0x00, 0x02, 0xda, 0x6e, 0x4c, 0xfb, 0xb5, 0x19,
//!                      0x88, 0xab, 0x04, 0xff, 0x01, 0xfd, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00, 0x01];
//! bytes.resize(60, 0);
//! let frame = EplFrame::decode(&bytes).unwrap();
//! let Message::PRes(pres) = &frame.message else { panic!("not a PRes") };
//! assert_eq!(frame.src_node, 1);
//! assert_eq!(pres.nmt_state, NmtState::Operational);
//! assert_eq!(pres.payload, [0x01]);
//! assert_eq!(frame.encode().unwrap(), bytes);
//! ```
#![forbid(unsafe_code)]

pub mod asnd;
pub mod cdc;
pub mod codes;
pub mod cycle;
pub mod error;
pub mod ethernet;
pub mod flags;
pub mod frame;
pub mod ident;
pub mod lease;
pub mod object_access;
pub mod od;
pub mod preq;
pub mod pres;
pub mod sdo;
pub mod sdo_transfer;
pub mod soa;
pub mod soc;
pub mod status;
pub mod values;
mod wire;

pub use asnd::{Asnd, NmtCommand, NmtRequest};
pub use cdc::{Cdc, CdcEntry, CdcError, NodeAssignment};
pub use codes::{NmtCommandId, NmtState, RequestedService, SdoCommandId};

pub use cycle::{CycleReport, CycleTracker, PresSeen};
pub use error::{DecodeError, EncodeError};
pub use ethernet::{EthernetHeader, MacAddr, ETHERTYPE_EPL, ETHERTYPE_VLAN, MIN_FRAME_LEN};
pub use flags::{Flags, PrRs};
pub use frame::{EplFrame, Message, Padding};
pub use ident::{FixedText, IdentResponse};
pub use lease::{SafetyLease, LEASE_ASND_NODE_ID, SAFETY_LEASE_SERVICE_ID};
pub use object_access::{ObjectAccess, SdoAbortCode};
pub use od::{DeviceIdentity, ObjectDictionary, PdoMapping, SafetyNodeTiming, XddError, SAFETY_LEASE_OBJECT};
pub use preq::PReq;
pub use pres::PRes;
pub use sdo::{SdoCommand, SdoFrame};
pub use sdo_transfer::{SdoClient, SdoConfig, SdoError, SdoServer, TransferId, TransferOutcome};
pub use soa::{Soa, SyncRequest};
pub use soc::{NetTime, Soc};
pub use status::{StatusEntry, StatusResponse};
pub use values::{ExtractError, NodeValues, Sample, Value, ValueMap, ValueMapError, ValueSpec, ValueType};

/// Node ID of the Managing Node (240).
pub const MN_NODE_ID: u8 = 240;
/// Broadcast node ID (255): destination of SoC, SoA, PRes, IdentResponse and StatusResponse.
pub const BROADCAST_NODE_ID: u8 = 255;
/// Offset of the PDO payload in a PReq/PRes, counted from the message type byte (frame byte 24
/// without a VLAN tag).
pub const PDO_PAYLOAD_OFFSET: usize = 10;
