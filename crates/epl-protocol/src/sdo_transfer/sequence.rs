//! The asynchronous SDO sequence layer (EPSG DS 301): a connection between one client and
//! one server, reliable and in order over a lossy channel.
//!
//! Each frame carries, from its sender's side, a *receive* sequence number and connection
//! state (the last in-order frame received from the peer: the acknowledgement) and a *send*
//! sequence number and connection state (6-bit numbers, modulo 64; states: [`ConState`]).
//!
//! * Set-up, initiated by the client: `InitReq` (rcon 0, scon 1) → `InitAck` (1, 1) →
//!   `InitResp` (1, 2) → `Valid` (2, 2). The server takes its first send number from the
//!   client's receive number (openPOWERLINK does; both 0 in the captures).
//! * A frame with command-layer data takes the next send number and stays in the history until
//!   acknowledged. An acknowledgement-only frame repeats the current send number.
//! * A received frame whose send number is the next one is delivered; the same number again
//!   (or an older one) is a duplicate and dropped; a number further ahead means frames were
//!   lost: the layer answers with an error response (rcon 3) carrying the last in-order number,
//!   and the peer sends its history again.
//! * scon 3 asks the receiver to acknowledge at once: set on the frame that fills the send
//!   window and on every retransmission.
//! * A time-out with frames unacknowledged sends the history again (scon 3), at most
//!   `max_retries` times; then the connection is closed (rcon 0, scon 0) and reported as
//!   [`CloseReason::TimedOut`].
//! * A frame arriving without a connection (other than a client's `InitReq` at a server) is
//!   answered with a close frame, as openPOWERLINK does.
//!
//! The layer never blocks and never panics: every field of a received frame is masked to its
//! width, and the history is bounded by the window.

use std::collections::VecDeque;
use std::time::Instant;

use crate::sdo::{SdoCommand, SdoFrame};
use crate::SdoCommandId;

use super::SdoConfig;

/// Sequence numbers are 6 bits.
const SEQ_MASK: u8 = 0x3F;
/// Half the sequence number space: a received number 2..HALF ahead of the expected one means
/// lost frames, one HALF or more ahead (i.e. behind) is an old duplicate.
const HALF: u8 = 32;
/// The history never holds more than this many frames (the window plus a final abort).
const HISTORY_LIMIT: usize = super::MAX_WINDOW + 2;

/// A connection state of the sequence layer (2 bits of a sequence byte).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ConState {
    /// 0: no connection (a frame with rcon 0 and scon 0 closes the connection).
    NoConnection,
    /// 1: initialisation.
    Initialization,
    /// 2: connection valid.
    Valid,
    /// 3: as rcon, an error response (frames were lost: send the history again); as scon, the
    /// connection is valid and the sender asks for an acknowledgement.
    Request,
}

impl ConState {
    /// The state of a 2-bit field (higher bits ignored).
    pub fn from_bits(bits: u8) -> Self {
        match bits & 0x03 {
            0 => Self::NoConnection,
            1 => Self::Initialization,
            2 => Self::Valid,
            _ => Self::Request,
        }
    }

    /// The 2-bit wire value.
    pub fn bits(self) -> u8 {
        match self {
            Self::NoConnection => 0,
            Self::Initialization => 1,
            Self::Valid => 2,
            Self::Request => 3,
        }
    }
}

/// Which end of the connection a [`SequenceLayer`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Role {
    /// Opens connections and sends requests (an MN configuring a CN).
    Client,
    /// Accepts connections and answers (a CN).
    Server,
}

/// Where a connection stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LinkState {
    /// No connection.
    Closed,
    /// Client: `InitReq` sent, waiting for `InitAck`.
    InitRequested,
    /// Server: `InitAck` sent, waiting for `InitResp`.
    InitAcknowledged,
    /// Client: `InitResp` sent, waiting for `Valid`.
    InitResponded,
    /// Connection valid: command-layer data flows.
    Connected,
}

/// Why a connection ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CloseReason {
    /// The peer sent a close frame (rcon 0, scon 0).
    ClosedByPeer,
    /// The client opened the connection again (a server received `InitReq` while connected).
    Reinitialised,
    /// Frames stayed unacknowledged (or a set-up step unanswered) through every retry.
    TimedOut,
}

