//! Real CAN adapters through Linux SocketCAN (`can0`, `vcan0`, ...).
//!
//! A raw `CAN_RAW` socket without own-message reception, so like every [`CanBus`] it does
//! not see its own frames. Needs a kernel with SocketCAN and an interface that is up.

use crate::{CanBus, CanError, CanFrame, Received};
use socketcan_crate::{CanSocket, EmbeddedFrame, ExtendedId, Id, Socket, StandardId};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// A [`CanBus`] on a SocketCAN interface.
pub struct SocketCanBus {
    iface: String,
    socket: CanSocket,
    read_lock: Mutex<()>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

impl SocketCanBus {
    /// Opens interface `iface` (e.g. `can0`).
    ///
    /// Fails with [`CanError::Unavailable`] naming the interface when the kernel has no
    /// SocketCAN or the interface does not exist.
    pub fn open(iface: &str) -> Result<SocketCanBus, CanError> {
        let socket = CanSocket::open(iface).map_err(|e| CanError::Unavailable {
            what: format!("SocketCAN interface {iface:?}"),
            reason: match e.raw_os_error() {
                Some(97) => {
                    format!("the kernel has no SocketCAN support (address family not supported: {e})")
                }
                Some(19) => format!("no such CAN interface ({e})"),
                _ => e.to_string(),
            },
        })?;
        Ok(SocketCanBus { iface: iface.to_owned(), socket, read_lock: Mutex::new(()) })
    }

    /// The interface name.
    pub fn iface(&self) -> &str {
        &self.iface
    }
}

fn to_native(frame: &CanFrame) -> Option<socketcan_crate::CanFrame> {
    let id: Id = if frame.is_extended() {
        Id::Extended(ExtendedId::new(frame.id())?)
    } else {
        Id::Standard(StandardId::new(u16::try_from(frame.id()).ok()?)?)
    };
    if frame.is_remote() {
        socketcan_crate::CanFrame::new_remote(id, usize::from(frame.dlc()))
    } else {
        socketcan_crate::CanFrame::new(id, frame.data())
    }
}

fn from_native(frame: &socketcan_crate::CanFrame) -> Option<CanFrame> {
    let (id, extended) = match frame.id() {
        Id::Standard(s) => (u32::from(s.as_raw()), false),
        Id::Extended(e) => (e.as_raw(), true),
    };
    match frame {
        socketcan_crate::CanFrame::Data(_) => CanFrame::with_format(id, extended, frame.data()).ok(),
        socketcan_crate::CanFrame::Remote(_) => {
            CanFrame::remote(id, extended, u8::try_from(frame.dlc()).ok()?).ok()
        }
        socketcan_crate::CanFrame::Error(_) => None,
    }
}

impl CanBus for SocketCanBus {
    fn send(&self, frame: &CanFrame) -> Result<(), CanError> {
        let native =
            to_native(frame).ok_or_else(|| CanError::Protocol(format!("frame {frame} not representable")))?;
        self.socket.write_frame_insist(&native)?;
        Ok(())
    }

    fn recv(&self, timeout: Duration) -> Result<Option<Received>, CanError> {
        let _guard = lock(&self.read_lock);
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now()).max(Duration::from_micros(1));
            self.socket.set_read_timeout(left)?;
            match self.socket.read_frame() {
                Ok(native) => match from_native(&native) {
                    Some(frame) => return Ok(Some(Received { frame, at: Instant::now() })),
                    None => tracing::warn!(iface = %self.iface, "SocketCAN error frame: {:?}", native.id()),
                },
                Err(e)
                    if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) =>
                {
                    return Ok(None)
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e.into()),
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
        }
    }

    fn describe(&self) -> String {
        format!("socketcan://{}", self.iface)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::panic)]
    use super::*;

    #[test]
    fn frames_convert_both_ways() {
        for f in [
            CanFrame::new(0x605, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap(),
            CanFrame::new(0x080, &[]).unwrap(),
            CanFrame::with_format(0x1234_5678, true, &[1, 2, 3]).unwrap(),
            CanFrame::remote(0x701, false, 1).unwrap(),
        ] {
            let native = to_native(&f).unwrap();
            assert_eq!(from_native(&native).unwrap(), f);
        }
    }
}
