//! A virtual CAN bus speaking the server side of the socketcand protocol over TCP.
//!
//! Every frame a client sends reaches every *other* client (no echo), in one global
//! order. One thread serves every client from an event loop (`epoll` through `mio`): a
//! frame read from one socket is written to the others by the same thread, with no
//! hand-off between threads (see `docs/decisions.md`). With a bit rate configured, the
//! loop also models the bus: a frame is delivered when the virtual bus has carried it
//! (`deliver_at = max(arrival, bus_free_at) + frame_time`), so the hub carries no more
//! frames per second than a real bus would.

use super::bus_model::BusModel;
use super::session::{Chunk, Counters, Session, QUEUE_CAPACITY};
use crate::{wire_time, CanError, CanFrame};
use mio::net::TcpListener;
use mio::{Events, Interest, Poll, Token, Waker};
use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// How to start a [`Hub`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HubConfig {
    /// Address to listen on (port 0 picks a free port; see [`Hub::local_addr`]).
    pub listen: SocketAddr,
    /// Bit rate of the modelled bus; `None` forwards frames at once.
    pub bitrate: Option<u32>,
    /// The channel name clients are expected to open (any name is accepted).
    pub channel: String,
}

/// Counters of one client.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ClientStats {
    /// Hub-local client number (1, 2, ... in accept order).
    pub id: u64,
    /// The client's address.
    pub peer: SocketAddr,
    /// Frames the client sent to the bus.
    pub sent: u64,
    /// Frames written to the client.
    pub received: u64,
    /// Whether the client is still connected.
    pub connected: bool,
}

/// Counters of a [`Hub`].
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct HubStats {
    /// Data frames carried by the bus.
    pub frames: u64,
    /// Worst-case bits of those frames ([`wire_time::worst_case_bits`]).
    pub bits: u64,
    /// Remote (RTR) frames received and not forwarded (socketcand cannot express them).
    pub remote_dropped: u64,
    /// Every client seen, in accept order.
    pub clients: Vec<ClientStats>,
}

/// Counters shared between the loop and [`Hub::stats`].
#[derive(Default)]
struct Shared {
    stop: AtomicBool,
    seen: Mutex<Vec<Arc<Counters>>>,
    frames: AtomicU64,
    bits: AtomicU64,
    remote: AtomicU64,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

const LISTENER: Token = Token(0);
const WAKER: Token = Token(1);
/// Tokens of clients start here.
const FIRST_CLIENT: u64 = 2;

/// A running socketcand hub. Stops on [`Hub::stop`] or drop.
pub struct Hub {
    local_addr: SocketAddr,
    channel: String,
    shared: Arc<Shared>,
    waker: Arc<Waker>,
    thread: Option<JoinHandle<()>>,
}

impl Hub {
    /// Binds `config.listen` and starts serving.
    pub fn start(config: HubConfig) -> Result<Hub, CanError> {
        if config.bitrate == Some(0) {
            return Err(CanError::Address("hub bit rate must be > 0".into()));
        }
        let std_listener = std::net::TcpListener::bind(config.listen)?;
        std_listener.set_nonblocking(true)?;
        let local_addr = std_listener.local_addr()?;
        let mut listener = TcpListener::from_std(std_listener);
        let poll = Poll::new()?;
        poll.registry().register(&mut listener, LISTENER, Interest::READABLE)?;
        let waker = Arc::new(Waker::new(poll.registry(), WAKER)?);
        let shared = Arc::new(Shared::default());
        let mut event_loop = EventLoop {
            poll,
            listener,
            shared: Arc::clone(&shared),
            channel: config.channel.clone(),
            sessions: HashMap::new(),
            next_id: 0,
            bus: config.bitrate.map(BusModel::new),
            dirty: Vec::new(),
            again: Vec::new(),
        };
        let thread = std::thread::Builder::new().name("socketcand-hub".into()).spawn(move || {
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Device);
            event_loop.run()
        })?;
        tracing::info!(%local_addr, bitrate = ?config.bitrate, "socketcand hub listening");
        Ok(Hub { local_addr, channel: config.channel, shared, waker, thread: Some(thread) })
    }

    /// The address the hub listens on.
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// The URI clients can pass to [`crate::open_bus`].
    pub fn uri(&self) -> String {
        format!("socketcand://{}/{}", self.local_addr, self.channel)
    }

    /// A snapshot of the counters.
    pub fn stats(&self) -> HubStats {
        let clients = lock(&self.shared.seen)
            .iter()
            .map(|c| ClientStats {
                id: c.id,
                peer: c.peer,
                sent: c.from_client.load(Ordering::Relaxed),
                received: c.to_client.load(Ordering::Relaxed),
                connected: c.connected.load(Ordering::Relaxed),
            })
            .collect();
        HubStats {
            frames: self.shared.frames.load(Ordering::Relaxed),
            bits: self.shared.bits.load(Ordering::Relaxed),
            remote_dropped: self.shared.remote.load(Ordering::Relaxed),
            clients,
        }
    }

