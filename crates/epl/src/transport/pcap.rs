//! [`PcapLink`]: a decorator that records every frame sent and received on a link into a
//! classic pcap file (link type 1, Ethernet; nanosecond timestamps), which tshark and
//! Wireshark decode as POWERLINK. Over a [`super::UdpLink`] the Ethernet frame inside the
//! datagram is recorded, not the UDP datagram.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use motus_epl_protocol::MacAddr;
use pcap_file::pcap::{PcapHeader, PcapPacket, PcapWriter};
use pcap_file::{DataLink, Endianness, TsResolution};

use super::EthLink;

/// The file behind the pcap writer, shared so that [`PcapLink::flush`] can reach it.
#[derive(Debug, Clone)]
struct Sink(Arc<Mutex<BufWriter<File>>>);

impl Write for Sink {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner).write(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner).flush()
    }
}

/// Records the frames of an inner link to a pcap file (see the module documentation).
#[derive(Debug)]
pub struct PcapLink<L> {
    inner: L,
    writer: Mutex<PcapWriter<Sink>>,
    sink: Sink,
    epoch_instant: Instant,
    epoch_wall: Duration,
}

fn pcap_err(e: pcap_file::PcapError) -> io::Error {
    io::Error::other(format!("pcap: {e}"))
}

impl<L: EthLink> PcapLink<L> {
    /// Creates (truncates) `path` and records `inner`'s traffic into it.
    pub fn create(inner: L, path: impl AsRef<Path>) -> io::Result<Self> {
        let sink = Sink(Arc::new(Mutex::new(BufWriter::new(File::create(path)?))));
        let header = PcapHeader {
            datalink: DataLink::ETHERNET,
            ts_resolution: TsResolution::NanoSecond,
            endianness: Endianness::Little,
            ..PcapHeader::default()
        };
        let writer = PcapWriter::with_header(sink.clone(), header).map_err(pcap_err)?;
        Ok(Self {
            inner,
            writer: Mutex::new(writer),
            sink,
            epoch_instant: Instant::now(),
            epoch_wall: SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default(),
        })
    }

    /// The wrapped link.
    pub fn inner(&self) -> &L {
        &self.inner
    }

    /// Flushes buffered records to the file.
    pub fn flush(&self) -> io::Result<()> {
        self.sink.clone().flush()
    }

    fn record(&self, at: Instant, frame: &[u8]) -> io::Result<()> {
        let ts = self.epoch_wall + at.saturating_duration_since(self.epoch_instant);
        let len = u32::try_from(frame.len()).unwrap_or(u32::MAX);
        let mut w = self.writer.lock().unwrap_or_else(PoisonError::into_inner);
        w.write_packet(&PcapPacket::new(ts, len, frame)).map_err(pcap_err)?;
        Ok(())
    }
}

impl<L: EthLink> EthLink for PcapLink<L> {
    fn send(&self, frame: &[u8]) -> io::Result<()> {
        let at = Instant::now();
        self.inner.send(frame)?;
        self.record(at, frame)
    }

    fn recv(&self, buf: &mut [u8], timeout: Duration) -> io::Result<Option<(usize, Instant)>> {
        let got = self.inner.recv(buf, timeout)?;
        if let Some((n, at)) = got {
            self.record(at, buf.get(..n).unwrap_or(buf))?;
        }
        Ok(got)
    }

    fn mac(&self) -> MacAddr {
        self.inner.mac()
    }

    fn describe(&self) -> String {
        format!("pcap({})", self.inner.describe())
    }

    fn rx_drops(&self) -> Option<u64> {
        self.inner.rx_drops()
    }

    fn kernel_rx_stats(&self) -> io::Result<Option<super::KernelRxStats>> {
        self.inner.kernel_rx_stats()
    }
}

impl<L> Drop for PcapLink<L> {
    fn drop(&mut self) {
        if let Err(e) = self.sink.flush() {
            tracing::warn!("pcap flush failed: {e}");
        }
    }
}
