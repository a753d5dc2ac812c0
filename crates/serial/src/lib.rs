//! # motus-serial — serial lines and the half-duplex bus master
//!
//! * [`Link`]: the one seam for byte IO. [`SerialLink`] opens real ports (RS-232, RS-485
//!   adapters, USB-serial) and the slave side of a pseudo-terminal; [`PtyLink`] is the
//!   master side a simulator serves (it creates the pty and a symlink to it).
//! * Decorators that work on any link: [`FaultInjector`] (drop writes, corrupt bytes both
//!   ways), [`Paced`] (bytes leave at the real baud rate), [`Traced`] (hex dumps to
//!   `tracing`).
//! * [`FramedLink`]: a link read frame by frame with a codec's stream decoder.
//! * [`SimServer`]: the serve loop of every serial simulator; a protocol plugs in its
//!   codec's scanner and a [`Responder`].
//! * [`SimLink`]: the host's side of an in-process simulated line: the simulator's serve
//!   step runs inline in the host's thread on a (virtual) [`motus_clock::Clock`], so a
//!   driver and its simulator run in one test on virtual time.
//! * Every wait is on a [`motus_clock::Clock`] (the system clock by default; `with_clock`
//!   constructors take another).
//! * [`BusMaster`]: request/response transactions on a multi-drop line (replies found by
//!   the codec's [`motus_wire::Scanner`]), with time-outs
//!   from the baud rate, retries, resynchronisation, per-device counters, exclusive
//!   access, a [`Poller`] for periodic polling and keep-alive, and [`BusStats`]
//!   (transactions/s, line utilisation).
//! * [`DeviceUri`]: `scheme:///dev/ttyUSB0?addr=3&baud=9600` names a device on a line.

#![forbid(unsafe_code)]

mod bus;
mod link;
mod serve;
mod uri;

pub use bus::master::{BusConfig, BusError, BusMaster, Request};
pub use bus::poller::{Poller, PollerHandle};
pub use bus::stats::{BusStats, DeviceStats};
pub use link::fault::{FaultConfig, FaultInjector, FaultStats, RateError};
pub use link::framed::FramedLink;
pub use link::paced::Paced;
pub use link::pty::PtyLink;
pub use link::serial_port::SerialLink;
pub use link::sim::{NullLink, SimLink};
pub use link::trace::Traced;
pub use link::{LineSettings, Link, SharedLink};
pub use serve::{Answer, LineError, Responder, ServeOptions, ServeThread, SimServer};
pub use uri::{DeviceUri, UriError};
