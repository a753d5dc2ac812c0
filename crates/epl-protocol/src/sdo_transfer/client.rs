//! The SDO client of an MN configuring a CN: queues reads and writes by index, opens the
//! connection, runs one transfer at a time, and reports each transfer's outcome.
//!
//! * A write goes expedited when the value and its index header fit one segment, else
//!   segmented (initiate with the data size, segments, complete), as fast as the send window
//!   allows. A read is one expedited request; the server answers expedited or segmented.
//! * Lost frames are the sequence layer's business (retransmission after
//!   [`SdoConfig::timeout`]); a connection that gives up fails the transfer with
//!   [`SdoError::Timeout`] (and every queued one too when the connection could not even be
//!   set up). A transfer without progress for [`SdoConfig::transfer_timeout`] is aborted
//!   ([`SdoAbortCode::Timeout`] sent to the server) and fails with [`SdoError::Timeout`].
//! * A server abort fails the transfer with [`SdoError::Aborted`] and its code. A response
//!   the client cannot take (larger than [`SdoConfig::max_transfer_size`], a size that
//!   disagrees with the announced one, a segment out of place, a wrong command) is aborted by
//!   the client, which reports [`SdoError::ClientAbort`] with the code it sent.
//!
//! Outcomes are collected with [`SdoClient::pop_outcome`].

use std::collections::VecDeque;
use std::time::Instant;

use crate::sdo::{SdoCommand, SdoFrame};
use crate::{SdoAbortCode, SdoCommandId};

use super::sequence::{CloseReason, LinkState, Role, SeqEvent, SequenceLayer};
use super::{
    abort_command, announced_value_size, command, index_header, parse_size_header, segmentation,
    size_matches, SdoConfig, INDEX_HEADER, SIZE_HEADER,
};

/// Identifies a queued transfer (in queueing order).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TransferId(pub u64);

/// Read or write.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TransferKind {
    /// Read by Index.
    Read,
    /// Write by Index.
    Write,
}

/// Why a transfer failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SdoError {
    /// The server aborted the transfer.
    #[error("the SDO server aborted the transfer: {code} ({:#010x})", .code.raw())]
    Aborted {
        /// The server's abort code.
        code: SdoAbortCode,
    },
    /// The client aborted the transfer because of the server's answer.
    #[error("the SDO client aborted the transfer: {code} ({:#010x})", .code.raw())]
    ClientAbort {
        /// The abort code sent to the server.
        code: SdoAbortCode,
    },
    /// The server did not answer (connection set-up, retransmissions, or the transfer time-out).
    #[error("SDO time-out: the server did not answer")]
    Timeout,
    /// The server closed or re-initialised the connection during the transfer.
    #[error("the SDO connection was closed during the transfer")]
    ConnectionClosed,
    /// [`SdoClient::close`] cancelled the transfer.
    #[error("the SDO transfer was cancelled")]
    Cancelled,
    /// The value is larger than [`SdoConfig::max_transfer_size`].
    #[error("a value of {len} bytes exceeds the SDO transfer limit of {max} bytes")]
    TooLarge {
        /// The value's size.
        len: usize,
        /// The limit.
        max: usize,
    },
}

/// How a transfer ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TransferOutcome {
    /// The transfer.
    pub id: TransferId,
    /// Read or write.
    pub kind: TransferKind,
    /// Object index.
    pub index: u16,
    /// Object subindex.
    pub subindex: u8,
    /// The value read (empty for a write), or why it failed.
    pub result: Result<Vec<u8>, SdoError>,
}

#[derive(Debug, Clone)]
struct Request {
    id: TransferId,
    kind: TransferKind,
    index: u16,
    subindex: u8,
    /// The value to write (empty for a read).
    data: Vec<u8>,
}

impl Request {
    fn command_id(&self) -> SdoCommandId {
        match self.kind {
            TransferKind::Read => SdoCommandId::ReadByIndex,
            TransferKind::Write => SdoCommandId::WriteByIndex,
        }
    }
}

#[derive(Debug, Clone)]
enum Phase {
    /// A segmented write: `offset` bytes of the value are sent.
    Sending { offset: usize },
    /// The request is sent; the response has not begun.
    AwaitResponse,
    /// A segmented read response is arriving.
    Receiving { announced: u32, value: Vec<u8> },
}

