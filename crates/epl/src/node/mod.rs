//! Standards-based POWERLINK nodes that interoperate with other stacks (openPOWERLINK):
//! sans-IO state machines driven by `now`, and runtimes that run them on an [`crate::EthLink`].
//!
//! * [`cn`]: a Controlled Node (NMT CN state machine, SDO server over ASnd, error
//!   signalling, PRes from the dictionary's TPDO mapping).
//! * [`mn`]: a Managing Node for foreign CNs driven by a concise DCF (boot-up with identity
//!   check, SDO configuration and NMT commands, process data by the CNs' mappings, re-boot of
//!   a CN that leaves OPERATIONAL).

pub mod cn;
pub mod mn;