/// What a received frame means to the command layer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SeqEvent {
    /// Nothing new for the command layer (set-up step, acknowledgement, duplicate...).
    Nothing,
    /// The connection became valid.
    Connected,
    /// The next in-order command-layer frame.
    Command(SdoCommand),
    /// The connection ended; anything in flight is lost.
    Closed(CloseReason),
}

/// Why [`SequenceLayer::send`] refused a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum SeqError {
    /// There is no valid connection.
    #[error("no valid SDO connection")]
    NotConnected,
    /// Too many frames are waiting for an acknowledgement.
    #[error("SDO send history full ({0} frames unacknowledged)")]
    HistoryFull(usize),
}

/// One end of an SDO sequence-layer connection (see the module documentation).
#[derive(Debug, Clone)]
pub struct SequenceLayer {
    role: Role,
    config: SdoConfig,
    state: LinkState,
    /// The send number of the last data frame sent (or the initial number).
    own_seq: u8,
    /// The send number of the last in-order frame received from the peer.
    peer_seq: u8,
    /// Sent data frames not yet acknowledged, oldest first; the last has number `own_seq`.
    history: VecDeque<SdoCommand>,
    /// Frames to send, in order.
    outbox: VecDeque<SdoFrame>,
    /// When the current time-out expires.
    deadline: Option<Instant>,
    /// Time-outs since the last progress.
    retries: u8,
    /// An in-order frame was received and nothing acknowledging it has been queued yet.
    ack_due: bool,
}

/// `a - b` modulo 64.
fn seq_diff(a: u8, b: u8) -> u8 {
    a.wrapping_sub(b) & SEQ_MASK
}

/// An acknowledgement-only frame (no command layer) would decode from 60 padded bytes with an
/// all-zero command layer: that, or no command at all, carries no data.
fn is_empty_command(command: Option<&SdoCommand>) -> bool {
    match command {
        None => true,
        Some(c) => {
            c.command_id == SdoCommandId::Nil
                && c.segment_size == 0
                && !c.response
                && !c.abort
                && c.data.is_empty()
        }
    }
}

impl SequenceLayer {
    /// A closed connection end.
    pub fn new(role: Role, config: SdoConfig) -> Self {
        Self {
            role,
            config,
            state: LinkState::Closed,
            own_seq: 0,
            peer_seq: 0,
            history: VecDeque::new(),
            outbox: VecDeque::new(),
            deadline: None,
            retries: 0,
            ack_due: false,
        }
    }

    /// This end's role.
    pub fn role(&self) -> Role {
        self.role
    }

    /// Where the connection stands.
    pub fn state(&self) -> LinkState {
        self.state
    }

    /// Whether data frames can be sent now: connected, and the send window has room.
    pub fn can_send(&self) -> bool {
        self.state == LinkState::Connected && self.history.len() < self.config.send_window()
    }

    /// Data frames sent and not yet acknowledged.
    pub fn unacknowledged(&self) -> usize {
        self.history.len()
    }

    /// When [`SequenceLayer::handle_timeout`] next has work (a retransmission or giving up).
    pub fn next_deadline(&self) -> Option<Instant> {
        self.deadline
    }

    /// Client: starts the connection set-up (queues `InitReq`). Does nothing unless closed
    /// or when called on a server.
    pub fn open(&mut self, now: Instant) {
        if self.role != Role::Client || self.state != LinkState::Closed {
            return;
        }
        self.reset();
        self.state = LinkState::InitRequested;
        self.push_control(ConState::NoConnection, ConState::Initialization);
        self.deadline = now.checked_add(self.config.timeout);
    }

    /// Closes the connection: queues a close frame (rcon 0, scon 0) unless already closed,
    /// and drops the history.
    pub fn close(&mut self) {
        if self.state != LinkState::Closed {
            self.push_control(ConState::NoConnection, ConState::NoConnection);
        }
        self.state = LinkState::Closed;
        self.history.clear();
        self.deadline = None;
        self.retries = 0;
        self.ack_due = false;
    }