#[derive(Debug, Clone)]
struct Active {
    request: Request,
    tid: u8,
    phase: Phase,
    last_progress: Instant,
}

/// An SDO client (one connection to one server); see the module documentation.
#[derive(Debug, Clone)]
pub struct SdoClient {
    seq: SequenceLayer,
    config: SdoConfig,
    queue: VecDeque<Request>,
    active: Option<Active>,
    outcomes: VecDeque<TransferOutcome>,
    next_id: u64,
    next_tid: u8,
}

impl Default for SdoClient {
    fn default() -> Self {
        Self::new(SdoConfig::default())
    }
}

impl SdoClient {
    /// A client without a connection and with nothing queued.
    pub fn new(config: SdoConfig) -> Self {
        Self {
            seq: SequenceLayer::new(Role::Client, config.clone()),
            config,
            queue: VecDeque::new(),
            active: None,
            outcomes: VecDeque::new(),
            next_id: 0,
            next_tid: 0,
        }
    }

    /// The sequence-layer connection state.
    pub fn state(&self) -> LinkState {
        self.seq.state()
    }

    /// Queues a write of `value` to `index`/`subindex`; it starts at the next
    /// [`SdoClient::poll`] or [`SdoClient::on_frame`] once the transfers before it ended.
    ///
    /// # Errors
    /// [`SdoError::TooLarge`] when `value` exceeds [`SdoConfig::max_transfer_size`].
    pub fn write(&mut self, index: u16, subindex: u8, value: Vec<u8>) -> Result<TransferId, SdoError> {
        let max = self.config.max_transfer_size;
        if value.len() > max {
            return Err(SdoError::TooLarge { len: value.len(), max });
        }
        Ok(self.enqueue(TransferKind::Write, index, subindex, value))
    }

    /// Queues a read of `index`/`subindex` (see [`SdoClient::write`]).
    pub fn read(&mut self, index: u16, subindex: u8) -> TransferId {
        self.enqueue(TransferKind::Read, index, subindex, Vec::new())
    }

    /// Transfers queued or running.
    pub fn pending(&self) -> usize {
        self.queue.len() + usize::from(self.active.is_some())
    }

    /// Whether nothing is queued or running.
    pub fn is_idle(&self) -> bool {
        self.pending() == 0
    }

    /// The next finished transfer, oldest first.
    pub fn pop_outcome(&mut self) -> Option<TransferOutcome> {
        self.outcomes.pop_front()
    }

