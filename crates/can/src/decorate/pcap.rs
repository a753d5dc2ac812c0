//! pcap captures with LINKTYPE_CAN_SOCKETCAN (227), which Wireshark/tshark decode.
//!
//! Each record is a 16-byte SocketCAN `can_frame`: the CAN id as a big-endian u32 with
//! flags (0x8000_0000 extended, 0x4000_0000 remote), the DLC, 3 zero bytes, 8 data bytes
//! (zero padded).

use super::wall_clock;
use crate::{CanBus, CanError, CanFrame, Received};
use pcap_file::pcap::{PcapHeader, PcapPacket, PcapWriter};
use pcap_file::DataLink;
use std::fs::File;
use std::path::Path;
use std::sync::{Mutex, MutexGuard};
use std::time::Duration;

/// Flag of an extended (29-bit) id in a SocketCAN record.
pub const EFF_FLAG: u32 = 0x8000_0000;
/// Flag of a remote frame in a SocketCAN record.
pub const RTR_FLAG: u32 = 0x4000_0000;

/// The 16-byte LINKTYPE_CAN_SOCKETCAN record of `frame`.
pub fn socketcan_record(frame: &CanFrame) -> [u8; 16] {
    let mut id = frame.id();
    if frame.is_extended() {
        id |= EFF_FLAG;
    }
    if frame.is_remote() {
        id |= RTR_FLAG;
    }
    let mut rec = [0u8; 16];
    let (head, data) = rec.split_at_mut(8);
    let (id_bytes, rest) = head.split_at_mut(4);
    id_bytes.copy_from_slice(&id.to_be_bytes());
    if let Some(dlc) = rest.first_mut() {
        *dlc = frame.dlc();
    }
    for (d, s) in data.iter_mut().zip(frame.data()) {
        *d = *s;
    }
    rec
}

/// Writes every frame sent and received through the inner bus to a pcap file.
pub struct PcapCapture<B> {
    inner: B,
    writer: Mutex<PcapWriter<File>>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

fn pcap_err(e: pcap_file::PcapError) -> CanError {
    match e {
        pcap_file::PcapError::IoError(io) => CanError::Io(io),
        other => CanError::Protocol(format!("pcap: {other}")),
    }
}

impl<B: CanBus> PcapCapture<B> {
    /// Creates (truncates) the capture file at `path`.
    pub fn create(inner: B, path: &Path) -> Result<Self, CanError> {
        let file = File::create(path)?;
        let header = PcapHeader { datalink: DataLink::CAN_SOCKETCAN, snaplen: 16, ..PcapHeader::default() };
        let writer = PcapWriter::with_header(file, header).map_err(pcap_err)?;
        Ok(PcapCapture { inner, writer: Mutex::new(writer) })
    }

    /// The wrapped bus.
    pub fn inner(&self) -> &B {
        &self.inner
    }

    /// Appends one record (used for every frame sent and received).
    pub fn record(&self, frame: &CanFrame) -> Result<(), CanError> {
        let rec = socketcan_record(frame);
        let packet = PcapPacket::new(wall_clock(), 16, &rec);
        lock(&self.writer).write_packet(&packet).map_err(pcap_err)?;
        Ok(())
    }

    fn record_logged(&self, frame: &CanFrame) {
        if let Err(e) = self.record(frame) {
            tracing::warn!("pcap capture: write failed: {e}");
        }
    }
}

impl<B: CanBus> CanBus for PcapCapture<B> {
    fn send(&self, frame: &CanFrame) -> Result<(), CanError> {
        self.inner.send(frame)?;
        self.record_logged(frame);
        Ok(())
    }

    fn send_batch(&self, frames: &[CanFrame]) -> Result<(), CanError> {
        self.inner.send_batch(frames)?;
        for f in frames {
            self.record_logged(f);
        }
        Ok(())
    }

    fn recv(&self, timeout: Duration) -> Result<Option<Received>, CanError> {
        let r = self.inner.recv(timeout)?;
        if let Some(r) = &r {
            self.record_logged(&r.frame);
        }
        Ok(r)
    }

    fn describe(&self) -> String {
        format!("{} (pcap capture)", self.inner.describe())
    }
}
