//! One-shot decoding of arbitrary bytes as a command and as a reply: never panics, and
//! whatever decodes re-encodes to the same bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_ps1a_protocol::{CommandFrame, StatusReply};

fuzz_target!(|data: &[u8]| {
    if let Ok(frame) = CommandFrame::decode(data) {
        assert_eq!(frame.encode(), data);
    }
    if let Ok(reply) = StatusReply::decode(data) {
        assert_eq!(&reply.to_bytes()[..], data);
    }
});
