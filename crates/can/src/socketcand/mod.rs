//! The socketcand protocol (CAN over TCP, ASCII): a codec, a hub that is a virtual bus,
//! and a client that joins a hub or a real socketcand daemon.
//!
//! ```no_run
//! use motus_can::socketcand::{Hub, HubConfig, SocketcandBus};
//! use motus_can::{CanBus, CanFrame};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let hub = Hub::start(HubConfig { listen: "127.0.0.1:0".parse()?, bitrate: None, channel: "can0".into() })?;
//! let a = SocketcandBus::connect(hub.local_addr(), "can0")?;
//! let b = SocketcandBus::connect(hub.local_addr(), "can0")?;
//! a.send(&CanFrame::new(0x080, &[])?)?;
//! let sync = b.recv(std::time::Duration::from_secs(1))?;
//! # Ok(()) }
//! ```

mod bus_model;
pub mod client;
pub mod codec;
pub mod hub;
mod session;

pub use client::SocketcandBus;
pub use codec::{CodecError, Message, StreamParser};
pub use hub::{ClientStats, Hub, HubConfig, HubStats};
pub use session::{QUEUE_CAPACITY, SETTLE};
