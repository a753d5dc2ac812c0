//! Streaming decoder behaviour on hand-made byte sequences (frames from tests/vectors.rs,
//! CRCs by tests/crc_reference.py).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use motus_kv01_protocol::*;

/// "OK" reply from joint 2 and a D3 reply from joint 4.
const OK: [u8; 7] = [0xE2, 0x07, 0xD0, 0x4F, 0x4B, 0x23, 0xF0];
const D3: [u8; 8] = [0xE4, 0x08, 0xD3, 0x12, 0x34, 0x3A, 0x91, 0xF0];
const UC: [u8; 4] = [0xE2, b'U', b'C', 0xF0];

fn events(dec: &mut StreamDecoder) -> Vec<StreamEvent> {
    dec.by_ref().collect()
}

fn is_frame(e: &StreamEvent) -> bool {
    matches!(e, StreamEvent::Frame(_))
}

#[test]
fn byte_by_byte() {
    let mut dec = StreamDecoder::new(MessageScanner::replies(CrcMode::Strict));
    let mut frames = 0;
    for b in OK.iter().chain(&UC).chain(&D3) {
        dec.push(&[*b]);
        frames += events(&mut dec).iter().filter(|e| is_frame(e)).count();
    }
    assert_eq!(frames, 3);
    assert_eq!(dec.stats().frames, 3);
    assert_eq!(dec.pending(), 0);
}

#[test]
fn garbage_is_reported_before_the_next_frame() {
    let mut dec = StreamDecoder::new(MessageScanner::replies(CrcMode::Strict));
    dec.push(&[0x00, 0x11, 0xF0]);
    dec.push(&OK);
    let ev = events(&mut dec);
    assert_eq!(ev.len(), 2);
    assert_eq!(ev[0], StreamEvent::Garbage { bytes: 3 });
    assert!(is_frame(&ev[1]));
    assert_eq!(dec.stats().garbage_bytes, 3);
}

#[test]
fn long_length_garbage_waits_until_flush() {
    // E2 FF looks like the start of a 255-byte message.
    let mut dec = StreamDecoder::new(MessageScanner::replies(CrcMode::Strict));
    dec.push(&[0xE2, 0xFF]);
    dec.push(&D3);
    assert_eq!(events(&mut dec), vec![]);
    assert_eq!(dec.pending(), 10);
    dec.flush();
    let ev = events(&mut dec);
    assert_eq!(ev[0], StreamEvent::Garbage { bytes: 2 });
    assert!(is_frame(&ev[1]));
    assert_eq!(dec.pending(), 0);
}

#[test]
fn partial_frame_is_dropped_by_flush_only() {
    let mut dec = StreamDecoder::new(MessageScanner::replies(CrcMode::Strict));
    dec.push(&D3[..5]);
    assert_eq!(events(&mut dec), vec![]);
    dec.push(&D3[5..]);
    assert_eq!(events(&mut dec).len(), 1);
    dec.push(&D3[..5]);
    dec.flush();
    assert_eq!(events(&mut dec), vec![StreamEvent::Garbage { bytes: 5 }]);
}

#[test]
fn crc_failure_is_counted_and_resynchronised() {
    let mut bad = OK;
    bad[3] = b'X'; // "XK": the CRC 0x23 no longer fits.
    let mut dec = StreamDecoder::new(MessageScanner::replies(CrcMode::Strict));
    dec.push(&bad);
    dec.push(&D3);
    let ev = events(&mut dec);
    assert!(
        matches!(ev[0], StreamEvent::Corrupt(CrcFailure { address: 0xE2, mismatch }) if mismatch.received == 0x23)
    );
    assert_eq!(ev[1], StreamEvent::Garbage { bytes: 7 });
    assert!(is_frame(&ev[2]));
    assert_eq!(dec.stats().corrupt_frames, 1);
    // Lenient: accepted, with the mismatch reported.
    let mut dec = StreamDecoder::new(MessageScanner::replies(CrcMode::Lenient));
    dec.push(&bad);
    let d = dec.next_frame().unwrap();
    assert_eq!(d.crc_mismatch.map(|m| m.received), Some(0x23));
    assert_eq!((dec.stats().frames, dec.stats().corrupt_frames), (1, 0));
}

#[test]
fn request_stream_rejects_f0_early_and_ignores_short_form() {
    // E2 06 D1 F0 ..: 0xF0 at offset 3 of a host message, dropped before LENGTH bytes came.
    let mut dec = StreamDecoder::new(MessageScanner::requests(CrcMode::Strict));
    dec.push(&[0xE2, 0x06, 0xD1, 0xF0]);
    dec.push(&UC);
    dec.push(&[0xE2, 0x07, 0xD0, 0x45, 0x4E, 0xFB, 0xF0]);
    let frames: Vec<_> = std::iter::from_fn(|| dec.next_frame()).collect();
    assert_eq!(frames.len(), 1);
    assert_eq!(
        frames[0].message,
        Message::request(Address::joint(2).unwrap(), Command::Faulhaber { text: "EN".into() })
    );
    assert_eq!(dec.stats().garbage_bytes, 8);
}

#[test]
fn the_reply_scanner_finds_one_reply_at_the_start_of_a_buffer() {
    use motus_wire::{Scan, Scanner};
    let strict = MessageScanner::replies(CrcMode::Strict);
    assert!(matches!(strict.scan(&UC), Scan::Frame { len: 4, .. }));
    assert_eq!(strict.scan(&[0x00, 0xE2]), Scan::Skip);
    assert_eq!(strict.scan(&UC[..2]), Scan::Incomplete);
    // The source's example reply fails the published CRC: corrupt in strict mode.
    let example = [0xE2, 0x07, 0xD0, 0x4F, 0x4B, 0xB5, 0xF0];
    assert!(matches!(strict.scan(&example), Scan::Corrupt(CrcFailure { address: 0xE2, .. })));
    assert!(matches!(MessageScanner::replies(CrcMode::Lenient).scan(&example), Scan::Frame { len: 7, .. }));
}
