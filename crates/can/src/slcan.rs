//! Lawicel (SLCAN) ASCII adapters on a serial port: `t<III><L><data>\\r` frames.
//!
//! Many USB-CAN adapters (CANable, USBtin, ...) speak this. [`encode`] and [`decode`] are
//! the sans-IO codec; [`SlcanBus`] opens the port, sets the bit rate (`S<n>`), opens the
//! channel (`O`) and reads frames on a thread.

use crate::{CanBus, CanError, CanFrame, Received};
use std::fmt::Write as _;
use std::io::{Read, Write};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// The `S<n>` code of a standard bit rate.
pub fn bitrate_code(bitrate: u32) -> Option<u8> {
    [10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000]
        .iter()
        .position(|&b| b == bitrate)
        .and_then(|i| u8::try_from(i).ok())
}

/// The command line (with its `\r`) that transmits `frame`.
pub fn encode(frame: &CanFrame) -> String {
    let mut s = String::with_capacity(27);
    let kind = match (frame.is_remote(), frame.is_extended()) {
        (false, false) => 't',
        (false, true) => 'T',
        (true, false) => 'r',
        (true, true) => 'R',
    };
    s.push(kind);
    let _ =
        if frame.is_extended() { write!(s, "{:08X}", frame.id()) } else { write!(s, "{:03X}", frame.id()) };
    let _ = write!(s, "{}", frame.dlc());
    for b in frame.data() {
        let _ = write!(s, "{b:02X}");
    }
    s.push('\r');
    s
}

/// Decodes one received line (without its `\r`); `None` if it is not a frame.
pub fn decode(line: &str) -> Option<CanFrame> {
    let kind = line.chars().next()?;
    let (extended, remote) = match kind {
        't' => (false, false),
        'T' => (true, false),
        'r' => (false, true),
        'R' => (true, true),
        _ => return None,
    };
    let id_len = if extended { 8 } else { 3 };
    let id = u32::from_str_radix(line.get(1..1 + id_len)?, 16).ok()?;
    let dlc = line.get(1 + id_len..2 + id_len)?.parse::<u8>().ok()?;
    let rest = line.get(2 + id_len..)?;
    if remote {
        return rest.is_empty().then(|| CanFrame::remote(id, extended, dlc).ok()).flatten();
    }
    if rest.len() != 2 * usize::from(dlc) {
        return None;
    }
    let mut data = Vec::with_capacity(8);
    for i in 0..usize::from(dlc) {
        data.push(u8::from_str_radix(rest.get(2 * i..2 * i + 2)?, 16).ok()?);
    }
    CanFrame::with_format(id, extended, &data).ok()
}

/// A [`CanBus`] on an SLCAN serial adapter.
pub struct SlcanBus {
    path: String,
    port: Mutex<Box<dyn serialport::SerialPort>>,
    rx: Mutex<Receiver<Received>>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

impl SlcanBus {
    /// Opens the adapter at `path` and the CAN channel at `bitrate`.
    pub fn open(path: &str, bitrate: u32) -> Result<SlcanBus, CanError> {
        let code = bitrate_code(bitrate)
            .ok_or_else(|| CanError::Address(format!("SLCAN has no bit rate {bitrate}")))?;
        let unavailable = |e: serialport::Error| CanError::Unavailable {
            what: format!("SLCAN port {path:?}"),
            reason: e.to_string(),
        };
        let mut port =
            serialport::new(path, 115_200).timeout(Duration::from_millis(50)).open().map_err(unavailable)?;
        port.write_all(format!("C\rS{code}\rO\r").as_bytes())?;
        let mut reader = port.try_clone().map_err(unavailable)?;
        let (tx, rx) = channel();
        std::thread::Builder::new().name(format!("slcan-{path}")).spawn(move || {
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Device);
            let mut line = String::new();
            let mut buf = [0u8; 256];
            loop {
                let n = match reader.read(&mut buf) {
                    Ok(0) => return,
                    Ok(n) => n,
                    Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
                    Err(_) => return,
                };
                for &b in buf.get(..n).unwrap_or(&[]) {
                    if b == b'\r' || b == 0x07 {
                        if let Some(frame) = decode(&line) {
                            if tx.send(Received { frame, at: Instant::now() }).is_err() {
                                return;
                            }
                        }
                        line.clear();
                    } else if line.len() < 32 {
                        line.push(char::from(b));
                    }
                }
            }
        })?;
        Ok(SlcanBus { path: path.to_owned(), port: Mutex::new(port), rx: Mutex::new(rx) })
    }
}

impl CanBus for SlcanBus {
    fn send(&self, frame: &CanFrame) -> Result<(), CanError> {
        lock(&self.port).write_all(encode(frame).as_bytes())?;
        Ok(())
    }

    fn recv(&self, timeout: Duration) -> Result<Option<Received>, CanError> {
        match lock(&self.rx).recv_timeout(timeout) {
            Ok(r) => Ok(Some(r)),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => {
                Err(CanError::Closed(format!("SLCAN port {} closed", self.path)))
            }
        }
    }

    fn describe(&self) -> String {
        format!("slcan://{}", self.path)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn lawicel_lines() {
        // Hand-written from the Lawicel CAN232 manual: t<id:3><len:1><data>, T<id:8>..., r/R remote.
        let sdo = CanFrame::new(0x605, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap();
        // t, id 605, DLC 8, then 40 00 10 00 00 00 00 00.
        assert_eq!(encode(&sdo), "t6058".to_owned() + "4000100000000000" + "\r");
        assert_eq!(encode(&CanFrame::new(0x080, &[]).unwrap()), "t0800\r");
        assert_eq!(encode(&CanFrame::remote(0x701, false, 1).unwrap()), "r7011\r");
        let ext = CanFrame::with_format(0x1234_5678, true, &[0xAB]).unwrap();
        assert_eq!(encode(&ext), "T123456781AB\r");
        for f in [sdo, ext, CanFrame::remote(0x701, false, 1).unwrap()] {
            assert_eq!(decode(encode(&f).trim_end_matches('\r')), Some(f));
        }
        assert_eq!(decode("t60581122"), None, "length mismatch");
        assert_eq!(decode("z"), None);
        assert_eq!(bitrate_code(500_000), Some(6));
        assert_eq!(bitrate_code(33_333), None);
    }
}
