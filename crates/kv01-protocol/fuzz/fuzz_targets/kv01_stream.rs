//! The stream decoder fed arbitrary chunks: the first byte picks direction and mode, the
//! following bytes alternate (chunk length, chunk). It must never panic, every frame must
//! re-encode, and after a flush every byte is either in a frame or counted as garbage.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_kv01_protocol::{CrcMode, Direction, MessageScanner, StreamDecoder, StreamEvent};

fuzz_target!(|data: &[u8]| {
    let Some((&sel, mut rest)) = data.split_first() else {
        return;
    };
    let dir = match sel % 3 {
        0 => Direction::ToModule,
        1 => Direction::FromModule,
        _ => Direction::Auto,
    };
    let mode = if sel & 0x80 != 0 { CrcMode::Lenient } else { CrcMode::Strict };
    let mut dec = StreamDecoder::new(MessageScanner::new(dir, mode));
    let mut frame_bytes = 0usize;
    let mut total = 0usize;
    let mut count = |ev: StreamEvent| {
        if let StreamEvent::Frame(d) = ev {
            // A frame accepted with a bad CRC re-encodes to the same length.
            frame_bytes += d.message.encode().expect("decoded frames re-encode").len();
        }
    };
    while let Some((&n, r)) = rest.split_first() {
        let (chunk, r) = r.split_at(usize::from(n).min(r.len()));
        rest = r;
        total += chunk.len();
        dec.push(chunk);
        dec.by_ref().for_each(&mut count);
    }
    dec.flush();
    dec.by_ref().for_each(&mut count);
    assert_eq!(dec.pending(), 0);
    assert_eq!(dec.stats().garbage_bytes as usize + frame_bytes, total);
});