    /// When [`SdoClient::poll`] next has work (a retransmission, a time-out), if ever.
    pub fn next_deadline(&self) -> Option<Instant> {
        let transfer = self.transfer_deadline();
        match (self.seq.next_deadline(), transfer) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// Closes the connection (a close frame follows from [`SdoClient::poll`]); the running
    /// and queued transfers end with [`SdoError::Cancelled`].
    pub fn close(&mut self) {
        self.seq.close();
        if let Some(active) = self.active.take() {
            self.finish_request(active.request, Err(SdoError::Cancelled));
        }
        while let Some(request) = self.queue.pop_front() {
            self.finish_request(request, Err(SdoError::Cancelled));
        }
    }

    /// Handles a frame from the server and returns the frames to send, in order.
    pub fn on_frame(&mut self, now: Instant, response: &SdoFrame) -> Vec<SdoFrame> {
        match self.seq.on_frame(now, response) {
            SeqEvent::Command(cmd) => self.on_command(now, cmd),
            SeqEvent::Closed(reason) => {
                let error = match reason {
                    CloseReason::TimedOut => SdoError::Timeout,
                    CloseReason::ClosedByPeer | CloseReason::Reinitialised => SdoError::ConnectionClosed,
                };
                self.finish(Err(error));
            }
            SeqEvent::Nothing | SeqEvent::Connected => {}
        }
        self.pump(now);
        self.seq.flush_ack();
        std::iter::from_fn(|| self.seq.poll_transmit()).collect()
    }

    /// Handles time-outs, starts queued transfers, and returns the next frame to send, if
    /// any: call until `None`.
    pub fn poll(&mut self, now: Instant) -> Option<SdoFrame> {
        let setting_up = matches!(self.seq.state(), LinkState::InitRequested | LinkState::InitResponded);
        if let Some(SeqEvent::Closed(_)) = self.seq.handle_timeout(now) {
            self.finish(Err(SdoError::Timeout));
            if setting_up {
                // The server does not answer at all: nothing queued can succeed.
                while let Some(request) = self.queue.pop_front() {
                    self.finish_request(request, Err(SdoError::Timeout));
                }
            }
        }
        if self.transfer_deadline().is_some_and(|t| now >= t) {
            self.abort(now, SdoAbortCode::Timeout, SdoError::Timeout);
        }
        self.pump(now);
        self.seq.poll_transmit()
    }

    /// When the running transfer times out (never when the time-out does not fit an
    /// `Instant`).
    fn transfer_deadline(&self) -> Option<Instant> {
        self.active.as_ref().and_then(|a| a.last_progress.checked_add(self.config.transfer_timeout))
    }

    fn enqueue(&mut self, kind: TransferKind, index: u16, subindex: u8, data: Vec<u8>) -> TransferId {
        let id = TransferId(self.next_id);
        self.next_id += 1;
        self.queue.push_back(Request { id, kind, index, subindex, data });
        id
    }

    /// Opens the connection when needed, starts the next transfer, sends write segments.
    fn pump(&mut self, now: Instant) {
        if self.active.is_none() && !self.queue.is_empty() {
            match self.seq.state() {
                LinkState::Closed => self.seq.open(now),
                LinkState::Connected if self.seq.can_send() => self.start(now),
                _ => {}
            }
        }
        let segment = self.config.segment_size();
        while self.seq.can_send() {
            let Some(active) = &mut self.active else { return };
            let Phase::Sending { offset } = &mut active.phase else { return };
            let data = &active.request.data;
            let end = offset.saturating_add(segment).min(data.len());
            let chunk = data.get(*offset..end).unwrap_or_default().to_vec();
            let last = end >= data.len();
            let segm = if last { segmentation::COMPLETE } else { segmentation::SEGMENT };
            let cmd = command(active.tid, false, false, segm, SdoCommandId::WriteByIndex, chunk);
            *offset = end;
            if last {
                active.phase = Phase::AwaitResponse;
            }
            active.last_progress = now;
            self.send(now, cmd);
        }
    }

    fn start(&mut self, now: Instant) {
        let Some(request) = self.queue.pop_front() else { return };
        let tid = self.next_tid;
        self.next_tid = self.next_tid.wrapping_add(1);
        let header = index_header(request.index, request.subindex);
        let segment = self.config.segment_size();
        let (cmd, phase) = match request.kind {
            TransferKind::Read => (
                command(
                    tid,
                    false,
                    false,
                    segmentation::EXPEDITED,
                    SdoCommandId::ReadByIndex,
                    header.to_vec(),
                ),
                Phase::AwaitResponse,
            ),
            TransferKind::Write if request.data.len() + INDEX_HEADER <= segment => {
                let mut data = header.to_vec();
                data.extend_from_slice(&request.data);
                (
                    command(tid, false, false, segmentation::EXPEDITED, SdoCommandId::WriteByIndex, data),
                    Phase::AwaitResponse,
                )
            }
            TransferKind::Write => {
                let overhead = SIZE_HEADER + INDEX_HEADER;
                let Some(announced) =
                    request.data.len().checked_add(overhead).and_then(|n| u32::try_from(n).ok())
                else {
                    let len = request.data.len();
                    let max = self.config.max_transfer_size;
                    return self.finish_request(request, Err(SdoError::TooLarge { len, max }));
                };
                let first = segment - overhead;
                let mut data = announced.to_le_bytes().to_vec();
                data.extend_from_slice(&header);
                data.extend_from_slice(request.data.get(..first).unwrap_or(&request.data));
                (
                    command(tid, false, false, segmentation::INITIATE, SdoCommandId::WriteByIndex, data),
                    Phase::Sending { offset: first },
                )
            }
        };
        self.active = Some(Active { request, tid, phase, last_progress: now });
        self.send(now, cmd);
    }

    fn on_command(&mut self, now: Instant, cmd: SdoCommand) {
        let Some(active) = &mut self.active else { return };
        if !cmd.response || cmd.transaction_id != active.tid {
            return; // Not an answer to the running transfer (a stale one): ignore.
        }
        if cmd.abort {
            let code = cmd.abort_code().map_or(SdoAbortCode::GeneralError, SdoAbortCode::from_raw);
            return self.finish(Err(SdoError::Aborted { code }));
        }
        if cmd.command_id != active.request.command_id() {
            return self.client_abort(now, SdoAbortCode::GeneralError);
        }
        let max = self.config.max_transfer_size;
        let phase = std::mem::replace(&mut active.phase, Phase::AwaitResponse);
        active.last_progress = now;
        match (active.request.kind, phase, cmd.segmentation) {
            (TransferKind::Write, Phase::AwaitResponse, _) => self.finish(Ok(Vec::new())),
            (TransferKind::Write, _, _) => self.client_abort(now, SdoAbortCode::GeneralError),
            (TransferKind::Read, Phase::AwaitResponse, segmentation::EXPEDITED) => {
                if cmd.data.len() > max {
                    self.client_abort(now, SdoAbortCode::OutOfMemory);
                } else {
                    self.finish(Ok(cmd.data));
                }
            }
            (TransferKind::Read, Phase::AwaitResponse, segmentation::INITIATE) => {
                let Some((announced, first)) = parse_size_header(&cmd.data) else {
                    return self.client_abort(now, SdoAbortCode::GeneralError);
                };
                if announced_value_size(announced, SIZE_HEADER) > max || first.len() > max {
                    return self.client_abort(now, SdoAbortCode::OutOfMemory);
                }
                if first.len() > usize::try_from(announced).unwrap_or(usize::MAX) {
                    return self.client_abort(now, SdoAbortCode::TypeLengthTooHigh);
                }
                active.phase = Phase::Receiving { announced, value: first.to_vec() };
            }
            (TransferKind::Read, Phase::Receiving { announced, mut value }, segm)
                if segm == segmentation::SEGMENT || segm == segmentation::COMPLETE =>
            {
                let total = value.len().saturating_add(cmd.data.len());
                if total > max {
                    return self.client_abort(now, SdoAbortCode::OutOfMemory);
                }
                if total > usize::try_from(announced).unwrap_or(usize::MAX) {
                    return self.client_abort(now, SdoAbortCode::TypeLengthTooHigh);
                }
                value.extend_from_slice(&cmd.data);
                if segm == segmentation::COMPLETE {
                    if size_matches(announced, SIZE_HEADER, value.len()) {
                        self.finish(Ok(value));
                    } else {
                        self.client_abort(now, SdoAbortCode::TypeLengthTooLow);
                    }
                } else {
                    active.phase = Phase::Receiving { announced, value };
                }
            }
            (TransferKind::Read, _, _) => self.client_abort(now, SdoAbortCode::InvalidSequenceNumber),
        }
    }

    /// Aborts the running transfer towards the server and reports [`SdoError::ClientAbort`].
    fn client_abort(&mut self, now: Instant, code: SdoAbortCode) {
        self.abort(now, code, SdoError::ClientAbort { code });
    }

    fn abort(&mut self, now: Instant, code: SdoAbortCode, error: SdoError) {
        let Some(active) = &self.active else { return };
        let cmd = abort_command(active.tid, false, active.request.command_id(), code);
        self.send(now, cmd);
        self.finish(Err(error));
    }

    /// Ends the running transfer.
    fn finish(&mut self, result: Result<Vec<u8>, SdoError>) {
        if let Some(active) = self.active.take() {
            self.finish_request(active.request, result);
        }
    }

    fn finish_request(&mut self, request: Request, result: Result<Vec<u8>, SdoError>) {
        self.outcomes.push_back(TransferOutcome {
            id: request.id,
            kind: request.kind,
            index: request.index,
            subindex: request.subindex,
            result,
        });
    }

    fn send(&mut self, now: Instant, cmd: SdoCommand) {
        // Only called while connected with room in the window; a refusal would leave the
        // transfer to its time-out.
        let _ = self.seq.send(now, cmd);
    }
}
