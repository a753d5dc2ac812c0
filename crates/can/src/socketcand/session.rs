//! One client of the [`Hub`](super::Hub): its handshake state, what it sent, and the
//! text waiting to be written to it.
//!
//! A session never blocks: the hub's event loop reads what a readable socket has and
//! writes what a writable one takes. Handshake replies (`< hi >`, `< ok >`, `< ok >`)
//! are written at once; bus traffic waits [`SETTLE`] after the last `< ok >` (python-can
//! reads each handshake reply with a single `recv`), then goes out in as few writes as
//! the socket allows.

use super::codec::{Message, StreamParser};
use crate::CanFrame;
use mio::net::TcpStream;
use std::collections::VecDeque;
use std::io::{ErrorKind, IoSlice, Read, Write};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Time between the last handshake reply and the first frame written to a client.
pub const SETTLE: Duration = Duration::from_millis(100);
/// Frames (and echo replies) queued for one client before it is considered dead and
/// disconnected.
pub const QUEUE_CAPACITY: usize = 65_536;
/// Most queued chunks handed to one `writev`.
const MAX_IOV: usize = 64;
/// Most reads of one socket per readiness event (a client that never stops sending
/// cannot starve the others; the loop comes back to it).
const READS_PER_TURN: usize = 16;

/// Counters of one client, kept after it leaves.
#[derive(Debug)]
pub(crate) struct Counters {
    pub id: u64,
    pub peer: SocketAddr,
    pub from_client: AtomicU64,
    pub to_client: AtomicU64,
    pub connected: AtomicBool,
    /// Frames and echo replies queued and not yet written.
    pub queued: AtomicUsize,
}

/// Text shared by every client a batch of frames goes to (formatted once).
pub(crate) struct Chunk {
    text: Arc<[u8]>,
    /// Frames in the text.
    frames: u64,
    /// Share of [`QUEUE_CAPACITY`] it takes (frames, or 1 for an echo reply).
    weight: usize,
}

impl Chunk {
    /// Frames delivered by the bus, with one time stamp.
    pub fn frames(frames: &[CanFrame], timestamp: Duration) -> Chunk {
        let mut text = String::with_capacity(40 * frames.len());
        for frame in frames {
            Message::Frame { frame: frame.clone(), timestamp }.format_into(&mut text);
        }
        Chunk { text: text.into_bytes().into(), frames: frames.len() as u64, weight: frames.len().max(1) }
    }

    /// The answer to `< echo >`.
    fn echo() -> Chunk {
        Chunk { text: Message::Echo.format().into_bytes().into(), frames: 0, weight: 1 }
    }

    fn share(&self) -> Chunk {
        Chunk { text: Arc::clone(&self.text), frames: self.frames, weight: self.weight }
    }
}

/// What reading a client produced.
#[derive(Default)]
pub(crate) struct Input {
    /// Frames sent to the bus, in order; each inner list came in one read.
    pub batches: Vec<Vec<CanFrame>>,
    /// The client finished the handshake in this read (it now receives bus traffic).
    pub joined: bool,
    /// The socket is closed or failed; the client must be removed.
    pub closed: bool,
    /// The read budget ran out before the socket was drained: read again soon.
    pub more: bool,
}

/// One connected client.
pub(crate) struct Session {
    pub counters: Arc<Counters>,
    pub stream: TcpStream,
    parser: StreamParser,
    opened: bool,
    /// Set once `< rawmode >` was answered: bus traffic may be written from this instant.
    pub ready_at: Option<Instant>,
    out: VecDeque<Chunk>,
    /// Bytes of the front chunk already written.
    written: usize,
    /// Whether the socket is registered for writability (it refused a write).
    pub want_write: bool,
}

impl Session {
    /// A freshly accepted client; `< hi >` is written at once.
    pub fn accept(stream: TcpStream, id: u64, peer: SocketAddr) -> std::io::Result<Session> {
        stream.set_nodelay(true)?;
        let counters = Arc::new(Counters {
            id,
            peer,
            from_client: AtomicU64::new(0),
            to_client: AtomicU64::new(0),
            connected: AtomicBool::new(true),
            queued: AtomicUsize::new(0),
        });
        let mut s = Session {
            counters,
            stream,
            parser: StreamParser::new(),
            opened: false,
            ready_at: None,
            out: VecDeque::new(),
            written: 0,
            want_write: false,
        };
        s.reply(&Message::Hi)?;
        Ok(s)
    }

    /// Client number.
    pub fn id(&self) -> u64 {
        self.counters.id
    }

    /// Whether the client receives bus traffic.
    pub fn joined(&self) -> bool {
        self.ready_at.is_some()
    }

    /// Writes a handshake reply now. These are a few bytes into an empty socket; a
    /// socket that cannot take them is treated as broken.
    fn reply(&mut self, msg: &Message) -> std::io::Result<()> {
        self.stream.write_all(msg.format().as_bytes())
    }

