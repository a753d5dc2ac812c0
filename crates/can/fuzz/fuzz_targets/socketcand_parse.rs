//! The socketcand stream parser fed arbitrary chunks (bytes alternate: chunk length,
//! chunk). It must never panic, keep its buffer bounded, and every typed frame or send
//! message must format to text that parses back to the same message.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_can::socketcand::codec::MAX_MESSAGE;
use motus_can::socketcand::{Message, StreamParser};

fuzz_target!(|data: &[u8]| {
    let mut parser = StreamParser::new();
    let mut rest = data;
    while let Some((&n, r)) = rest.split_first() {
        let (chunk, r) = r.split_at(usize::from(n).min(r.len()));
        rest = r;
        parser.push(chunk);
        for msg in parser.by_ref() {
            if matches!(msg, Message::Frame { .. } | Message::Send(_)) {
                let text = msg.format();
                let inner = text.trim_start_matches('<').trim_end_matches('>');
                assert_eq!(Message::parse(inner).as_ref(), Ok(&msg), "{text}");
            }
        }
        assert!(parser.buffered() <= MAX_MESSAGE + 256);
    }
});
