//! [`PacketScanner`]: finds the fixed-length packets of the three protocols for their
//! stream decoders ([`motus_wire::Stream`]).

use std::convert::Infallible;
use std::fmt;
use std::marker::PhantomData;

use motus_wire::{Scan, Scanner};

use crate::{converter, microsoft, mouse_systems, ConverterPacket, MicrosoftPacket, MouseSystemsPacket};

/// A fixed-length packet whose first byte is recognisable.
pub trait Packet: Sized {
    /// Bytes in one packet.
    const LEN: usize;
    /// True if `byte` can start a packet.
    fn is_start(byte: u8) -> bool;
    /// The packet in exactly [`Packet::LEN`] bytes, if they are one.
    fn parse(bytes: &[u8]) -> Option<Self>;
}

/// Finds a packet `P`: a start byte and the bytes after it that decode; otherwise the start
/// byte is garbage and the search resumes at the next byte.
pub struct PacketScanner<P>(PhantomData<fn() -> P>);

impl<P> Default for PacketScanner<P> {
    fn default() -> Self {
        PacketScanner(PhantomData)
    }
}

impl<P> Clone for PacketScanner<P> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<P> Copy for PacketScanner<P> {}

impl<P> fmt::Debug for PacketScanner<P> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "PacketScanner<{}>", std::any::type_name::<P>())
    }
}

impl<P: Packet> Scanner for PacketScanner<P> {
    type Frame = P;
    type Error = Infallible;

    fn scan(&self, buf: &[u8]) -> Scan<P> {
        match buf.first() {
            None => Scan::Incomplete,
            Some(&b) if !P::is_start(b) => Scan::Skip,
            Some(_) => match buf.get(..P::LEN) {
                None => Scan::Incomplete,
                Some(candidate) => match P::parse(candidate) {
                    Some(frame) => Scan::Frame { frame, len: P::LEN },
                    None => Scan::Skip,
                },
            },
        }
    }
}

/// Implements [`Packet`] with a packet type's length, start-byte test and `decode`.
macro_rules! packet {
    ($($packet:ty: $len:expr, |$byte:ident| $is_start:expr;)*) => {$(
        impl Packet for $packet {
            const LEN: usize = $len;
            fn is_start($byte: u8) -> bool {
                $is_start
            }
            fn parse(bytes: &[u8]) -> Option<Self> {
                <$packet>::decode(bytes).ok()
            }
        }
    )*};
}

packet! {
    ConverterPacket: converter::PACKET_LEN, |byte| byte == converter::START;
    MicrosoftPacket: microsoft::PACKET_LEN, |byte| byte & microsoft::SYNC != 0;
    MouseSystemsPacket: mouse_systems::PACKET_LEN, |byte| byte & mouse_systems::HEADER_MASK == mouse_systems::HEADER;
}
