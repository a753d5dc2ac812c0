//! The converter-packet stream decoder fed arbitrary chunks (the input alternates chunk
//! length, chunk). It must never panic, every packet must re-encode to 7 bytes that decode
//! to it, and every byte is in a packet, counted as garbage, or pending.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_mouse_protocol::{ConverterPacket, ConverterStream};

fuzz_target!(|data: &[u8]| {
    let _ = ConverterPacket::decode(data);
    let mut dec = ConverterStream::new();
    let mut rest = data;
    let mut total = 0usize;
    while let Some((&n, r)) = rest.split_first() {
        let (chunk, r) = r.split_at(usize::from(n).min(r.len()));
        rest = r;
        total += chunk.len();
        dec.push_with(chunk, |p| {
            assert_eq!(ConverterPacket::decode(&p.encode()), Ok(p));
        });
    }
    let st = dec.stats();
    assert!(dec.pending() < 7);
    assert_eq!(st.packets as usize * 7 + st.garbage_bytes as usize + dec.pending(), total);
    dec.flush();
    assert_eq!(dec.pending(), 0);
});
