//! The Microsoft and Mouse Systems stream decoders fed the same arbitrary chunks (the input
//! alternates chunk length, chunk). They must never panic, every packet must round-trip,
//! and every byte is in a packet, counted as garbage, or pending.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_mouse_protocol::{MicrosoftPacket, MicrosoftStream, MouseSystemsPacket, MouseSystemsStream};

fuzz_target!(|data: &[u8]| {
    let _ = MicrosoftPacket::decode(data);
    let _ = MouseSystemsPacket::decode(data);
    let mut ms = MicrosoftStream::new();
    let mut sy = MouseSystemsStream::new();
    let mut rest = data;
    let mut total = 0usize;
    while let Some((&n, r)) = rest.split_first() {
        let (chunk, r) = r.split_at(usize::from(n).min(r.len()));
        rest = r;
        total += chunk.len();
        ms.push_with(chunk, |p| assert_eq!(MicrosoftPacket::decode(&p.encode()), Ok(p)));
        sy.push_with(chunk, |p| assert_eq!(MouseSystemsPacket::decode(&p.encode()), Ok(p)));
    }
    let a = ms.stats();
    assert_eq!(a.packets as usize * 3 + a.garbage_bytes as usize + ms.pending(), total);
    let b = sy.stats();
    assert_eq!(b.packets as usize * 5 + b.garbage_bytes as usize + sy.pending(), total);
});
