//! The SDO server of a CN: answers Read by Index and Write by Index, expedited and
//! segmented, from an [`ObjectAccess`] object dictionary.
//!
//! * Expedited write: the value is written at once; the response has no data. Segmented
//!   write: the initiate segment (data size, index header, first bytes) and the segments are
//!   collected (each acknowledged at the sequence layer), and the value is written when the
//!   complete segment arrives.
//! * Read: a value up to one segment long goes back expedited, a longer one segmented (the
//!   initiate segment carries the data size), as fast as the send window allows.
//! * Aborts: the dictionary's [`SdoAbortCode`]; [`SdoAbortCode::InvalidCommandSpecifier`] for
//!   other commands (Write/Read Multiple Parameter by Index, by name, file access: the
//!   openPOWERLINK MN uses none of them with a CN that does not advertise them, see the
//!   captures) and malformed requests; [`SdoAbortCode::InvalidSequenceNumber`] for a segment
//!   without its initiate; [`SdoAbortCode::OutOfMemory`] for a value larger than
//!   [`SdoConfig::max_transfer_size`] (refused before it is buffered);
//!   [`SdoAbortCode::TypeLengthTooHigh`] / [`SdoAbortCode::TypeLengthTooLow`] for segments that
//!   disagree with the announced size; [`SdoAbortCode::Timeout`] for a segmented transfer
//!   stalled for [`SdoConfig::transfer_timeout`].
//!
//! One connection: feed it the frames of one client (the MN); an `InitReq` from the client
//! starts over. Memory is bounded by [`SdoConfig::max_transfer_size`] and the send window.

use std::time::Instant;

use crate::sdo::{SdoCommand, SdoFrame};
use crate::{ObjectAccess, SdoAbortCode, SdoCommandId};

use super::sequence::{LinkState, Role, SeqEvent, SequenceLayer};
use super::{
    abort_command, announced_value_size, command, parse_index_header, parse_size_header, segmentation,
    size_matches, SdoConfig, INDEX_HEADER, SIZE_HEADER,
};

/// The command-layer transfer in progress.
#[derive(Debug, Clone)]
enum Transfer {
    Idle,
    /// Collecting a segmented write.
    Receiving {
        tid: u8,
        index: u16,
        subindex: u8,
        announced: u32,
        value: Vec<u8>,
        last_progress: Instant,
    },
    /// Sending a segmented read response; `offset` bytes of `data` are sent.
    Sending {
        tid: u8,
        data: Vec<u8>,
        offset: usize,
        last_progress: Instant,
    },
}

impl Transfer {
    fn last_progress(&self) -> Option<Instant> {
        match self {
            Self::Idle => None,
            Self::Receiving { last_progress, .. } | Self::Sending { last_progress, .. } => {
                Some(*last_progress)
            }
        }
    }
}

/// An SDO server (one connection); see the module documentation.
#[derive(Debug, Clone)]
pub struct SdoServer {
    seq: SequenceLayer,
    config: SdoConfig,
    transfer: Transfer,
    /// The transaction of a segmented write this server aborted: its segments still in flight
    /// are dropped quietly.
    aborted: Option<u8>,
}

impl Default for SdoServer {
    fn default() -> Self {
        Self::new(SdoConfig::default())
    }
}

impl SdoServer {
    /// A server waiting for a client's connection.
    pub fn new(config: SdoConfig) -> Self {
        Self {
            seq: SequenceLayer::new(Role::Server, config.clone()),
            config,
            transfer: Transfer::Idle,
            aborted: None,
        }
    }

    /// The sequence-layer connection state.
    pub fn state(&self) -> LinkState {
        self.seq.state()
    }

    /// Whether a segmented transfer is in progress.
    pub fn transfer_in_progress(&self) -> bool {
        !matches!(self.transfer, Transfer::Idle)
    }

