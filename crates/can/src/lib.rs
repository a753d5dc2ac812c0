//! CAN transports for Motus.
//!
//! Every transport implements [`CanBus`]: send a frame, receive the next frame with a
//! time-out. Transports are shared between threads (`&self` methods), so a master can
//! receive on one thread and send from others.
//!
//! - [`memory`]: an in-process virtual bus for unit tests.
//! - [`pair`]: a bus whose other end is an in-process peer (a simulated device) that
//!   answers synchronously, on a [`motus_clock::Clock`] (virtual time in tests).
//! - [`socketcand`]: the socketcand protocol: a TCP hub that is a virtual bus shared with
//!   independent tools (python-can, python-canopen), and a client of hubs and daemons.
//! - [`socketcan`]: real adapters through Linux SocketCAN.
//! - [`slcan`]: Lawicel ASCII adapters on a serial port.
//! - [`decorate`]: wrappers that log (candump, pcap), inject faults or measure bus load.
//! - [`wire_time`]: how long a frame occupies a real bus at a bit rate.
//! - [`open_bus`]: a bus from a URI.
//! - [`reconnect`]: a bus that reopens its transport with back-off when it closes.

#![forbid(unsafe_code)]

pub mod decorate;
pub mod memory;
pub mod pair;
pub mod reconnect;
pub mod slcan;
#[cfg(target_os = "linux")]
pub mod socketcan;
pub mod socketcand;
pub mod uri;
pub mod wire_time;

pub use memory::{MemoryHub, MemoryPort};
pub use motus_can_frame::CanFrame;
pub use pair::{PairBus, PairPeer};
pub use reconnect::{ReconnectPolicy, ReconnectingBus, WhileDown};
pub use uri::{open_bus, BusUri};

use std::time::{Duration, Instant};

/// Errors of a CAN transport.
#[derive(Debug, thiserror::Error)]
pub enum CanError {
    /// The transport is closed (peer gone, hub stopped, port dropped).
    #[error("CAN transport closed: {0}")]
    Closed(String),
    /// An operating-system error.
    #[error("CAN transport I/O error: {0}")]
    Io(#[from] std::io::Error),
    /// The peer sent something this transport cannot understand.
    #[error("CAN transport protocol error: {0}")]
    Protocol(String),
    /// A URI or option is invalid.
    #[error("invalid CAN bus address: {0}")]
    Address(String),
    /// A transport cannot be opened on this machine (no driver, no such interface).
    #[error("{what} unavailable: {reason}")]
    Unavailable {
        /// What was asked for, e.g. `SocketCAN interface "vcan0"`.
        what: String,
        /// Why it cannot be opened.
        reason: String,
    },
}

/// A frame as received, with the local time it arrived.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Received {
    /// The frame.
    pub frame: CanFrame,
    /// When this process received it.
    pub at: Instant,
}

/// A CAN bus endpoint: every frame sent is seen by every *other* endpoint of the bus
/// (no echo to the sender, like a raw SocketCAN socket).
pub trait CanBus: Send + Sync {
    /// Queues one frame for transmission.
    fn send(&self, frame: &CanFrame) -> Result<(), CanError>;
    /// Queues several frames for transmission, in order. Transports that can hand them to
    /// the medium in one operation override it (socketcand: one TCP write instead of one
    /// per frame, so the peers wake once per batch); the default sends them one by one.
    fn send_batch(&self, frames: &[CanFrame]) -> Result<(), CanError> {
        frames.iter().try_for_each(|f| self.send(f))
    }
    /// Waits up to `timeout` for the next frame; `Ok(None)` on time-out. A zero `timeout`
    /// only returns a frame already received (a poll).
    fn recv(&self, timeout: Duration) -> Result<Option<Received>, CanError>;
    /// A short description for logs and errors (e.g. `socketcand://127.0.0.1:29536/can0`).
    fn describe(&self) -> String;
}

impl<T: CanBus + ?Sized> CanBus for std::sync::Arc<T> {
    fn send(&self, frame: &CanFrame) -> Result<(), CanError> {
        (**self).send(frame)
    }
    fn send_batch(&self, frames: &[CanFrame]) -> Result<(), CanError> {
        (**self).send_batch(frames)
    }
    fn recv(&self, timeout: Duration) -> Result<Option<Received>, CanError> {
        (**self).recv(timeout)
    }
    fn describe(&self) -> String {
        (**self).describe()
    }
}

impl<T: CanBus + ?Sized> CanBus for Box<T> {
    fn send(&self, frame: &CanFrame) -> Result<(), CanError> {
        (**self).send(frame)
    }
    fn send_batch(&self, frames: &[CanFrame]) -> Result<(), CanError> {
        (**self).send_batch(frames)
    }
    fn recv(&self, timeout: Duration) -> Result<Option<Received>, CanError> {
        (**self).recv(timeout)
    }
    fn describe(&self) -> String {
        (**self).describe()
    }
}

/// Convenience: the deadline `timeout` from now.
pub fn deadline(timeout: Duration) -> Instant {
    Instant::now() + timeout
}