    /// Forgets the connection without sending anything (e.g. on an NMT reset).
    pub fn reset(&mut self) {
        self.state = LinkState::Closed;
        self.own_seq = 0;
        self.peer_seq = 0;
        self.history.clear();
        self.outbox.clear();
        self.deadline = None;
        self.retries = 0;
        self.ack_due = false;
    }

    /// Queues a data frame with `command`, taking the next send number.
    ///
    /// # Errors
    /// [`SeqError::NotConnected`] without a valid connection; [`SeqError::HistoryFull`] when
    /// the history is at its hard limit (callers check [`SequenceLayer::can_send`] first; the
    /// limit leaves room for one abort beyond the window).
    pub fn send(&mut self, now: Instant, command: SdoCommand) -> Result<(), SeqError> {
        if self.state != LinkState::Connected {
            return Err(SeqError::NotConnected);
        }
        if self.history.len() >= HISTORY_LIMIT {
            return Err(SeqError::HistoryFull(self.history.len()));
        }
        self.own_seq = (self.own_seq + 1) & SEQ_MASK;
        let scon = if self.history.len() + 1 >= self.config.send_window() {
            ConState::Request
        } else {
            ConState::Valid
        };
        let frame = self.frame(ConState::Valid, self.own_seq, scon, Some(command.clone()));
        self.history.push_back(command);
        self.outbox.push_back(frame);
        self.ack_due = false;
        self.deadline = now.checked_add(self.config.timeout);
        Ok(())
    }

    /// Queues an acknowledgement-only frame if an in-order frame arrived and nothing sent since
    /// acknowledges it. Command layers call this after handling a received frame.
    pub fn flush_ack(&mut self) {
        if self.ack_due && self.state == LinkState::Connected {
            self.push_control(ConState::Valid, ConState::Valid);
        }
        self.ack_due = false;
    }

    /// The next frame to send, oldest first.
    pub fn poll_transmit(&mut self) -> Option<SdoFrame> {
        self.outbox.pop_front()
    }

    /// Handles the time-out if it has expired: retransmits the unacknowledged frames or
    /// repeats a set-up step, or gives up after `max_retries` (queues a close frame and returns
    /// [`SeqEvent::Closed`] with [`CloseReason::TimedOut`]).
    pub fn handle_timeout(&mut self, now: Instant) -> Option<SeqEvent> {
        let deadline = self.deadline?;
        if now < deadline {
            return None;
        }
        let retry = self.retries < self.config.max_retries;
        match self.state {
            LinkState::Closed => {
                self.deadline = None;
                None
            }
            LinkState::Connected if self.history.is_empty() => {
                self.deadline = None;
                None
            }
            _ if !retry => {
                self.close();
                Some(SeqEvent::Closed(CloseReason::TimedOut))
            }
            LinkState::Connected => {
                self.retries += 1;
                self.retransmit(now);
                None
            }
            LinkState::InitRequested => {
                self.retries += 1;
                self.push_control(ConState::NoConnection, ConState::Initialization);
                self.deadline = now.checked_add(self.config.timeout);
                None
            }
            LinkState::InitResponded => {
                self.retries += 1;
                self.push_control(ConState::Initialization, ConState::Valid);
                self.deadline = now.checked_add(self.config.timeout);
                None
            }
            LinkState::InitAcknowledged => {
                // The client repeats its own steps; the server only waits.
                self.retries += 1;
                self.deadline = now.checked_add(self.config.timeout);
                None
            }
        }
    }

