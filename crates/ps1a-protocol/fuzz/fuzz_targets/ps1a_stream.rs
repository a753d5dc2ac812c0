//! The streaming decoders fed arbitrary bytes in arbitrary chunks: never panic, and every
//! frame they return re-encodes to valid bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_ps1a_protocol::{CommandFrame, CommandStream, ReplyStream, StatusReply, StreamEvent};

fuzz_target!(|data: &[u8]| {
    let split = data.first().copied().unwrap_or(1).max(1) as usize;
    let mut commands = CommandStream::default();
    let mut replies = ReplyStream::default();
    for chunk in data.chunks(split) {
        commands.push(chunk);
        replies.push(chunk);
        while let Some(e) = commands.next_event() {
            if let StreamEvent::Frame(f) = e {
                assert!(CommandFrame::decode(&f.encode()).is_ok());
            }
        }
        while let Some(e) = replies.next_event() {
            if let StreamEvent::Frame(r) = e {
                assert_eq!(StatusReply::decode(&r.to_bytes()), Ok(r));
            }
        }
    }
});