    /// Reads what the socket has (up to a budget) and handles the handshake and echo;
    /// frames are returned for the bus.
    pub fn read(&mut self, channel: &str, now: Instant) -> Input {
        let mut input = Input::default();
        let mut buf = [0u8; 16 * 1024];
        for turn in 0.. {
            if turn == READS_PER_TURN {
                input.more = true;
                break;
            }
            match self.stream.read(&mut buf) {
                Ok(0) => {
                    input.closed = true;
                    break;
                }
                Ok(n) => {
                    self.parser.push(buf.get(..n).unwrap_or(&[]));
                    if let Err(e) = self.handle_messages(channel, now, &mut input) {
                        tracing::debug!(client = self.id(), "socketcand hub: reply failed: {e}");
                        input.closed = true;
                        break;
                    }
                    if n < buf.len() {
                        // The socket is drained: text arriving later raises a new readiness
                        // event (epoll is edge-triggered on every arrival), so the read that
                        // would only say "would block" is saved.
                        break;
                    }
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => {
                    tracing::debug!(client = self.id(), "socketcand hub: read failed: {e}");
                    input.closed = true;
                    break;
                }
            }
        }
        input
    }

    fn handle_messages(&mut self, channel: &str, now: Instant, input: &mut Input) -> std::io::Result<()> {
        let mut frames = Vec::new();
        while let Some(msg) = self.parser.next() {
            match msg {
                Message::Send(frame) if self.opened => {
                    self.counters.from_client.fetch_add(1, Ordering::Relaxed);
                    frames.push(frame);
                    continue;
                }
                Message::Open(name) if !self.joined() => {
                    if name != channel {
                        tracing::debug!(client = self.id(), "client opened {name:?}, hub serves {channel:?}");
                    }
                    self.opened = true;
                    self.reply(&Message::Ok)?;
                }
                Message::Rawmode if self.opened && !self.joined() => {
                    // Joined before the `< ok >` leaves: a frame another client sends after
                    // this client saw the `< ok >` reaches it.
                    self.ready_at = Some(now + SETTLE);
                    input.joined = true;
                    self.reply(&Message::Ok)?;
                }
                Message::Echo if self.joined() => {
                    // Answered in order with the bus traffic queued before it.
                    self.push(&Chunk::echo());
                }
                Message::Echo => self.reply(&Message::Echo)?,
                other => tracing::debug!(client = self.id(), "socketcand hub: ignoring {other:?}"),
            }
            // A non-frame message ends a batch (frames keep their order around it).
            if !frames.is_empty() {
                input.batches.push(std::mem::take(&mut frames));
            }
        }
        if !frames.is_empty() {
            input.batches.push(frames);
        }
        Ok(())
    }

    /// Queues `chunk`; `false` when the queue is over [`QUEUE_CAPACITY`] (the client is
    /// not reading and must be dropped).
    pub fn push(&mut self, chunk: &Chunk) -> bool {
        let queued = self.counters.queued.fetch_add(chunk.weight, Ordering::Relaxed) + chunk.weight;
        self.out.push_back(chunk.share());
        queued <= QUEUE_CAPACITY
    }

    /// Whether text waits to be written.
    pub fn pending(&self) -> bool {
        !self.out.is_empty()
    }

    /// Writes queued text until the queue is empty or the socket is full (then
    /// `want_write` is set by the caller). Before `ready_at` nothing is written.
    /// Returns `Ok(true)` when everything was written.
    pub fn flush(&mut self, now: Instant) -> std::io::Result<bool> {
        if !matches!(self.ready_at, Some(t) if now >= t) {
            return Ok(self.out.is_empty());
        }
        while !self.out.is_empty() {
            let slices: Vec<IoSlice<'_>> = self
                .out
                .iter()
                .take(MAX_IOV)
                .enumerate()
                .map(|(i, c)| {
                    IoSlice::new(if i == 0 { c.text.get(self.written..).unwrap_or(&[]) } else { &c.text })
                })
                .collect();
            let n = match self.stream.write_vectored(&slices) {
                Ok(0) => return Err(ErrorKind::WriteZero.into()),
                Ok(n) => n,
                Err(e) if e.kind() == ErrorKind::WouldBlock => return Ok(false),
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            };
            self.consume(n);
        }
        Ok(true)
    }

    /// Drops `n` written bytes from the front of the queue.
    fn consume(&mut self, mut n: usize) {
        while n > 0 {
            let Some(front) = self.out.front() else { return };
            let left = front.text.len() - self.written.min(front.text.len());
            if n < left {
                self.written += n;
                return;
            }
            n -= left;
            self.written = 0;
            if let Some(done) = self.out.pop_front() {
                self.counters.queued.fetch_sub(done.weight, Ordering::Relaxed);
                self.counters.to_client.fetch_add(done.frames, Ordering::Relaxed);
            }
        }
    }
}