    /// Handles a received frame: connection set-up, acknowledgements, retransmission
    /// requests, ordering. Frames to send in answer are queued (see
    /// [`SequenceLayer::poll_transmit`]).
    pub fn on_frame(&mut self, now: Instant, frame: &SdoFrame) -> SeqEvent {
        let rcon = ConState::from_bits(frame.receive_con);
        let scon = ConState::from_bits(frame.send_con);
        let rseq = frame.receive_sequence & SEQ_MASK;
        let sseq = frame.send_sequence & SEQ_MASK;
        use ConState::{Initialization as Init, NoConnection as No, Request, Valid};
        let is_close = rcon == No && scon == No;
        let is_init_req = rcon == No && scon == Init;

        if self.role == Role::Server && is_init_req {
            let was_connected = self.state == LinkState::Connected;
            self.accept_init(now, rseq, sseq);
            return if was_connected {
                SeqEvent::Closed(CloseReason::Reinitialised)
            } else {
                SeqEvent::Nothing
            };
        }
        match self.state {
            LinkState::Closed => {
                if !is_close {
                    // No connection: tell the sender (openPOWERLINK answers the same way).
                    self.outbox.push_back(SdoFrame {
                        receive_sequence: sseq,
                        receive_con: No.bits(),
                        send_sequence: rseq,
                        send_con: No.bits(),
                        command: None,
                        reserved: 0,
                    });
                }
                SeqEvent::Nothing
            }
            LinkState::InitRequested => {
                if rcon == Init && scon == Init {
                    self.peer_seq = sseq;
                    self.state = LinkState::InitResponded;
                    self.retries = 0;
                    self.push_control(Init, Valid);
                    self.deadline = now.checked_add(self.config.timeout);
                }
                SeqEvent::Nothing
            }
            LinkState::InitResponded => {
                if rcon == Valid && scon == Valid {
                    self.peer_seq = sseq;
                    self.connected();
                    SeqEvent::Connected
                } else {
                    if rcon == Init && scon == Init {
                        // InitAck again: our InitResp may have been lost.
                        self.push_control(Init, Valid);
                    }
                    SeqEvent::Nothing
                }
            }
            LinkState::InitAcknowledged => {
                if rcon == Init && scon == Valid {
                    self.peer_seq = sseq;
                    self.connected();
                    self.push_control(Valid, Valid);
                    SeqEvent::Connected
                } else if is_close {
                    self.close_silently();
                    SeqEvent::Closed(CloseReason::ClosedByPeer)
                } else {
                    SeqEvent::Nothing
                }
            }
            LinkState::Connected => match scon {
                No => {
                    self.close_silently();
                    SeqEvent::Closed(CloseReason::ClosedByPeer)
                }
                // A server handled InitReq above; anything else with scon 1 is a stale set-up
                // frame.
                Init => SeqEvent::Nothing,
                Valid | Request => {
                    if self.role == Role::Server && rcon == Init {
                        // InitResp again: our Valid was lost.
                        self.push_control(Valid, Valid);
                        return SeqEvent::Nothing;
                    }
                    self.on_connected_frame(now, rcon, scon, rseq, sseq, frame.command.as_ref())
                }
            },
        }
    }

    fn on_connected_frame(
        &mut self,
        now: Instant,
        rcon: ConState,
        scon: ConState,
        rseq: u8,
        sseq: u8,
        command: Option<&SdoCommand>,
    ) -> SeqEvent {
        self.acknowledge(now, rseq);
        if rcon == ConState::Request && !self.history.is_empty() {
            // Error response: the peer lost frames after `rseq`.
            self.retransmit(now);
        }
        match seq_diff(sseq, self.peer_seq) {
            1 => {
                self.peer_seq = sseq;
                self.ack_due = true;
                match command {
                    Some(c) if !is_empty_command(Some(c)) => SeqEvent::Command(c.clone()),
                    _ => SeqEvent::Nothing,
                }
            }
            d if d < HALF && d != 0 => {
                // Frames between peer_seq and sseq were lost: ask for them again.
                self.push_control(ConState::Request, ConState::Valid);
                SeqEvent::Nothing
            }
            _ => {
                // A duplicate (or an acknowledgement-only frame).
                if scon == ConState::Request {
                    if self.history.is_empty() {
                        self.ack_due = true;
                    } else {
                        // The peer has not got our frames after `rseq`: they carry the
                        // acknowledgement too.
                        self.retransmit(now);
                    }
                }
                SeqEvent::Nothing
            }
        }
    }

