//! SDO over ASnd transfer engines (EPSG DS 301's asynchronous SDO): the sequence layer
//! ([`sequence`]), an SDO server for a CN ([`server`]) and an SDO client for an MN ([`client`]).
//!
//! Sans-IO like the rest of the crate: frames in, frames out, and time is an input. Every
//! method that can send or time out takes `now: std::time::Instant`; `poll(now)` hands out
//! what must be sent (retransmissions, aborts after a time-out, the next queued request), one
//! frame per call: call it until it returns `None`, and again at
//! [`SdoServer::next_deadline`] / [`SdoClient::next_deadline`] at the latest.
//!
//! What the engines do on the wire follows openPOWERLINK V2.7.2 as captured in
//! `shared/fixtures/powerlink/oplk_mn_cn_*.pcapng` (the MN configuring CN 1 by SDO, frames
//! 871..2584 of the merged veth capture; the tests replay them):
//!
//! * Connection set-up by the client: `InitReq` (rcon 0, scon 1), `InitAck` (1, 1),
//!   `InitResp` (1, 2), `Valid` (2, 2); then the client's first request carries send sequence
//!   number 1.
//! * Every frame carrying command-layer data takes the next 6-bit send sequence number; a
//!   frame's receive sequence number acknowledges the peer's frames up to that number; an
//!   acknowledgement-only frame repeats the sender's current send sequence number.
//! * An unacknowledged frame is sent again after [`SdoConfig::timeout`] (5 s) with scon 3
//!   ("acknowledge request"), at most [`SdoConfig::max_retries`] (2) times; then the
//!   connection is closed (rcon 0, scon 0).
//! * Segmented transfers: the initiate segment's data size counts every command-layer payload
//!   byte of the transfer (the sum of all segment sizes: itself, the index header of a write,
//!   and the value), as openPOWERLINK sends it.

pub mod client;
pub mod sequence;
pub mod server;

use std::time::Duration;

pub use client::{SdoClient, SdoError, TransferId, TransferKind, TransferOutcome};
pub use sequence::{CloseReason, ConState, LinkState, Role, SeqError, SeqEvent, SequenceLayer};
pub use server::SdoServer;

/// The largest command-layer payload (segment size) one ASnd frame carries: a 1514-byte
/// Ethernet frame less the Ethernet header (14), the POWERLINK header up to the ServiceID (4),
/// the sequence layer (4) and the command-layer header (8).
pub const MAX_SEGMENT_SIZE: usize = 1484;
/// openPOWERLINK's segment size (`SDO_CMD_SEGM_TX_MAX_SIZE`, 1456 bytes): the default.
pub const DEFAULT_SEGMENT_SIZE: usize = 1456;
/// The smallest segment size accepted in [`SdoConfig`] (room for a segmented write's headers
/// and some data).
pub const MIN_SEGMENT_SIZE: usize = 16;
/// The largest send window (frames sent and not yet acknowledged); keeps every sequence
/// number comparison unambiguous modulo 64.
pub const MAX_WINDOW: usize = 16;

/// Time-outs and limits of an SDO server or client.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SdoConfig {
    /// Sequence layer: a frame not acknowledged after this long is sent again with an
    /// acknowledge request; a connection set-up step not answered after this long is retried.
    /// Default 5 s, openPOWERLINK's (captured: response frame 1409 sent again as 1782, 2183,
    /// 5 s apart, then the close 2584).
    pub timeout: Duration,
    /// Sequence layer: retries after a time-out before the connection is given up and closed.
    /// Default 2 (openPOWERLINK's).
    pub max_retries: u8,
    /// Command layer: a transfer that makes no progress for this long is aborted with
    /// [`crate::SdoAbortCode::Timeout`]. Default 15 s (the sequence layer's give-up time).
    pub transfer_timeout: Duration,
    /// The largest value one transfer moves, in bytes; larger ones are refused with
    /// [`crate::SdoAbortCode::OutOfMemory`] before any of it is buffered. Default 64 KiB.
    pub max_transfer_size: usize,
    /// The largest command-layer payload sent in one frame (the segment size field),
    /// clamped to [`MIN_SEGMENT_SIZE`]..=[`MAX_SEGMENT_SIZE`]. Default
    /// [`DEFAULT_SEGMENT_SIZE`]. Received frames may carry any size.
    pub max_segment_size: usize,
    /// Frames sent and not yet acknowledged at most, clamped to 1..=[`MAX_WINDOW`]; the
    /// frame that fills the window asks for an acknowledgement (scon 3). Default 4
    /// (openPOWERLINK keeps 5 frames and asks when one is left).
    pub window: usize,
}

impl Default for SdoConfig {
    fn default() -> Self {
        Self {
            timeout: Duration::from_secs(5),
            max_retries: 2,
            transfer_timeout: Duration::from_secs(15),
            max_transfer_size: 64 * 1024,
            max_segment_size: DEFAULT_SEGMENT_SIZE,
            window: 4,
        }
    }
}

impl SdoConfig {
    /// The segment size in use ([`SdoConfig::max_segment_size`] clamped).
    pub fn segment_size(&self) -> usize {
        self.max_segment_size.clamp(MIN_SEGMENT_SIZE, MAX_SEGMENT_SIZE)
    }

