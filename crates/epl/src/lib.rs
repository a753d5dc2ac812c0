//! Ethernet POWERLINK on real and simulated links, built on the sans-IO codec
//! [`motus_epl_protocol`] (`specs/powerlink.md`).
//!
//! * [`transport`]: the [`EthLink`] trait (one Ethernet port: send a frame, receive a frame
//!   with a time-out) and its implementations: [`RawSocket`] (AF_PACKET on a Linux interface,
//!   needs CAP_NET_RAW) and [`RingSocket`] (the same, received through a TPACKET_V3 ring),
//!   [`UdpLink`] (Ethernet frames carried in UDP datagrams on 127.0.0.1, unprivileged), and the
//!   decorators [`PcapLink`] (records a pcap file) and [`FaultyLink`] (drops, delays and
//!   corrupts frames with a seeded generator).
//! * [`sim`]: a simulated segment: a Managing Node running the cycle (boot-up, SoC, PReq,
//!   PRes time-outs, SoA, NMT commands) and Controlled Nodes that behave like servo drives,
//!   driven by a [`sim::MotionProgram`].
//! * [`netns`]: network namespaces joined by a bridge, for tests on a real kernel data path.
//! * [`node`]: standards-based nodes that interoperate with openPOWERLINK: a Controlled Node
//!   ([`node::cn`]) and a Managing Node ([`node::mn`]), sans-IO with runtimes on a link.
//! * [`monitor`]: a passive listener that decodes every frame, groups them into cycles and
//!   extracts mapped process values per node with freshness; [`replay`] feeds it from a pcap
//!   or pcapng file.
#![deny(unsafe_code)]

pub mod monitor;
pub mod netns;
pub mod node;
pub mod replay;
pub mod sim;
pub mod transport;

pub use monitor::{CycleSample, Monitor, MonitorConfig, MonitorStats, NodeCounters, NodeSample, TimingStats};
pub use transport::{
    open_link, EthLink, FaultConfig, FaultCounters, FaultyLink, KernelRxStats, PcapLink, RawSocket,
    RingConfig, RingSocket, UdpHub, UdpLink,
};
