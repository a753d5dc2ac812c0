//! Decode arbitrary bytes as an Ethernet frame, raw and behind a valid POWERLINK Ethernet
//! header (so the fuzzer reaches the message decoders at once): never panics, and every
//! accepted frame re-encodes to the same bytes, also through its JSON form.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_epl_protocol::{CycleTracker, EplFrame};

/// Destination 01:11:1e:00:00:02, source 02:00:00:00:00:01, EtherType 0x88ab.
const HEADER: [u8; 14] = [1, 0x11, 0x1e, 0, 0, 2, 2, 0, 0, 0, 0, 1, 0x88, 0xab];

fn check(bytes: &[u8]) {
    if let Ok(frame) = EplFrame::decode(bytes) {
        assert_eq!(frame.encode().ok().as_deref(), Some(bytes));
        let json = serde_json::to_string(&frame).ok();
        let back: Option<EplFrame> = json.as_deref().and_then(|j| serde_json::from_str(j).ok());
        assert_eq!(back.as_ref(), Some(&frame));
        let mut t = CycleTracker::new();
        let _ = t.push(0, &frame);
        let _ = t.finish();
    }
}

fuzz_target!(|data: &[u8]| {
    check(data);
    let mut framed = HEADER.to_vec();
    framed.extend_from_slice(data);
    check(&framed);
});
