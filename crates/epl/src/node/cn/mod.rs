//! A standards-based POWERLINK Controlled Node that a foreign Managing Node (openPOWERLINK's)
//! boots, configures by SDO and keeps OPERATIONAL.
//!
//! * [`ControlledNode`] (sans-IO, driven by `now`): raw frames in, frames to send out.
//!   - NMT CN state machine: power-on through GS_INITIALISING and the reset states to
//!     NOT_ACTIVE; a SoA or SoC -> PRE_OPERATIONAL_1; a SoC -> PRE_OPERATIONAL_2;
//!     NMTEnableReadyToOperate -> READY_TO_OPERATE; NMTStartNode -> OPERATIONAL; NMTStopNode
//!     -> STOPPED (no PRes there); NMTEnterPreOperational2 -> PRE_OPERATIONAL_2; NMTResetNode,
//!     NMTResetCommunication, NMTResetConfiguration, NMTSwReset (also their "Ex" forms naming
//!     this node, and an SDO write of the command to 0x1F9E) -> the reset states ->
//!     NOT_ACTIVE; NOT_ACTIVE without any POWERLINK frame for 0x1F99 -> BASIC_ETHERNET, left
//!     on the next frame of the MN. 0x1F8C always holds the current state.
//!   - Loss of SoC: a SoC later than the cycle length (0x1006) plus the tolerance (0x1C14)
//!     after the previous one; loss of PReq: a cycle in READY_TO_OPERATE/OPERATIONAL without
//!     a PReq. Both are counted in 0x1C0B/0x1C0D (cumulative count +1, threshold count +8,
//!     -1 per good cycle); at the threshold (sub 3, 0 = never) the node has a cycle error and
//!     falls back to PRE_OPERATIONAL_1.
//!   - Asynchronous slot: SDO over ASnd through [`motus_epl_protocol::SdoServer`]; its
//!     answers wait in a queue announced by RS (count, up to 7) and PR = 3 in the PRes and
//!     StatusResponse, and go out one per SoA UnspecifiedInvite naming this node, as the
//!     openPOWERLINK CN does (`oplk_mn_cn_veth_merged.pcapng`: InitReq in frame 871, RS=1
//!     PR=3 in 882 and 887, invitation 893, InitAck 894).
//!   - IdentResponse (SoA IdentRequest) and StatusResponse (SoA StatusRequest) built from the
//!     dictionary ([`ControlledNode::ident_response`], [`ControlledNode::status_response`]).
//!   - Error signalling: a SoA with ER for this node sets EC (and clears EN and the entries);
//!     EC stays set until it has been reported to a StatusRequest without ER, which is what
//!     stops the MN asking (frames 881-917 of the capture). [`ControlledNode::post_error`]
//!     adds an entry and toggles EN (acknowledged by EA in the PReq).
//!   - PRes: prepared in advance (state, RD only in OPERATIONAL, EN, RS/PR, TPDO mapping
//!     version and payload from the dictionary) so that [`ControlledNode::pres_for`] answers
//!     a PReq without decoding it; the PReq payload is applied through the RPDO mapping in
//!     OPERATIONAL when RD is set and the PDO version's main nibble matches 0x1400/2.
//! * [`ControlledNodeRuntime`]: runs a [`ControlledNode`] on an [`crate::EthLink`] in a
//!   thread of its own, promoted as a cyclic real-time thread, waiting for frames asleep,
//!   by anticipatory polling ([`Anticipation`]: polls only around the PReq's due time) or
//!   busy polling ([`CnWait`]), with PReq -> PRes turnaround
//!   statistics; [`serve_frame`] is how it serves one frame, for a loop that embeds a node
//!   (the supervisor as a safety node).

mod anticipation;
mod machine;
mod runtime;
#[cfg(test)]
mod tests;

pub use anticipation::{Anticipation, WaitStep, MAX_MISSED_CYCLES};
pub use machine::{
    CnCounters, CnError, CnEvent, ControlledNode, StateCause, MAX_ASYNC_QUEUE, MAX_STATUS_ENTRIES,
    PR_GENERIC, REANNOUNCE_AFTER,
};
pub use runtime::{serve_frame, CnRuntimeConfig, CnRuntimeStats, CnWait, ControlledNodeRuntime, Served};
