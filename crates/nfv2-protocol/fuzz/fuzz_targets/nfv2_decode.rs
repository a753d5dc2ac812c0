//! Fuzz the single-frame decoder: never panics, and every frame it accepts re-encodes to
//! the same bytes (and survives the JSON-free round trip through `Frame`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_nfv2_protocol::{decode_frame, encode_frame, Revision};

fuzz_target!(|data: &[u8]| {
    for rev in Revision::ALL {
        if let Ok(frame) = decode_frame(data, rev) {
            let again = encode_frame(&frame, rev);
            assert_eq!(again.as_deref(), Ok(data), "re-encoding differs ({rev})");
        }
    }
});