    /// Drops the history frames the peer acknowledges with `rseq`; an acknowledgement of a
    /// frame never sent is ignored.
    fn acknowledge(&mut self, now: Instant, rseq: u8) {
        let pending = self.history.len();
        let Ok(pending_u8) = u8::try_from(pending) else { return };
        let last_acked = self.own_seq.wrapping_sub(pending_u8) & SEQ_MASK;
        let acked = usize::from(seq_diff(rseq, last_acked));
        if acked == 0 || acked > pending {
            return;
        }
        self.history.drain(..acked);
        self.retries = 0;
        self.deadline = if self.history.is_empty() { None } else { now.checked_add(self.config.timeout) };
    }

    /// Sends every unacknowledged frame again, asking for an acknowledgement.
    fn retransmit(&mut self, now: Instant) {
        let Ok(pending) = u8::try_from(self.history.len()) else { return };
        let first = self.own_seq.wrapping_sub(pending).wrapping_add(1) & SEQ_MASK;
        let frames: Vec<SdoFrame> = self
            .history
            .iter()
            .zip(0u8..)
            .map(|(c, i)| {
                self.frame(ConState::Valid, (first + i) & SEQ_MASK, ConState::Request, Some(c.clone()))
            })
            .collect();
        self.outbox.extend(frames);
        self.ack_due = false;
        self.deadline = now.checked_add(self.config.timeout);
    }

    fn accept_init(&mut self, now: Instant, rseq: u8, sseq: u8) {
        self.reset();
        self.own_seq = rseq;
        self.peer_seq = sseq;
        self.state = LinkState::InitAcknowledged;
        self.push_control(ConState::Initialization, ConState::Initialization);
        self.deadline = now.checked_add(self.config.timeout);
    }

    fn connected(&mut self) {
        self.state = LinkState::Connected;
        self.history.clear();
        self.deadline = None;
        self.retries = 0;
        self.ack_due = false;
    }

    fn close_silently(&mut self) {
        self.state = LinkState::Closed;
        self.history.clear();
        self.deadline = None;
        self.retries = 0;
        self.ack_due = false;
    }

    /// Queues a frame without command-layer data, numbered with the current numbers.
    fn push_control(&mut self, rcon: ConState, scon: ConState) {
        let frame = self.frame(rcon, self.own_seq, scon, None);
        self.outbox.push_back(frame);
    }

