//! Fuzz the streaming decoder: arbitrary bytes in arbitrary chunks (the first byte picks
//! the chunk size); it never panics, every byte is accounted for, and each frame it
//! returns re-encodes to bytes the single-frame decoder accepts.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_nfv2_protocol::{decode_frame, FrameScanner, Revision, StreamDecoder};

fuzz_target!(|data: &[u8]| {
    let Some((&size, bytes)) = data.split_first() else {
        return;
    };
    let size = usize::from(size).max(1);
    let rev = Revision::LATEST;
    let mut decoder = StreamDecoder::new(FrameScanner::new(rev));
    for chunk in bytes.chunks(size) {
        decoder.push(chunk);
        while let Some(frame) = decoder.next_frame() {
            let encoded = frame.encode(rev);
            assert!(encoded.is_ok(), "decoded frame does not encode: {frame:?}");
            if let Ok(encoded) = encoded {
                assert_eq!(decode_frame(&encoded, rev).as_ref(), Ok(&frame));
            }
        }
        let s = decoder.stats();
        assert_eq!(s.bytes_in, s.garbage_bytes + s.frame_bytes + decoder.pending() as u64);
        assert!(decoder.pending() < 256);
    }
});
