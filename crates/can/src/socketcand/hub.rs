//! A virtual CAN bus speaking the server side of the socketcand protocol over TCP.
//!
//! Every frame a client sends reaches every *other* client (no echo), in one global
//! order. With a bit rate configured, one dispatcher thread models the bus: a frame is
//! delivered when the virtual bus has carried it (`deliver_at = max(arrival, bus_free_at)
//! + frame_time`), so the hub carries no more frames per second than a real bus would.

use super::session::{self, ClientHandle, Counters, Outgoing};
use crate::{wire_time, CanError, CanFrame};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{channel, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

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

/// State shared by the hub's threads.
pub(crate) struct Shared {
    pub channel: String,
    stop: AtomicBool,
    clients: Mutex<Vec<ClientHandle>>,
    seen: Mutex<Vec<Arc<Counters>>>,
    sockets: Mutex<Vec<(u64, TcpStream)>>,
    dispatch: Option<Mutex<Sender<(Instant, u64, CanFrame)>>>,
    frames: AtomicU64,
    bits: AtomicU64,
    remote: AtomicU64,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

impl Shared {
    pub fn stopping(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    pub fn register_counters(&self, c: Arc<Counters>) {
        lock(&self.seen).push(c);
    }

    pub fn join(&self, client: ClientHandle) {
        lock(&self.clients).push(client);
    }

    /// Client `id` is gone: forget its queue and socket.
    pub fn leave(&self, id: u64) {
        lock(&self.clients).retain(|c| c.counters.id != id);
        lock(&self.sockets).retain(|(i, _)| *i != id);
    }

    /// A frame sent by client `source` enters the bus.
    pub fn submit(&self, source: u64, frame: CanFrame) {
        if frame.is_remote() {
            self.remote.fetch_add(1, Ordering::Relaxed);
            tracing::debug!("socketcand hub: dropping remote frame {frame}");
            return;
        }
        match &self.dispatch {
            Some(tx) => {
                let _ = lock(tx).send((Instant::now(), source, frame));
            }
            None => self.fan_out(source, frame),
        }
    }

    /// Frames sent by client `source` in one read enter the bus together: every other
    /// client gets them as one message (its writer wakes once for the batch).
    pub fn submit_many(&self, source: u64, frames: Vec<CanFrame>) {
        let (remote, data): (Vec<CanFrame>, Vec<CanFrame>) =
            frames.into_iter().partition(CanFrame::is_remote);
        if !remote.is_empty() {
            self.remote.fetch_add(remote.len() as u64, Ordering::Relaxed);
            tracing::debug!("socketcand hub: dropping {} remote frame(s)", remote.len());
        }
        if self.dispatch.is_some() || data.len() == 1 {
            // The bus model times each frame; a single frame needs no batch.
            for f in data {
                self.submit(source, f);
            }
            return;
        }
        if data.is_empty() {
            return;
        }
        let mut clients = lock(&self.clients);
        self.frames.fetch_add(data.len() as u64, Ordering::Relaxed);
        let bits: u64 = data.iter().map(|f| u64::from(wire_time::worst_case_bits(f))).sum();
        self.bits.fetch_add(bits, Ordering::Relaxed);
        let batch: Arc<[CanFrame]> = data.into();
        clients.retain(|c| c.counters.id == source || c.offer(Outgoing::Frames(Arc::clone(&batch))));
    }

    /// Queues `frame` for every client but `source`, dropping clients that overflow.
    fn fan_out(&self, source: u64, frame: CanFrame) {
        let mut clients = lock(&self.clients);
        self.frames.fetch_add(1, Ordering::Relaxed);
        self.bits.fetch_add(u64::from(wire_time::worst_case_bits(&frame)), Ordering::Relaxed);
        clients.retain(|c| c.counters.id == source || c.offer(Outgoing::Frame(frame.clone())));
    }
}

/// A running socketcand hub. Stops on [`Hub::stop`] or drop.
pub struct Hub {
    local_addr: SocketAddr,
    shared: Arc<Shared>,
    threads: Vec<JoinHandle<()>>,
}

impl Hub {
    /// Binds `config.listen` and starts serving.
    pub fn start(config: HubConfig) -> Result<Hub, CanError> {
        let listener = TcpListener::bind(config.listen)?;
        listener.set_nonblocking(true)?;
        let local_addr = listener.local_addr()?;
        let (dispatch, dispatch_rx) = match config.bitrate {
            Some(0) => return Err(CanError::Address("hub bit rate must be > 0".into())),
            Some(_) => {
                let (tx, rx) = channel();
                (Some(Mutex::new(tx)), Some(rx))
            }
            None => (None, None),
        };
        let shared = Arc::new(Shared {
            channel: config.channel,
            stop: AtomicBool::new(false),
            clients: Mutex::new(Vec::new()),
            seen: Mutex::new(Vec::new()),
            sockets: Mutex::new(Vec::new()),
            dispatch,
            frames: AtomicU64::new(0),
            bits: AtomicU64::new(0),
            remote: AtomicU64::new(0),
        });
        let mut threads = Vec::new();
        let s = shared.clone();
        threads.push(
            std::thread::Builder::new()
                .name("socketcand-accept".into())
                .spawn(move || accept_loop(&s, &listener))?,
        );
        if let (Some(rx), Some(bitrate)) = (dispatch_rx, config.bitrate) {
            let s = shared.clone();
            let run = move || {
                let mut bus_free_at = Instant::now();
                while !s.stopping() {
                    let (arrival, source, frame) = match rx.recv_timeout(Duration::from_millis(50)) {
                        Ok(item) => item,
                        Err(RecvTimeoutError::Timeout) => continue,
                        Err(RecvTimeoutError::Disconnected) => return,
                    };
                    let deliver_at = arrival.max(bus_free_at) + wire_time::frame_time(&frame, bitrate);
                    let now = Instant::now();
                    if deliver_at > now {
                        std::thread::sleep(deliver_at - now);
                    }
                    bus_free_at = deliver_at;
                    s.fan_out(source, frame);
                }
            };
            threads.push(std::thread::Builder::new().name("socketcand-bus".into()).spawn(run)?);
        }
        tracing::info!(%local_addr, bitrate = ?config.bitrate, "socketcand hub listening");
        Ok(Hub { local_addr, shared, threads })
    }

    /// The address the hub listens on.
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// The URI clients can pass to [`crate::open_bus`].
    pub fn uri(&self) -> String {
        format!("socketcand://{}/{}", self.local_addr, self.shared.channel)
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

    /// Stops accepting, disconnects every client and joins the hub's threads.
    pub fn stop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
        lock(&self.shared.clients).clear();
        for (_, s) in lock(&self.shared.sockets).drain(..) {
            let _ = s.shutdown(Shutdown::Both);
        }
    }
}

impl Drop for Hub {
    fn drop(&mut self) {
        self.stop();
    }
}

fn accept_loop(shared: &Arc<Shared>, listener: &TcpListener) {
    let mut next_id = 0u64;
    while !shared.stopping() {
        match listener.accept() {
            Ok((stream, peer)) => {
                next_id += 1;
                let id = next_id;
                if stream.set_nonblocking(false).is_err() {
                    continue;
                }
                if let Ok(copy) = stream.try_clone() {
                    lock(&shared.sockets).push((id, copy));
                }
                let s = shared.clone();
                let spawned = std::thread::Builder::new()
                    .name(format!("socketcand-r{id}"))
                    .spawn(move || session::serve(s, stream, id, peer));
                if let Err(e) = spawned {
                    tracing::warn!("socketcand hub: cannot start client thread: {e}");
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(5))
            }
            Err(e) => {
                tracing::warn!("socketcand hub: accept failed: {e}");
                std::thread::sleep(Duration::from_millis(50));
            }
        }
    }
}
