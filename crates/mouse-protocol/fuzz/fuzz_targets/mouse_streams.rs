//! The three stream decoders (converter, Microsoft, Mouse Systems) fed the same arbitrary
//! chunks (the input alternates chunk length, chunk), and the one-shot decoders fed the
//! whole input. They must never panic, every packet must re-encode to bytes that decode to
//! it, and every byte is in a packet, counted as garbage, or pending (less than a packet).
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_mouse_protocol::{
    ConverterPacket, MicrosoftPacket, MouseSystemsPacket, Packet, PacketError, PacketScanner, Stream,
};
use std::fmt::Debug;

/// One decoder: `round_trip` re-encodes a packet and decodes it again.
fn check<P: Packet + PartialEq + Debug>(data: &[u8], round_trip: fn(&P) -> Result<P, PacketError>) {
    let mut dec = Stream::<PacketScanner<P>>::default();
    let mut rest = data;
    while let Some((&n, r)) = rest.split_first() {
        let (chunk, r) = r.split_at(usize::from(n).min(r.len()));
        rest = r;
        dec.push(chunk);
        while let Some(p) = dec.next_frame() {
            assert_eq!(round_trip(&p).as_ref(), Ok(&p));
        }
    }
    let st = dec.stats();
    assert!(dec.pending() < P::LEN);
    assert_eq!(st.frame_bytes + st.garbage_bytes + dec.pending() as u64, st.bytes_in);
    assert_eq!(st.frame_bytes, st.frames * P::LEN as u64);
    dec.clear();
    assert_eq!(dec.pending(), 0);
}

fuzz_target!(|data: &[u8]| {
    let _ = ConverterPacket::decode(data);
    let _ = MicrosoftPacket::decode(data);
    let _ = MouseSystemsPacket::decode(data);
    check::<ConverterPacket>(data, |p| ConverterPacket::decode(&p.encode()));
    check::<MicrosoftPacket>(data, |p| MicrosoftPacket::decode(&p.encode()));
    check::<MouseSystemsPacket>(data, |p| MouseSystemsPacket::decode(&p.encode()));
});
