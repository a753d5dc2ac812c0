//! Opening a bus from a URI: `socketcand://HOST:PORT/CHANNEL`, `socketcan://IFACE`,
//! `slcan:///dev/ttyUSB0?bitrate=500000`.

use crate::{CanBus, CanError};
use std::net::{SocketAddr, ToSocketAddrs};
use std::sync::Arc;

/// The default TCP port of the socketcand daemon.
pub const SOCKETCAND_PORT: u16 = 29536;

/// A parsed bus address.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BusUri {
    /// `socketcand://HOST[:PORT]/CHANNEL` (port defaults to [`SOCKETCAND_PORT`]).
    Socketcand {
        /// Host name or address.
        host: String,
        /// TCP port.
        port: u16,
        /// Channel to open, e.g. `can0`.
        channel: String,
    },
    /// `socketcan://IFACE`.
    SocketCan {
        /// Interface name, e.g. `can0`.
        iface: String,
    },
    /// `slcan://PATH?bitrate=N` (a Lawicel serial adapter).
    Slcan {
        /// Serial device path, e.g. `/dev/ttyUSB0`.
        path: String,
        /// CAN bit rate.
        bitrate: u32,
    },
}

fn bad(uri: &str, why: impl std::fmt::Display) -> CanError {
    CanError::Address(format!("{uri:?}: {why}"))
}

impl BusUri {
    /// Parses a bus URI.
    pub fn parse(uri: &str) -> Result<BusUri, CanError> {
        let (scheme, rest) = uri.split_once("://").ok_or_else(|| {
            bad(uri, "missing scheme (use socketcand://HOST:PORT/CHANNEL or socketcan://IFACE)")
        })?;
        match scheme {
            "socketcand" => {
                let (authority, channel) =
                    rest.split_once('/').ok_or_else(|| bad(uri, "missing /CHANNEL (e.g. /can0)"))?;
                if channel.is_empty() || channel.contains(['/', ' ', '<', '>', '?']) {
                    return Err(bad(uri, format!("bad channel {channel:?}")));
                }
                let (host, port) = match authority.rsplit_once(':') {
                    Some((h, p)) if !h.ends_with(':') || h.starts_with('[') => {
                        let port = p.parse::<u16>().map_err(|_| bad(uri, format!("bad port {p:?}")))?;
                        (h, port)
                    }
                    _ => (authority, SOCKETCAND_PORT),
                };
                if host.is_empty() {
                    return Err(bad(uri, "missing host"));
                }
                Ok(BusUri::Socketcand { host: host.to_owned(), port, channel: channel.to_owned() })
            }
            "socketcan" => {
                if rest.is_empty() || rest.len() > 15 || rest.contains(['/', ' ', '?']) {
                    return Err(bad(
                        uri,
                        format!("bad interface name {rest:?} (1-15 characters, e.g. can0)"),
                    ));
                }
                Ok(BusUri::SocketCan { iface: rest.to_owned() })
            }
            "slcan" => {
                let (path, query) = rest.split_once('?').unwrap_or((rest, ""));
                if path.is_empty() {
                    return Err(bad(uri, "missing serial device path"));
                }
                let mut bitrate = None;
                for pair in query.split('&').filter(|p| !p.is_empty()) {
                    match pair.split_once('=') {
                        Some(("bitrate", v)) => {
                            bitrate =
                                Some(v.parse::<u32>().map_err(|_| bad(uri, format!("bad bitrate {v:?}")))?)
                        }
                        _ => return Err(bad(uri, format!("unknown option {pair:?} (only bitrate=N)"))),
                    }
                }
                let bitrate = bitrate.ok_or_else(|| bad(uri, "missing ?bitrate=N"))?;
                Ok(BusUri::Slcan { path: path.to_owned(), bitrate })
            }
            other => Err(bad(uri, format!("unknown scheme {other:?} (socketcand, socketcan, slcan)"))),
        }
    }
}

/// Opens the bus `uri` names (see [`BusUri`]).
pub fn open_bus(uri: &str) -> Result<Arc<dyn CanBus>, CanError> {
    match BusUri::parse(uri)? {
        BusUri::Socketcand { host, port, channel } => {
            let addr: SocketAddr = (host.trim_start_matches('[').trim_end_matches(']'), port)
                .to_socket_addrs()
                .map_err(|e| bad(uri, format!("cannot resolve {host:?}: {e}")))?
                .next()
                .ok_or_else(|| bad(uri, format!("{host:?} has no address")))?;
            Ok(Arc::new(crate::socketcand::SocketcandBus::connect(addr, &channel)?))
        }
        #[cfg(target_os = "linux")]
        BusUri::SocketCan { iface } => Ok(Arc::new(crate::socketcan::SocketCanBus::open(&iface)?)),
        #[cfg(not(target_os = "linux"))]
        BusUri::SocketCan { iface } => Err(CanError::Unavailable {
            what: format!("SocketCAN interface {iface:?}"),
            reason: "SocketCAN exists only on Linux".into(),
        }),
        BusUri::Slcan { path, bitrate } => Ok(Arc::new(crate::slcan::SlcanBus::open(&path, bitrate)?)),
    }
}
