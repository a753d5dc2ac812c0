//! One client of the [`Hub`](super::Hub): handshake, reader thread, writer thread.
//!
//! The reader answers the handshake (`< hi >`, `< ok >`, `< ok >`), then hands every
//! frame the client sends to the hub. The writer owns a bounded queue; it waits
//! [`SETTLE`] after the handshake before writing any frame (python-can reads each
//! handshake reply with a single `recv`), and batches queued messages into one write.

use super::codec::{Message, StreamParser};
use super::hub::Shared;
use crate::CanFrame;
use std::io::{Read, Write};
use std::net::{Shutdown, SocketAddr, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Time between the last handshake reply and the first frame written to a client.
pub const SETTLE: Duration = Duration::from_millis(100);
/// Frames (and echo replies) queued for one client before it is considered dead and
/// disconnected.
pub const QUEUE_CAPACITY: usize = 65_536;
/// Most messages written to a socket in one batch.
const BATCH: usize = 256;

/// A message for a client's writer.
pub(crate) enum Outgoing {
    /// A frame delivered by the bus.
    Frame(CanFrame),
    /// Frames another client sent in one write, delivered together.
    Frames(Arc<[CanFrame]>),
    /// The answer to `< echo >`.
    Echo,
}

impl Outgoing {
    /// How much of a client's [`QUEUE_CAPACITY`] this message takes.
    fn weight(&self) -> usize {
        match self {
            Outgoing::Frames(batch) => batch.len().max(1),
            Outgoing::Frame(_) | Outgoing::Echo => 1,
        }
    }
}

/// Counters of one client, kept after it leaves.
#[derive(Debug)]
pub(crate) struct Counters {
    pub id: u64,
    pub peer: SocketAddr,
    pub from_client: AtomicU64,
    pub to_client: AtomicU64,
    pub connected: AtomicBool,
    /// Frames and echo replies queued for the client's writer.
    pub queued: AtomicUsize,
}

/// What the hub keeps of a joined client.
pub(crate) struct ClientHandle {
    pub counters: Arc<Counters>,
    pub tx: SyncSender<Outgoing>,
    pub stream: TcpStream,
}

impl ClientHandle {
    /// Queues `msg`; `false` when the client must be dropped (queue full or writer gone).
    pub fn offer(&self, msg: Outgoing) -> bool {
        let weight = msg.weight();
        let queued = self.counters.queued.fetch_add(weight, Ordering::Relaxed) + weight;
        let sent = if queued > QUEUE_CAPACITY { Err(TrySendError::Full(msg)) } else { self.tx.try_send(msg) };
        match sent {
            Ok(()) => true,
            Err(TrySendError::Full(_)) => {
                tracing::warn!(client = self.counters.id, peer = %self.counters.peer,
                    "socketcand hub: client queue overflow ({QUEUE_CAPACITY} messages), disconnecting");
                let _ = self.stream.shutdown(Shutdown::Both);
                false
            }
            Err(TrySendError::Disconnected(_)) => false,
        }
    }
}

/// Serves one accepted connection until it closes (runs on its own thread).
pub(crate) fn serve(shared: Arc<Shared>, stream: TcpStream, id: u64, peer: SocketAddr) {
    let counters = Arc::new(Counters {
        id,
        peer,
        from_client: AtomicU64::new(0),
        to_client: AtomicU64::new(0),
        connected: AtomicBool::new(true),
        queued: AtomicUsize::new(0),
    });
    shared.register_counters(counters.clone());
    if let Err(e) = run(&shared, &stream, &counters) {
        tracing::debug!(client = id, %peer, "socketcand hub: client ended: {e}");
    }
    counters.connected.store(false, Ordering::Relaxed);
    shared.leave(id);
    let _ = stream.shutdown(Shutdown::Both);
}

fn run(shared: &Arc<Shared>, stream: &TcpStream, counters: &Arc<Counters>) -> std::io::Result<()> {
    stream.set_nodelay(true)?;
    let mut reader = stream.try_clone()?;
    let mut direct = stream.try_clone()?;
    direct.write_all(Message::Hi.format().as_bytes())?;
    let mut parser = StreamParser::new();
    let mut buf = [0u8; 4096];
    let mut opened = false;
    let mut joined: Option<SyncSender<Outgoing>> = None;
    loop {
        let n = reader.read(&mut buf)?;
        if n == 0 || shared.stopping() {
            return Ok(());
        }
        parser.push(buf.get(..n).unwrap_or(&[]));
        // The frames of one read enter the bus together (see `Shared::submit_many`).
        let mut frames = Vec::new();
        for msg in parser.by_ref() {
            if !matches!(msg, Message::Send(_)) && !frames.is_empty() {
                shared.submit_many(counters.id, std::mem::take(&mut frames));
            }
            match (msg, &joined) {
                (Message::Open(channel), None) => {
                    if channel != shared.channel {
                        tracing::debug!(
                            client = counters.id,
                            "client opened {channel:?}, hub serves {:?}",
                            shared.channel
                        );
                    }
                    opened = true;
                    direct.write_all(Message::Ok.format().as_bytes())?;
                }
                (Message::Rawmode, None) if opened => {
                    // Join first (the writer holds frames for SETTLE), then confirm: a frame
                    // sent by another client after our client saw `< ok >` reaches it.
                    let (tx, go) = join(shared, stream, counters)?;
                    joined = Some(tx);
                    direct.write_all(Message::Ok.format().as_bytes())?;
                    let _ = go.send(Instant::now());
                }
                (Message::Echo, Some(tx)) => {
                    counters.queued.fetch_add(1, Ordering::Relaxed);
                    if tx.try_send(Outgoing::Echo).is_err() {
                        counters.queued.fetch_sub(1, Ordering::Relaxed);
                    }
                }
                (Message::Echo, None) => direct.write_all(Message::Echo.format().as_bytes())?,
                (Message::Send(frame), _) if opened => {
                    counters.from_client.fetch_add(1, Ordering::Relaxed);
                    frames.push(frame);
                }
                (other, _) => {
                    tracing::debug!(client = counters.id, "socketcand hub: ignoring {other:?}");
                }
            }
        }
        if !frames.is_empty() {
            shared.submit_many(counters.id, frames);
        }
    }
}

/// Starts the writer and adds the client to the bus.
///
/// The writer starts writing [`SETTLE`] after the instant sent on the returned `go`
/// channel (when `< ok >` was written); frames queue meanwhile.
fn join(
    shared: &Arc<Shared>,
    stream: &TcpStream,
    counters: &Arc<Counters>,
) -> std::io::Result<(SyncSender<Outgoing>, SyncSender<Instant>)> {
    let (tx, rx) = sync_channel(QUEUE_CAPACITY);
    let (go, go_rx) = sync_channel::<Instant>(1);
    let out = stream.try_clone()?;
    out.set_write_timeout(Some(Duration::from_secs(5)))?;
    let c = counters.clone();
    std::thread::Builder::new().name(format!("socketcand-w{}", counters.id)).spawn(move || {
        if let Ok(ok_written) = go_rx.recv() {
            write_loop(out, rx, ok_written + SETTLE, &c);
        }
    })?;
    shared.join(ClientHandle { counters: counters.clone(), tx: tx.clone(), stream: stream.try_clone()? });
    Ok((tx, go))
}

fn wall_clock() -> Duration {
    SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default()
}

fn write_loop(mut out: TcpStream, rx: Receiver<Outgoing>, ready_at: Instant, counters: &Counters) {
    let now = Instant::now();
    if ready_at > now {
        std::thread::sleep(ready_at - now);
    }
    let mut text = String::with_capacity(64 * BATCH);
    while let Ok(first) = rx.recv() {
        text.clear();
        let mut frames = 0u64;
        let mut next = Some(first);
        let mut count = 0;
        let timestamp = wall_clock();
        while let Some(msg) = next.take() {
            counters.queued.fetch_sub(msg.weight(), Ordering::Relaxed);
            match msg {
                Outgoing::Frame(frame) => {
                    frames += 1;
                    Message::Frame { frame, timestamp }.format_into(&mut text);
                }
                Outgoing::Frames(batch) => {
                    for frame in batch.iter() {
                        frames += 1;
                        Message::Frame { frame: frame.clone(), timestamp }.format_into(&mut text);
                    }
                }
                Outgoing::Echo => Message::Echo.format_into(&mut text),
            }
            count += 1;
            if count < BATCH {
                next = rx.try_recv().ok();
            }
        }
        if let Err(e) = out.write_all(text.as_bytes()) {
            tracing::warn!(client = counters.id, peer = %counters.peer, "socketcand hub: write failed, disconnecting: {e}");
            let _ = out.shutdown(Shutdown::Both);
            return;
        }
        counters.to_client.fetch_add(frames, Ordering::Relaxed);
    }
}
