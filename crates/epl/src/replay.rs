//! Reading captures for [`crate::Monitor::replay`]: classic pcap (any byte order, µs or ns
//! timestamps) or pcapng, Ethernet link type only. Packets on other link types are skipped.
//!
//! pcapng time stamps count units of the interface's `if_tsresol` (microseconds when the
//! option is absent, as the pcapng specification says; dumpcap writes nanoseconds) from its
//! `if_tsoffset` (seconds); both are honoured per interface, so a capture replays at the
//! speed it was recorded. A packet's `epb_dropcount` (frames the capturing system lost before
//! it) is kept in [`CapturedFrame::dropped_before`].

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use pcap_file::pcap::PcapReader;
use pcap_file::pcapng::blocks::enhanced_packet::EnhancedPacketOption;
use pcap_file::pcapng::blocks::interface_description::{
    InterfaceDescriptionBlock, InterfaceDescriptionOption,
};
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
    /// Frames the capturing system lost between the previous frame of the same interface and
    /// this one (pcapng `epb_dropcount`; 0 when not recorded).
    pub dropped_before: u64,
}

impl CapturedFrame {
    /// A frame captured at `at_ns` with no recorded loss before it.
    pub fn new(at_ns: u64, data: Vec<u8>) -> Self {
        Self { at_ns, data, dropped_before: 0 }
    }
}

/// One pcapng interface: its link type and how its time stamps convert to nanoseconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PcapNgInterface {
    /// Ethernet (the others' packets are skipped).
    pub ethernet: bool,
    /// Time stamp units per second (`if_tsresol`: 10^6 when absent).
    pub units_per_second: u128,
    /// Seconds added to every time stamp (`if_tsoffset`).
    pub offset_s: u64,
}

impl PcapNgInterface {
    /// The interface an Interface Description Block describes.
    ///
    /// # Errors
    /// The `if_tsresol` is beyond what 128 bits can hold (a power of ten above 10^38 or of
    /// two above 2^127).
    pub fn from_idb(idb: &InterfaceDescriptionBlock<'_>) -> Result<Self, String> {
        let mut units_per_second = 1_000_000u128;
        let mut offset_s = 0;
        for o in &idb.options {
            match o {
                InterfaceDescriptionOption::IfTsResol(r) => {
                    let exp = u32::from(r & 0x7F);
                    let base: u128 = if r & 0x80 == 0 { 10 } else { 2 };
                    units_per_second =
                        base.checked_pow(exp).ok_or_else(|| format!("unsupported if_tsresol 0x{r:02x}"))?;
                }
                InterfaceDescriptionOption::IfTsOffset(s) => offset_s = *s,
                _ => {}
            }
        }
        Ok(Self { ethernet: idb.linktype == DataLink::ETHERNET, units_per_second, offset_s })
    }

    /// Nanoseconds since the Unix epoch of a raw time stamp of `units` (saturating).
    pub fn to_ns(&self, units: u128) -> u64 {
        let ns = units.saturating_mul(1_000_000_000) / self.units_per_second.max(1);
        let ns = ns.saturating_add(u128::from(self.offset_s) * 1_000_000_000);
        u64::try_from(ns).unwrap_or(u64::MAX)
    }
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
        let mut interfaces = Vec::new();
        while let Some(block) = reader.next_block() {
            match block.map_err(fmt_err)? {
                Block::SectionHeader(_) => interfaces.clear(),
                Block::InterfaceDescription(idb) => interfaces.push(
                    PcapNgInterface::from_idb(&idb)
                        .map_err(|message| ReplayError::Format { path: p.clone(), message })?,
                ),
                Block::EnhancedPacket(epb) => {
                    // pcap-file hands the raw time stamp over as nanoseconds, whatever its unit.
                    let units = epb.timestamp.as_nanos();
                    let Some(iface) = interfaces.get(usize::try_from(epb.interface_id).unwrap_or(usize::MAX))
                    else {
                        return Err(ReplayError::Format {
                            path: p.clone(),
                            message: format!("packet on undescribed interface {}", epb.interface_id),
                        });
                    };
                    if iface.ethernet {
                        let dropped_before = epb
                            .options
                            .iter()
                            .find_map(|o| match o {
                                EnhancedPacketOption::DropCount(n) => Some(*n),
                                _ => None,
                            })
                            .unwrap_or(0);
                        out.push(CapturedFrame {
                            at_ns: iface.to_ns(units),
                            data: epb.data.to_vec(),
                            dropped_before,
                        });
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
            out.push(CapturedFrame::new(at_ns, pkt.data.to_vec()));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

    use super::*;

    fn iface(options: Vec<InterfaceDescriptionOption<'static>>) -> Result<PcapNgInterface, String> {
        PcapNgInterface::from_idb(&InterfaceDescriptionBlock {
            linktype: DataLink::ETHERNET,
            snaplen: 0,
            options,
        })
    }

    #[test]
    fn if_tsresol_and_if_tsoffset_convert_to_nanoseconds() {
        // Absent: microseconds (pcapng specification).
        assert_eq!(iface(vec![]).unwrap().to_ns(1_500_000), 1_500_000_000);
        assert_eq!(iface(vec![InterfaceDescriptionOption::IfTsResol(9)]).unwrap().to_ns(7), 7);
        assert_eq!(iface(vec![InterfaceDescriptionOption::IfTsResol(3)]).unwrap().to_ns(2), 2_000_000);
        // 2^-10 s units: 1024 units are one second.
        assert_eq!(
            iface(vec![InterfaceDescriptionOption::IfTsResol(0x80 | 10)]).unwrap().to_ns(1024),
            1_000_000_000
        );
        let i =
            iface(vec![InterfaceDescriptionOption::IfTsResol(6), InterfaceDescriptionOption::IfTsOffset(10)])
                .unwrap();
        assert_eq!(i.to_ns(1), 10_000_001_000);
        // Beyond 128 bits: refused, not silently wrong.
        assert!(iface(vec![InterfaceDescriptionOption::IfTsResol(39)]).is_err());
        assert!(iface(vec![InterfaceDescriptionOption::IfTsResol(38)]).is_ok());
        // Saturates instead of wrapping.
        assert_eq!(
            iface(vec![InterfaceDescriptionOption::IfTsResol(0)]).unwrap().to_ns(u128::from(u64::MAX)),
            u64::MAX
        );
    }
}