    /// The send window in use ([`SdoConfig::window`] clamped).
    pub fn send_window(&self) -> usize {
        self.window.clamp(1, MAX_WINDOW)
    }
}

/// Command-layer payload bytes before the value in a (Write/Read)ByIndex request: index u16,
/// subindex u8, reserved u8.
const INDEX_HEADER: usize = 4;
/// Command-layer payload bytes of the data size field of an initiate segment.
const SIZE_HEADER: usize = 4;

/// Command-layer segmentation field values.
mod segmentation {
    /// The whole transfer in one frame.
    pub const EXPEDITED: u8 = 0;
    /// First frame of a segmented transfer (carries the data size).
    pub const INITIATE: u8 = 1;
    /// A middle frame.
    pub const SEGMENT: u8 = 2;
    /// The last frame.
    pub const COMPLETE: u8 = 3;
}

/// The (index, subindex) header of a (Write/Read)ByIndex request.
fn index_header(index: u16, subindex: u8) -> [u8; INDEX_HEADER] {
    let [i0, i1] = index.to_le_bytes();
    [i0, i1, subindex, 0]
}

/// Parses an (index, subindex) header; `None` when fewer than four bytes.
fn parse_index_header(data: &[u8]) -> Option<(u16, u8, &[u8])> {
    let (head, rest) = data.split_at_checked(INDEX_HEADER)?;
    let [i0, i1, sub, _] = <[u8; INDEX_HEADER]>::try_from(head).ok()?;
    Some((u16::from_le_bytes([i0, i1]), sub, rest))
}

/// Parses the data size of an initiate segment; `None` when fewer than four bytes.
fn parse_size_header(data: &[u8]) -> Option<(u32, &[u8])> {
    let (head, rest) = data.split_at_checked(SIZE_HEADER)?;
    let b = <[u8; SIZE_HEADER]>::try_from(head).ok()?;
    Some((u32::from_le_bytes(b), rest))
}

/// Whether a transfer that announced `announced` bytes and delivered `received` value bytes
/// with `overhead` bytes of headers is complete: openPOWERLINK counts the headers in the data
/// size (`announced == overhead + received`); a plain value size is accepted too.
fn size_matches(announced: u32, overhead: usize, received: usize) -> bool {
    let announced = usize::try_from(announced).unwrap_or(usize::MAX);
    announced == received.saturating_add(overhead) || announced == received
}

/// The value size an initiate segment announces at least (its data size less the headers it
/// counts), for the memory bound.
fn announced_value_size(announced: u32, overhead: usize) -> usize {
    usize::try_from(announced).unwrap_or(usize::MAX).saturating_sub(overhead)
}

/// Builds a command-layer frame body. `segment_size` is set to `data.len()`, saturating
/// (callers keep data within [`MAX_SEGMENT_SIZE`]).
fn command(
    transaction_id: u8,
    response: bool,
    abort: bool,
    segmentation: u8,
    command_id: crate::SdoCommandId,
    data: Vec<u8>,
) -> crate::SdoCommand {
    crate::SdoCommand {
        transaction_id,
        response,
        abort,
        segmentation,
        pad_size: 0,
        command_id,
        segment_size: u16::try_from(data.len()).unwrap_or(u16::MAX),
        data,
        flags_reserved: 0,
        reserved1: 0,
        reserved2: 0,
    }
}

/// An abort command: `response` set for the server's aborts, clear for the client's.
fn abort_command(
    transaction_id: u8,
    response: bool,
    command_id: crate::SdoCommandId,
    code: crate::SdoAbortCode,
) -> crate::SdoCommand {
    command(
        transaction_id,
        response,
        true,
        segmentation::EXPEDITED,
        command_id,
        code.raw().to_le_bytes().to_vec(),
    )
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn headers_parse_and_sizes_match_both_conventions() {
        assert_eq!(parse_index_header(&[0x06, 0x10, 0x00, 0x00, 0x50]), Some((0x1006, 0, &[0x50u8][..])));
        assert_eq!(parse_index_header(&[0x06, 0x10, 0x00]), None);
        assert_eq!(parse_size_header(&[8, 0, 0, 0, 1]), Some((8, &[1u8][..])));
        assert_eq!(parse_size_header(&[]), None);
        // openPOWERLINK: a 3000-byte write announces 3008, a 3000-byte read response 3004.
        assert!(size_matches(3008, 8, 3000));
        assert!(size_matches(3004, 4, 3000));
        assert!(size_matches(3000, 8, 3000));
        assert!(!size_matches(3009, 8, 3000));
        assert_eq!(announced_value_size(3008, 8), 3000);
        assert_eq!(announced_value_size(2, 8), 0);
    }

    #[test]
    fn config_clamps() {
        let c = SdoConfig { max_segment_size: 9000, window: 99, ..SdoConfig::default() };
        assert_eq!(c.segment_size(), MAX_SEGMENT_SIZE);
        assert_eq!(c.send_window(), MAX_WINDOW);
        let c = SdoConfig { max_segment_size: 0, window: 0, ..SdoConfig::default() };
        assert_eq!(c.segment_size(), MIN_SEGMENT_SIZE);
        assert_eq!(c.send_window(), 1);
    }
}
