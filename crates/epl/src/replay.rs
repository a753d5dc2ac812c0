//! Reading captures for [`crate::Monitor::replay`]: classic pcap (any byte order, µs or ns
//! timestamps) or pcapng, Ethernet link type only. Packets on other link types are skipped.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use pcap_file::pcap::PcapReader;
use pcap_file::pcapng::{Block, PcapNgReader};
use pcap_file::DataLink;
use thiserror::Error;

/// One captured Ethernet frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CapturedFrame {
    /// Capture time stamp (ns since the Unix epoch, as recorded).
    pub at_ns: u64,
    /// The frame bytes (without FCS, as captured).
    pub data: Vec<u8>,
}

/// Why a capture could not be read.
#[derive(Debug, Error)]
pub enum ReplayError {
    /// The file could not be opened or read.
    #[error("capture {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// The file is not a valid pcap/pcapng capture.
    #[error("capture {path}: {message}")]
    Format {
        /// The file.
        path: String,
        /// What the pcap reader said.
        message: String,
    },
}

/// The pcapng section header block type (also its magic at offset 0).
const PCAPNG_MAGIC: [u8; 4] = [0x0A, 0x0D, 0x0D, 0x0A];

/// Reads every Ethernet frame of a pcap or pcapng file.
pub fn read_capture(path: impl AsRef<Path>) -> Result<Vec<CapturedFrame>, ReplayError> {
    let p = path.as_ref().display().to_string();
    let io_err = |source| ReplayError::Io { path: p.clone(), source };
    let fmt_err = |e: pcap_file::PcapError| ReplayError::Format { path: p.clone(), message: e.to_string() };
    let mut file = BufReader::new(File::open(path.as_ref()).map_err(io_err)?);
    let mut magic = [0u8; 4];
    file.read_exact(&mut magic).map_err(io_err)?;
    file.seek(SeekFrom::Start(0)).map_err(io_err)?;
    let mut out = Vec::new();
    if magic == PCAPNG_MAGIC {
        let mut reader = PcapNgReader::new(file).map_err(fmt_err)?;
        let mut linktypes = Vec::new();
        while let Some(block) = reader.next_block() {
            match block.map_err(fmt_err)? {
                Block::SectionHeader(_) => linktypes.clear(),
                Block::InterfaceDescription(idb) => linktypes.push(idb.linktype),
                Block::EnhancedPacket(epb) => {
                    let ethernet = linktypes
                        .get(usize::try_from(epb.interface_id).unwrap_or(usize::MAX))
                        .map_or(true, |l| *l == DataLink::ETHERNET);
                    if ethernet {
                        let at_ns = u64::try_from(epb.timestamp.as_nanos()).unwrap_or(u64::MAX);
                        out.push(CapturedFrame { at_ns, data: epb.data.to_vec() });
                    }
                }
                _ => {}
            }
        }
    } else {
        let mut reader = PcapReader::new(file).map_err(fmt_err)?;
        if reader.header().datalink != DataLink::ETHERNET {
            return Ok(out);
        }
        while let Some(pkt) = reader.next_packet() {
            let pkt = pkt.map_err(fmt_err)?;
            let at_ns = u64::try_from(pkt.timestamp.as_nanos()).unwrap_or(u64::MAX);
            out.push(CapturedFrame { at_ns, data: pkt.data.to_vec() });
        }
    }
    Ok(out)
}
