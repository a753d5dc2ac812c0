//! One-shot decode of arbitrary bytes in every direction and CRC mode; every accepted frame
//! with a good CRC must re-encode to the same bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_kv01_protocol::{decode_message, CrcMode, Direction};

fuzz_target!(|data: &[u8]| {
    for dir in [Direction::ToModule, Direction::FromModule, Direction::Auto] {
        for mode in [CrcMode::Strict, CrcMode::Lenient] {
            if let Ok(d) = decode_message(data, dir, mode) {
                if d.crc_mismatch.is_none() {
                    if let Ok(bytes) = d.message.encode() {
                        assert_eq!(bytes, data);
                    }
                }
            }
        }
    }
});