    /// Stops accepting, disconnects every client and joins the hub's thread.
    pub fn stop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Err(e) = self.waker.wake() {
            tracing::warn!("socketcand hub: cannot wake the event loop to stop it: {e}");
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Hub {
    fn drop(&mut self) {
        self.stop();
    }
}

fn wall_clock() -> Duration {
    SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default()
}

/// When the first client with text waiting (and a socket not known to be full) may be
/// written to: `(waiting, ready_at)` per client. A time already past is returned as is
/// (the loop must not wait): the loop may have woken a little before a client's settle
/// time ended, found it not ready, and must come back for it without another event.
fn first_write(clients: impl Iterator<Item = (bool, Option<Instant>)>) -> Option<Instant> {
    clients.filter(|(waiting, _)| *waiting).filter_map(|(_, ready_at)| ready_at).min()
}

/// The hub's thread: every socket, the bus model and the fan-out.
struct EventLoop {
    poll: Poll,
    listener: TcpListener,
    shared: Arc<Shared>,
    channel: String,
    sessions: HashMap<u64, Session>,
    next_id: u64,
    bus: Option<BusModel>,
    /// Clients with text queued in this turn (flushed at its end).
    dirty: Vec<u64>,
    /// Clients whose read budget ran out (read again in the next turn).
    again: Vec<u64>,
}

impl EventLoop {
    fn run(&mut self) {
        let mut events = Events::with_capacity(256);
        while !self.shared.stop.load(Ordering::Relaxed) {
            let timeout = self.timeout(Instant::now());
            if let Err(e) = self.poll.poll(&mut events, timeout) {
                if e.kind() != std::io::ErrorKind::Interrupted {
                    tracing::error!("socketcand hub: poll failed, stopping: {e}");
                    break;
                }
            }
            for event in events.iter() {
                match event.token() {
                    LISTENER => self.accept(),
                    WAKER => {}
                    Token(t) => {
                        let id = t as u64;
                        if event.is_readable() || event.is_read_closed() || event.is_error() {
                            self.read(id);
                        }
                        if event.is_writable() {
                            self.dirty.push(id);
                        }
                    }
                }
            }
            for id in std::mem::take(&mut self.again) {
                self.read(id);
            }
            self.deliver_due();
            self.flush_dirty();
        }
        for (_, s) in self.sessions.drain() {
            s.counters.connected.store(false, Ordering::Relaxed);
        }
    }

    /// How long the next poll may wait: until a client's settle time ends, a modelled
    /// frame is due, or (without either) until woken.
    fn timeout(&mut self, now: Instant) -> Option<Duration> {
        if !self.again.is_empty() {
            return Some(Duration::ZERO);
        }
        let settle = first_write(self.sessions.values().map(|s| (s.pending() && !s.want_write, s.ready_at)));
        let due = self.bus.as_ref().and_then(BusModel::next_due);
        let next = match (settle, due) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }?;
        let left = next.saturating_duration_since(now);
        // epoll waits whole milliseconds: the last stretch of a modelled frame is slept
        // precisely, with the sockets polled just before and just after.
        if due == Some(next) && left < Duration::from_micros(1500) {
            std::thread::sleep(left);
            return Some(Duration::ZERO);
        }
        Some(left)
    }

    fn accept(&mut self) {
        loop {
            match self.listener.accept() {
                Ok((stream, peer)) => {
                    self.next_id += 1;
                    let id = self.next_id;
                    let mut session = match Session::accept(stream, id, peer) {
                        Ok(s) => s,
                        Err(e) => {
                            tracing::debug!(%peer, "socketcand hub: client lost in the handshake: {e}");
                            continue;
                        }
                    };
                    let token = Token((id + FIRST_CLIENT) as usize);
                    if let Err(e) =
                        self.poll.registry().register(&mut session.stream, token, Interest::READABLE)
                    {
                        tracing::warn!(%peer, "socketcand hub: cannot watch the client: {e}");
                        continue;
                    }
                    lock(&self.shared.seen).push(Arc::clone(&session.counters));
                    self.sessions.insert(id + FIRST_CLIENT, session);
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => {
                    tracing::warn!("socketcand hub: accept failed: {e}");
                    return;
                }
            }
        }
    }

    fn read(&mut self, key: u64) {
        let Some(session) = self.sessions.get_mut(&key) else { return };
        let input = session.read(&self.channel, Instant::now());
        if input.more {
            self.again.push(key);
        }
        for batch in input.batches {
            self.submit(key, batch);
        }
        if input.closed {
            self.remove(key, "closed the connection", false);
        }
    }

    /// Frames sent by client `source` in one read enter the bus together.
    fn submit(&mut self, source: u64, frames: Vec<CanFrame>) {
        let (remote, data): (Vec<CanFrame>, Vec<CanFrame>) =
            frames.into_iter().partition(CanFrame::is_remote);
        if !remote.is_empty() {
            self.shared.remote.fetch_add(remote.len() as u64, Ordering::Relaxed);
            tracing::debug!("socketcand hub: dropping {} remote frame(s)", remote.len());
        }
        if data.is_empty() {
            return;
        }
        match &mut self.bus {
            Some(bus) => {
                let now = Instant::now();
                for frame in data {
                    bus.enter(now, source, frame);
                }
            }
            None => self.fan_out(source, &data),
        }
    }

    /// Delivers the modelled frames whose time has come.
    fn deliver_due(&mut self) {
        let Some(bus) = &mut self.bus else { return };
        let due = bus.take_due(Instant::now());
        for (source, frame) in due {
            self.fan_out(source, std::slice::from_ref(&frame));
        }
    }

    /// Queues `frames` for every joined client but `source`, dropping clients whose
    /// queue overflows.
    fn fan_out(&mut self, source: u64, frames: &[CanFrame]) {
        self.shared.frames.fetch_add(frames.len() as u64, Ordering::Relaxed);
        let bits: u64 = frames.iter().map(|f| u64::from(wire_time::worst_case_bits(f))).sum();
        self.shared.bits.fetch_add(bits, Ordering::Relaxed);
        let chunk = Chunk::frames(frames, wall_clock());
        let mut overflowed = Vec::new();
        for (key, s) in &mut self.sessions {
            if *key == source || !s.joined() {
                continue;
            }
            if s.push(&chunk) {
                self.dirty.push(*key);
            } else {
                overflowed.push(*key);
            }
        }
        for key in overflowed {
            self.remove(
                key,
                &format!("is not reading: over {QUEUE_CAPACITY} frames queued, disconnecting"),
                true,
            );
        }
    }

    /// Writes what is queued for the clients touched in this turn and for those whose
    /// settle time has ended.
    fn flush_dirty(&mut self) {
        let now = Instant::now();
        let mut keys = std::mem::take(&mut self.dirty);
        keys.extend(
            self.sessions
                .iter()
                .filter(|(_, s)| s.pending() && !s.want_write && s.ready_at.is_some_and(|t| t <= now))
                .map(|(k, _)| *k),
        );
        keys.sort_unstable();
        keys.dedup();
        for key in keys {
            let Some(s) = self.sessions.get_mut(&key) else { continue };
            match s.flush(now) {
                Ok(done) => {
                    // Watch writability only while the socket refuses text.
                    let want = !done && s.ready_at.is_some_and(|t| t <= now);
                    if want != s.want_write {
                        let interest =
                            if want { Interest::READABLE | Interest::WRITABLE } else { Interest::READABLE };
                        let token = Token(key as usize);
                        if let Err(e) = self.poll.registry().reregister(&mut s.stream, token, interest) {
                            tracing::warn!(client = s.id(), "socketcand hub: cannot watch the client: {e}");
                        }
                        s.want_write = want;
                    }
                }
                Err(e) => self.remove(key, &format!("write failed ({e}), disconnecting"), true),
            }
        }
    }

    /// Forgets client `key` and closes its socket; `why` is logged (as a warning when
    /// the hub drops a client that did not leave by itself).
    fn remove(&mut self, key: u64, why: &str, dropped: bool) {
        let Some(mut s) = self.sessions.remove(&key) else { return };
        if dropped {
            tracing::warn!(client = s.id(), peer = %s.counters.peer, "socketcand hub: client {why}");
        } else {
            tracing::debug!(client = s.id(), peer = %s.counters.peer, "socketcand hub: client {why}");
        }
        let _ = self.poll.registry().deregister(&mut s.stream);
        s.counters.connected.store(false, Ordering::Relaxed);
        let _ = s.stream.shutdown(std::net::Shutdown::Both);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_client_whose_settle_time_passed_is_written_at_once() {
        let now = Instant::now();
        let ms = Duration::from_millis;
        // The loop woke just before the settle time ended; by the next turn it has passed.
        assert_eq!(first_write([(true, Some(now - ms(1)))].into_iter()), Some(now - ms(1)));
        assert_eq!(
            first_write(
                [(true, Some(now + ms(5))), (true, Some(now + ms(2))), (false, Some(now))].into_iter()
            ),
            Some(now + ms(2)),
            "the earliest waiting client; one with nothing to write does not count"
        );
        assert_eq!(first_write([(true, None), (false, Some(now))].into_iter()), None, "nothing to wait for");
    }
}