    /// When [`SdoServer::poll`] next has work (a retransmission, a time-out), if ever.
    pub fn next_deadline(&self) -> Option<Instant> {
        let transfer = self.next_transfer_deadline();
        match (self.seq.next_deadline(), transfer) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// When the transfer in progress times out (never when the time-out does not fit an
    /// `Instant`).
    fn next_transfer_deadline(&self) -> Option<Instant> {
        self.transfer.last_progress().and_then(|t| t.checked_add(self.config.transfer_timeout))
    }

    /// Handles a frame from the client and returns the frames to send back, in order (none,
    /// one, or several when a segmented read response or a retransmission follows).
    pub fn on_frame(&mut self, now: Instant, request: &SdoFrame, od: &mut dyn ObjectAccess) -> Vec<SdoFrame> {
        match self.seq.on_frame(now, request) {
            SeqEvent::Command(cmd) => self.on_command(now, cmd, od),
            SeqEvent::Closed(_) => self.transfer = Transfer::Idle,
            SeqEvent::Nothing | SeqEvent::Connected => {}
        }
        self.pump(now);
        self.seq.flush_ack();
        std::iter::from_fn(|| self.seq.poll_transmit()).collect()
    }

    /// Handles time-outs and returns the next frame to send, if any: call until `None`.
    pub fn poll(&mut self, now: Instant) -> Option<SdoFrame> {
        if let Some(SeqEvent::Closed(_)) = self.seq.handle_timeout(now) {
            self.transfer = Transfer::Idle;
        }
        if self.next_transfer_deadline().is_some_and(|t| now >= t) {
            let (tid, id) = match &self.transfer {
                Transfer::Receiving { tid, .. } => (*tid, SdoCommandId::WriteByIndex),
                Transfer::Sending { tid, .. } => (*tid, SdoCommandId::ReadByIndex),
                Transfer::Idle => (0, SdoCommandId::Nil),
            };
            self.transfer = Transfer::Idle;
            self.abort(now, tid, id, SdoAbortCode::Timeout);
        }
        self.pump(now);
        self.seq.poll_transmit()
    }

    /// Forgets the connection and any transfer without sending anything (NMT reset).
    pub fn reset(&mut self) {
        self.seq.reset();
        self.transfer = Transfer::Idle;
        self.aborted = None;
    }

    fn on_command(&mut self, now: Instant, cmd: SdoCommand, od: &mut dyn ObjectAccess) {
        let tid = cmd.transaction_id;
        if cmd.response {
            return; // Responses are for clients.
        }
        if cmd.abort {
            // The client gave up: drop its transfer, no answer.
            let ours = match &self.transfer {
                Transfer::Receiving { tid: t, .. } | Transfer::Sending { tid: t, .. } => *t == tid,
                Transfer::Idle => false,
            };
            if ours {
                self.transfer = Transfer::Idle;
            }
            return;
        }
        if cmd.segmentation == segmentation::SEGMENT || cmd.segmentation == segmentation::COMPLETE {
            if self.aborted == Some(tid) {
                return; // The rest of a write this server aborted.
            }
        } else {
            self.aborted = None;
        }
        match cmd.segmentation {
            segmentation::EXPEDITED => {
                // A new request ends whatever the client left unfinished.
                self.transfer = Transfer::Idle;
                match cmd.command_id {
                    SdoCommandId::WriteByIndex => self.write_expedited(now, tid, &cmd.data, od),
                    SdoCommandId::ReadByIndex => self.read(now, tid, &cmd.data, od),
                    SdoCommandId::Nil => {}
                    other => self.abort(now, tid, other, SdoAbortCode::InvalidCommandSpecifier),
                }
            }
            segmentation::INITIATE => {
                self.transfer = Transfer::Idle;
                match cmd.command_id {
                    SdoCommandId::WriteByIndex => self.write_initiate(now, tid, &cmd.data),
                    other => self.abort(now, tid, other, SdoAbortCode::InvalidCommandSpecifier),
                }
            }
            _ => self.write_segment(now, &cmd, od),
        }
    }

    fn write_expedited(&mut self, now: Instant, tid: u8, data: &[u8], od: &mut dyn ObjectAccess) {
        let id = SdoCommandId::WriteByIndex;
        let Some((index, subindex, value)) = parse_index_header(data) else {
            return self.abort(now, tid, id, SdoAbortCode::InvalidCommandSpecifier);
        };
        if value.len() > self.config.max_transfer_size {
            return self.abort(now, tid, id, SdoAbortCode::OutOfMemory);
        }
        self.finish_write(now, tid, index, subindex, value, od);
    }

    fn finish_write(
        &mut self,
        now: Instant,
        tid: u8,
        index: u16,
        subindex: u8,
        value: &[u8],
        od: &mut dyn ObjectAccess,
    ) {
        let id = SdoCommandId::WriteByIndex;
        match od.write(index, subindex, value) {
            Ok(()) => self.send(now, command(tid, true, false, segmentation::EXPEDITED, id, Vec::new())),
            Err(code) => self.abort(now, tid, id, code),
        }
    }

    fn write_initiate(&mut self, now: Instant, tid: u8, data: &[u8]) {
        let id = SdoCommandId::WriteByIndex;
        let Some((announced, (index, subindex, first))) =
            parse_size_header(data).and_then(|(size, rest)| Some((size, parse_index_header(rest)?)))
        else {
            return self.abort(now, tid, id, SdoAbortCode::InvalidCommandSpecifier);
        };
        let max = self.config.max_transfer_size;
        if announced_value_size(announced, SIZE_HEADER + INDEX_HEADER) > max || first.len() > max {
            return self.abort(now, tid, id, SdoAbortCode::OutOfMemory);
        }
        if first.len() > usize::try_from(announced).unwrap_or(usize::MAX) {
            return self.abort(now, tid, id, SdoAbortCode::TypeLengthTooHigh);
        }
        self.transfer = Transfer::Receiving {
            tid,
            index,
            subindex,
            announced,
            value: first.to_vec(),
            last_progress: now,
        };
    }

    fn write_segment(&mut self, now: Instant, cmd: &SdoCommand, od: &mut dyn ObjectAccess) {
        let tid = cmd.transaction_id;
        let transfer = std::mem::replace(&mut self.transfer, Transfer::Idle);
        let Transfer::Receiving { tid: t, index, subindex, announced, mut value, .. } = transfer else {
            return self.abort(now, tid, cmd.command_id, SdoAbortCode::InvalidSequenceNumber);
        };
        if t != tid || cmd.command_id != SdoCommandId::WriteByIndex {
            return self.abort(now, tid, cmd.command_id, SdoAbortCode::InvalidSequenceNumber);
        }
        let id = SdoCommandId::WriteByIndex;
        let total = value.len().saturating_add(cmd.data.len());
        if total > self.config.max_transfer_size {
            return self.abort(now, tid, id, SdoAbortCode::OutOfMemory);
        }
        if total > usize::try_from(announced).unwrap_or(usize::MAX) {
            return self.abort(now, tid, id, SdoAbortCode::TypeLengthTooHigh);
        }
        value.extend_from_slice(&cmd.data);
        if cmd.segmentation == segmentation::COMPLETE {
            if !size_matches(announced, SIZE_HEADER + INDEX_HEADER, value.len()) {
                return self.abort(now, tid, id, SdoAbortCode::TypeLengthTooLow);
            }
            self.finish_write(now, tid, index, subindex, &value, od);
        } else {
            self.transfer =
                Transfer::Receiving { tid, index, subindex, announced, value, last_progress: now };
        }
    }

    fn read(&mut self, now: Instant, tid: u8, data: &[u8], od: &mut dyn ObjectAccess) {
        let id = SdoCommandId::ReadByIndex;
        let Some((index, subindex, _)) = parse_index_header(data) else {
            return self.abort(now, tid, id, SdoAbortCode::InvalidCommandSpecifier);
        };
        let value = match od.read(index, subindex) {
            Ok(value) => value,
            Err(code) => return self.abort(now, tid, id, code),
        };
        if value.len() > self.config.max_transfer_size {
            return self.abort(now, tid, id, SdoAbortCode::OutOfMemory);
        }
        let segment = self.config.segment_size();
        if value.len() <= segment {
            return self.send(now, command(tid, true, false, segmentation::EXPEDITED, id, value));
        }
        let Some(announced) = value.len().checked_add(SIZE_HEADER).and_then(|n| u32::try_from(n).ok()) else {
            return self.abort(now, tid, id, SdoAbortCode::OutOfMemory);
        };
        let first = segment - SIZE_HEADER;
        let mut initiate = announced.to_le_bytes().to_vec();
        initiate.extend_from_slice(value.get(..first).unwrap_or(&value));
        self.send(now, command(tid, true, false, segmentation::INITIATE, id, initiate));
        self.transfer = Transfer::Sending { tid, data: value, offset: first, last_progress: now };
    }

    /// Sends the next segments of a read response while the window has room.
    fn pump(&mut self, now: Instant) {
        let segment = self.config.segment_size();
        while self.seq.can_send() {
            let Transfer::Sending { tid, data, offset, last_progress } = &mut self.transfer else { return };
            let end = offset.saturating_add(segment).min(data.len());
            let chunk = data.get(*offset..end).unwrap_or_default().to_vec();
            let last = end >= data.len();
            let segm = if last { segmentation::COMPLETE } else { segmentation::SEGMENT };
            let cmd = command(*tid, true, false, segm, SdoCommandId::ReadByIndex, chunk);
            *offset = end;
            *last_progress = now;
            if last {
                self.transfer = Transfer::Idle;
            }
            self.send(now, cmd);
        }
    }

    fn abort(&mut self, now: Instant, tid: u8, id: SdoCommandId, code: SdoAbortCode) {
        self.transfer = Transfer::Idle;
        if id == SdoCommandId::WriteByIndex {
            self.aborted = Some(tid);
        }
        self.send(now, abort_command(tid, true, id, code));
    }

    fn send(&mut self, now: Instant, cmd: SdoCommand) {
        // Not connected (or the history is full, which the window prevents): nothing can be
        // sent, and the client's own time-out reports the loss.
        let _ = self.seq.send(now, cmd);
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::super::index_header;
    use super::*;

    #[test]
    fn index_header_round_trips() {
        let h = index_header(0x1A00, 3);
        assert_eq!(parse_index_header(&h), Some((0x1A00, 3, &[][..])));
    }
}