    fn frame(
        &self,
        rcon: ConState,
        send_sequence: u8,
        scon: ConState,
        command: Option<SdoCommand>,
    ) -> SdoFrame {
        SdoFrame {
            receive_sequence: self.peer_seq,
            receive_con: rcon.bits(),
            send_sequence,
            send_con: scon.bits(),
            command,
            reserved: 0,
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]
    use std::time::Duration;

    use super::*;

    fn seq(frame: &SdoFrame) -> (u8, u8, u8, u8) {
        (frame.receive_sequence, frame.receive_con, frame.send_sequence, frame.send_con)
    }

    fn data(tag: u8) -> SdoCommand {
        super::super::command(tag, false, false, 0, SdoCommandId::WriteByIndex, vec![tag; 4])
    }

    fn drain(layer: &mut SequenceLayer) -> Vec<SdoFrame> {
        std::iter::from_fn(|| layer.poll_transmit()).collect()
    }

    /// Client and server connected, after the captured handshake (frames 871, 894, 908, 922).
    fn connected_pair(t: Instant) -> (SequenceLayer, SequenceLayer) {
        let mut client = SequenceLayer::new(Role::Client, SdoConfig::default());
        let mut server = SequenceLayer::new(Role::Server, SdoConfig::default());
        client.open(t);
        let req = drain(&mut client);
        assert_eq!(req.iter().map(seq).collect::<Vec<_>>(), [(0, 0, 0, 1)]);
        assert_eq!(server.on_frame(t, &req[0]), SeqEvent::Nothing);
        let ack = drain(&mut server);
        assert_eq!(ack.iter().map(seq).collect::<Vec<_>>(), [(0, 1, 0, 1)]);
        assert_eq!(client.on_frame(t, &ack[0]), SeqEvent::Nothing);
        let resp = drain(&mut client);
        assert_eq!(resp.iter().map(seq).collect::<Vec<_>>(), [(0, 1, 0, 2)]);
        assert_eq!(server.on_frame(t, &resp[0]), SeqEvent::Connected);
        let valid = drain(&mut server);
        assert_eq!(valid.iter().map(seq).collect::<Vec<_>>(), [(0, 2, 0, 2)]);
        assert_eq!(client.on_frame(t, &valid[0]), SeqEvent::Connected);
        assert_eq!((client.state(), server.state()), (LinkState::Connected, LinkState::Connected));
        (client, server)
    }

    #[test]
    fn con_state_round_trips() {
        for bits in 0..4 {
            assert_eq!(ConState::from_bits(bits).bits(), bits);
        }
        assert_eq!(ConState::from_bits(0xFF), ConState::Request);
    }

    #[test]
    fn numbers_wrap_modulo_64_and_acknowledge() {
        let t = Instant::now();
        let (mut client, mut server) = connected_pair(t);
        for i in 0..150u32 {
            client.send(t, data(i as u8)).unwrap();
            let f = drain(&mut client);
            assert_eq!(f.len(), 1);
            assert_eq!(f[0].send_sequence, ((i + 1) % 64) as u8);
            assert!(matches!(server.on_frame(t, &f[0]), SeqEvent::Command(c) if c.transaction_id == i as u8));
            server.flush_ack();
            let ack = drain(&mut server);
            assert_eq!(ack.len(), 1);
            assert_eq!(ack[0].receive_sequence, f[0].send_sequence);
            assert_eq!(client.on_frame(t, &ack[0]), SeqEvent::Nothing);
            assert_eq!(client.unacknowledged(), 0);
            assert!(drain(&mut client).is_empty(), "no acknowledgement of an acknowledgement");
        }
    }

    #[test]
    fn duplicate_is_dropped_gap_asks_again() {
        let t = Instant::now();
        let (mut client, mut server) = connected_pair(t);
        client.send(t, data(1)).unwrap();
        client.send(t, data(2)).unwrap();
        let f = drain(&mut client);
        // Frame 1 lost: frame 2 arrives first -> error response with the last in-order number.
        assert_eq!(server.on_frame(t, &f[1]), SeqEvent::Nothing);
        let err = drain(&mut server);
        assert_eq!(err.iter().map(seq).collect::<Vec<_>>(), [(0, 3, 0, 2)]);
        assert_eq!(client.on_frame(t, &err[0]), SeqEvent::Nothing);
        let again = drain(&mut client);
        assert_eq!(again.iter().map(seq).collect::<Vec<_>>(), [(0, 2, 1, 3), (0, 2, 2, 3)]);
        assert!(matches!(server.on_frame(t, &again[0]), SeqEvent::Command(c) if c.transaction_id == 1));
        assert!(matches!(server.on_frame(t, &again[1]), SeqEvent::Command(c) if c.transaction_id == 2));
        // The same frame again is a duplicate; with scon 3 it is acknowledged.
        assert_eq!(server.on_frame(t, &again[1]), SeqEvent::Nothing);
        server.flush_ack();
        let acks = drain(&mut server);
        assert_eq!(acks.iter().map(seq).collect::<Vec<_>>(), [(2, 2, 0, 2)]);
        client.on_frame(t, &acks[0]);
        assert_eq!(client.unacknowledged(), 0);
    }

    #[test]
    fn timeout_retransmits_then_closes() {
        let t = Instant::now();
        let (mut client, _server) = connected_pair(t);
        client.send(t, data(7)).unwrap();
        drain(&mut client);
        let timeout = SdoConfig::default().timeout;
        assert_eq!(client.next_deadline(), Some(t + timeout));
        assert_eq!(client.handle_timeout(t + timeout - Duration::from_millis(1)), None);
        for k in 1..=2u32 {
            assert_eq!(client.handle_timeout(t + timeout * k), None);
            let f = drain(&mut client);
            assert_eq!(f.iter().map(seq).collect::<Vec<_>>(), [(0, 2, 1, 3)]);
        }
        assert_eq!(client.handle_timeout(t + timeout * 3), Some(SeqEvent::Closed(CloseReason::TimedOut)));
        assert_eq!(drain(&mut client).iter().map(seq).collect::<Vec<_>>(), [(0, 0, 1, 0)]);
        assert_eq!(client.state(), LinkState::Closed);
        assert_eq!(client.next_deadline(), None);
    }

    #[test]
    fn window_fill_asks_for_acknowledgement_and_limits_history() {
        let t = Instant::now();
        let (mut client, _server) = connected_pair(t);
        for i in 0..4 {
            assert!(client.can_send());
            client.send(t, data(i)).unwrap();
        }
        assert!(!client.can_send());
        let f = drain(&mut client);
        assert_eq!(f.iter().map(|f| f.send_con).collect::<Vec<_>>(), [2, 2, 2, 3]);
        while client.send(t, data(9)).is_ok() {}
        assert_eq!(client.unacknowledged(), HISTORY_LIMIT);
        assert_eq!(client.send(t, data(9)), Err(SeqError::HistoryFull(HISTORY_LIMIT)));
    }

    #[test]
    fn frames_without_connection_are_answered_with_close() {
        let t = Instant::now();
        let mut server = SequenceLayer::new(Role::Server, SdoConfig::default());
        let stray = SdoFrame {
            receive_sequence: 17,
            receive_con: 2,
            send_sequence: 17,
            send_con: 2,
            command: None,
            reserved: 0,
        };
        assert_eq!(server.on_frame(t, &stray), SeqEvent::Nothing);
        assert_eq!(drain(&mut server).iter().map(seq).collect::<Vec<_>>(), [(17, 0, 17, 0)]);
        // A close is not answered.
        let close = SdoFrame { receive_con: 0, send_con: 0, ..stray };
        server.on_frame(t, &close);
        assert!(drain(&mut server).is_empty());
        assert_eq!(client_send_before_connect(), Err(SeqError::NotConnected));
    }

    fn client_send_before_connect() -> Result<(), SeqError> {
        SequenceLayer::new(Role::Client, SdoConfig::default()).send(Instant::now(), data(0))
    }

    #[test]
    fn init_request_while_connected_reinitialises() {
        let t = Instant::now();
        let (mut client, mut server) = connected_pair(t);
        client.reset();
        client.open(t);
        let req = drain(&mut client);
        assert_eq!(server.on_frame(t, &req[0]), SeqEvent::Closed(CloseReason::Reinitialised));
        assert_eq!(server.state(), LinkState::InitAcknowledged);
        assert_eq!(drain(&mut server).iter().map(seq).collect::<Vec<_>>(), [(0, 1, 0, 1)]);
    }

    #[test]
    fn lost_valid_is_repeated_and_init_retries_then_gives_up() {
        let t = Instant::now();
        let mut client = SequenceLayer::new(Role::Client, SdoConfig::default());
        let mut server = SequenceLayer::new(Role::Server, SdoConfig::default());
        client.open(t);
        server.on_frame(t, &drain(&mut client)[0]);
        client.on_frame(t, &drain(&mut server)[0]);
        let resp = drain(&mut client);
        assert_eq!(server.on_frame(t, &resp[0]), SeqEvent::Connected);
        drain(&mut server); // Valid lost
        let timeout = SdoConfig::default().timeout;
        assert_eq!(client.handle_timeout(t + timeout), None);
        let again = drain(&mut client);
        assert_eq!(again.iter().map(seq).collect::<Vec<_>>(), [(0, 1, 0, 2)]);
        assert_eq!(server.on_frame(t + timeout, &again[0]), SeqEvent::Nothing);
        let valid = drain(&mut server);
        assert_eq!(client.on_frame(t + timeout, &valid[0]), SeqEvent::Connected);

        // A server that never answers: InitReq, two retries, then the close.
        let mut lonely = SequenceLayer::new(Role::Client, SdoConfig::default());
        lonely.open(t);
        assert_eq!(drain(&mut lonely).len(), 1);
        for k in 1..=2u32 {
            assert_eq!(lonely.handle_timeout(t + timeout * k), None);
            assert_eq!(drain(&mut lonely).iter().map(seq).collect::<Vec<_>>(), [(0, 0, 0, 1)]);
        }
        assert_eq!(lonely.handle_timeout(t + timeout * 3), Some(SeqEvent::Closed(CloseReason::TimedOut)));
    }
}
