//! The socketcand codec against the exact strings of specs/can-transports.md and
//! python-can 4.6.1's socketcand.py (`convert_can_message_to_ascii_message` writes
//! `< send {id:03X|08X} {dlc:X} {" ".join(f"{x:x}")} >`).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_can::socketcand::{CodecError, Message, StreamParser};
use motus_can::CanFrame;
use proptest::prelude::*;
use std::time::Duration;

fn f(id: u32, data: &[u8]) -> CanFrame {
    CanFrame::new(id, data).unwrap()
}

#[test]
fn server_frames_match_the_spec() {
    // Spec: `< frame 123 1.000000 4300100092010200 >`, %02X bytes without spaces.
    let m = Message::Frame {
        frame: f(0x123, &[0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00]),
        timestamp: Duration::from_secs(1),
    };
    assert_eq!(m.format(), "< frame 123 1.000000 4300100092010200 >");
    // Zero-length frame: two spaces before `>`.
    let sync = Message::Frame { frame: f(0x080, &[]), timestamp: Duration::from_secs(1) };
    assert_eq!(sync.format(), "< frame 080 1.000000  >");
    // Extended: 8 upper-case digits; microseconds zero-padded to 6.
    let ext = Message::Frame {
        frame: CanFrame::with_format(0x1ABC_DEF0, true, &[0xAB]).unwrap(),
        timestamp: Duration::new(1_436_509_052, 249_713_000),
    };
    assert_eq!(ext.format(), "< frame 1ABCDEF0 1436509052.249713 AB >");
    // Standard id below 0x100 keeps 3 digits.
    let low = Message::Frame { frame: f(0x00A, &[1]), timestamp: Duration::from_micros(5) };
    assert_eq!(low.format(), "< frame 00A 0.000005 01 >");
}

#[test]
fn client_sends_match_python_can() {
    // Spec / python-can: lower-case unpadded bytes.
    assert_eq!(
        Message::Send(f(0x605, &[0x40, 0, 0x10, 0, 0, 0, 0, 0])).format(),
        "< send 605 8 40 0 10 0 0 0 0 0 >"
    );
    assert_eq!(Message::Send(f(0x080, &[])).format(), "< send 080 0  >");
    assert_eq!(Message::Send(CanFrame::remote(0x701, false, 1).unwrap()).format(), "< send 701 1  >");
    let ext = CanFrame::with_format(0x0000_0123, true, &[0xFF, 0x0A]).unwrap();
    assert_eq!(Message::Send(ext).format(), "< send 00000123 2 ff a >");
}

#[test]
fn parses_what_python_can_writes() {
    assert_eq!(
        Message::parse(" send 605 8 40 0 10 0 0 0 0 0 ").unwrap(),
        Message::Send(f(0x605, &[0x40, 0, 0x10, 0, 0, 0, 0, 0]))
    );
    assert_eq!(Message::parse(" send 080 0  ").unwrap(), Message::Send(f(0x080, &[])));
    // RTR request: DLC > 0 and no data bytes.
    assert_eq!(
        Message::parse(" send 701 1  ").unwrap(),
        Message::Send(CanFrame::remote(0x701, false, 1).unwrap())
    );
    let ext = Message::parse(" send 00000123 2 ff a ").unwrap();
    assert_eq!(ext, Message::Send(CanFrame::with_format(0x123, true, &[0xFF, 0x0A]).unwrap()));
    assert_eq!(Message::parse(" open can0 ").unwrap(), Message::Open("can0".into()));
    assert_eq!(Message::parse(" rawmode ").unwrap(), Message::Rawmode);
    assert_eq!(Message::parse(" hi ").unwrap(), Message::Hi);
    assert_eq!(Message::parse(" ok ").unwrap(), Message::Ok);
    assert_eq!(Message::parse(" echo ").unwrap(), Message::Echo);
    assert_eq!(Message::parse(" error 1 ").unwrap(), Message::Error("1".into()));
    assert_eq!(Message::parse(" bcmmode ").unwrap(), Message::Unknown("bcmmode".into()));
}

#[test]
fn parses_frames_from_a_real_daemon() {
    let m = Message::parse(" frame 123 1436509052.249713 4300100092010200 ").unwrap();
    assert_eq!(
        m,
        Message::Frame {
            frame: f(0x123, &[0x43, 0, 0x10, 0, 0x92, 1, 2, 0]),
            timestamp: Duration::new(1_436_509_052, 249_713_000)
        }
    );
    let sync = Message::parse(" frame 080 1.000000  ").unwrap();
    assert_eq!(sync, Message::Frame { frame: f(0x080, &[]), timestamp: Duration::from_secs(1) });
}

#[test]
fn rejects_malformed_arguments() {
    assert_eq!(
        Message::parse(" send 605 2 40 ").unwrap_err(),
        CodecError::LengthMismatch { dlc: 2, bytes: 1 }
    );
    assert_eq!(Message::parse(" send 605 9 ").unwrap_err(), CodecError::BadDlc("9".into()));
    assert_eq!(Message::parse(" send 80O 0 ").unwrap_err(), CodecError::BadId("80O".into()));
    assert_eq!(
        Message::parse(" send 800 0 ").unwrap_err(),
        CodecError::BadId("800".into()),
        "0x800 is not an 11-bit id"
    );
    assert_eq!(Message::parse(" send 605 1 100 ").unwrap_err(), CodecError::BadData("100".into()));
    assert_eq!(Message::parse(" frame 123 x 00 ").unwrap_err(), CodecError::BadTimestamp("x".into()));
    assert_eq!(Message::parse(" frame 123 1.0 ABC ").unwrap_err(), CodecError::BadData("ABC".into()));
    assert_eq!(Message::parse_lenient(" send 605 "), Message::Unknown("send 605".into()));
}

#[test]
fn stream_parser_splits_glued_messages_and_resynchronises() {
    let mut p = StreamParser::new();
    p.push(b"< hi >< ok >garbage< frame 080 1.000000  >>< send 6");
    assert_eq!(p.next(), Some(Message::Hi));
    assert_eq!(p.next(), Some(Message::Ok));
    assert_eq!(p.next(), Some(Message::Frame { frame: f(0x080, &[]), timestamp: Duration::from_secs(1) }));
    assert_eq!(p.next(), None);
    // "garbage" (7) + the stray ">" (1).
    assert_eq!(p.garbage_bytes(), 8);
    p.push(b"05 1 ff >");
    assert_eq!(p.next(), Some(Message::Send(f(0x605, &[0xFF]))));
    // A message cut by a new `<` is dropped: only the second one counts.
    p.push(b"< send 605 <echo>");
    assert_eq!(p.next(), Some(Message::Echo));
    assert_eq!(p.next(), None);
    assert_eq!(p.buffered(), 0);
}

#[test]
fn stream_parser_buffer_is_bounded() {
    let mut p = StreamParser::new();
    let long = vec![b'a'; 10 * motus_can::socketcand::codec::MAX_MESSAGE];
    p.push(b"<");
    p.push(&long);
    assert!(p.buffered() <= motus_can::socketcand::codec::MAX_MESSAGE, "{}", p.buffered());
    p.push(b">< ok >");
    assert_eq!(p.next(), Some(Message::Ok));
}

fn arb_frame() -> impl Strategy<Value = CanFrame> {
    (any::<bool>(), any::<u32>(), proptest::collection::vec(any::<u8>(), 0..=8)).prop_map(
        |(ext, id, data)| {
            let id = if ext { id & 0x1FFF_FFFF } else { id & 0x7FF };
            CanFrame::with_format(id, ext, &data).unwrap()
        },
    )
}

proptest! {
    #[test]
    fn send_round_trips(frame in arb_frame()) {
        let text = Message::Send(frame.clone()).format();
        let mut p = StreamParser::new();
        p.push(text.as_bytes());
        let m = p.next();
        prop_assert_eq!(m, Some(Message::Send(frame)));
    }

    #[test]
    fn frame_round_trips(frame in arb_frame(), secs in 0u64..4_000_000_000, micros in 0u32..1_000_000) {
        let timestamp = Duration::new(secs, micros * 1000);
        let text = Message::Frame { frame: frame.clone(), timestamp }.format();
        prop_assert!(text.ends_with(" >"));
        let mut p = StreamParser::new();
        // Split anywhere: the parser must reassemble.
        let cut = text.len() / 2;
        p.push(&text.as_bytes()[..cut]);
        p.push(&text.as_bytes()[cut..]);
        prop_assert_eq!(p.next(), Some(Message::Frame { frame, timestamp }));
    }

    #[test]
    fn parser_never_panics(chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..64), 0..16)) {
        let mut p = StreamParser::new();
        for c in &chunks {
            p.push(c);
            for _ in p.by_ref() {}
            prop_assert!(p.buffered() <= motus_can::socketcand::codec::MAX_MESSAGE + 64);
        }
    }
}

proptest! {
    /// The parser's iterator (which parses in place) yields exactly what its text API
    /// followed by the lenient parse yields, and counts the same garbage.
    #[test]
    fn iterator_equals_text_then_parse(chunks in proptest::collection::vec(
        proptest::collection::vec(prop_oneof![Just(b'<'), Just(b'>'), Just(b' '), any::<u8>(),
            Just(b's'), Just(b'f'), Just(b'1')], 0..48), 0..12)) {
        let (mut fast, mut slow) = (StreamParser::new(), StreamParser::new());
        for chunk in &chunks {
            fast.push(chunk);
            slow.push(chunk);
            let a: Vec<Message> = fast.by_ref().collect();
            let b: Vec<Message> = std::iter::from_fn(|| slow.next_text()).map(|t| Message::parse_lenient(&t)).collect();
            prop_assert_eq!(a, b);
            prop_assert_eq!(fast.garbage_bytes(), slow.garbage_bytes());
            prop_assert_eq!(fast.buffered(), slow.buffered());
        }
    }

    /// Hexadecimal bytes are written as `{:02X}` (frames) and `{:x}` (sends) would.
    #[test]
    fn hex_matches_core_fmt(frame in arb_frame()) {
        let send = Message::Send(frame.clone()).format();
        let mut want = String::from("< send ");
        want.push_str(&if frame.is_extended() { format!("{:08X}", frame.id()) } else { format!("{:03X}", frame.id()) });
        want.push_str(&format!(" {:X} ", frame.dlc()));
        for b in frame.data() {
            want.push_str(&format!("{b:x} "));
        }
        if frame.data().is_empty() {
            want.push(' ');
        }
        want.push('>');
        prop_assert_eq!(send, want);
        let text = Message::Frame { frame: frame.clone(), timestamp: std::time::Duration::ZERO }.format();
        let hex: String = frame.data().iter().map(|b| format!("{b:02X}")).collect();
        prop_assert!(text.ends_with(&format!(" 0.000000 {hex} >")), "{}", text);
    }
}
