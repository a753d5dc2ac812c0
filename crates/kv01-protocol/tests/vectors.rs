//! Test vectors. Every CRC byte below was computed by `tests/crc_reference.py`, an
//! independent Python transcription of the published C pseudo-code (seed 003, ch. 2.11:
//! variables A, B, C, divide by 2, `| 0x80`, then 0xF0 -> 0xF1), run once with python3; its
//! output is pasted here. The data bytes were worked out by hand from `specs/kv01.md`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use motus_kv01_protocol::faulhaber::{self, ControllerError};
use motus_kv01_protocol::*;

fn a(n: u8) -> Address {
    Address::joint(n).unwrap()
}

fn req(addr: u8, command: Command) -> Message {
    Message::request(a(addr), command)
}

fn rep(addr: u8, body: ReplyBody) -> Message {
    Message::reply(a(addr), body)
}

fn text(s: &str) -> Command {
    Command::Faulhaber { text: s.into() }
}

/// (frame, message) pairs; the frame is checked both ways with an explicit direction.
fn vectors() -> Vec<(Vec<u8>, Message)> {
    let released = JointStatus { brake_released: true, ..JointStatus::default() };
    vec![
        // E2 = joint 2, 07 = 7 bytes, D0, "EN", CRC FB, END.
        (vec![0xE2, 0x07, 0xD0, 0x45, 0x4E, 0xFB, 0xF0], req(2, text("EN"))),
        // Reply "OK" to it.
        (
            vec![0xE2, 0x07, 0xD0, 0x4F, 0x4B, 0x23, 0xF0],
            rep(2, ReplyBody::Faulhaber { answer: Answer::Controller(faulhaber::Reply::Ok) }),
        ),
        // D1 0xB1 = release brake.
        (vec![0xE2, 0x06, 0xD1, 0xB1, 0x6F, 0xF0], req(2, Command::BrakeLimit(D1Action::ReleaseBrake))),
        // D1 reply 0x08 = bit 3, brake released.
        (vec![0xE2, 0x06, 0xD1, 0x08, 0xC1, 0xF0], rep(2, ReplyBody::Status(released))),
        // Joint 1, D0 "V320".
        (vec![0xE1, 0x09, 0xD0, 0x56, 0x33, 0x32, 0x30, 0xA3, 0xF0], req(1, text("V320"))),
        // Joint 3, D2 "V-100".
        (
            vec![0xE3, 0x0A, 0xD2, 0x56, 0x2D, 0x31, 0x30, 0x30, 0x95, 0xF0],
            req(3, Command::Fast { text: "V-100".into() }),
        ),
        // D3 / D4 requests carry no data.
        (vec![0xE4, 0x05, 0xD3, 0x13, 0xF0], req(4, Command::ReadResolver)),
        (vec![0xE5, 0x05, 0xD4, 0x3B, 0xF0], req(5, Command::ReadVoltages)),
        // D5 0x31 = opening (bit 5) at speed 17.
        (vec![0xE6, 0x06, 0xD5, 0x31, 0xD6, 0xF0], req(6, Command::Gripper { speed: 17, opening: true })),
        // D3 reply 12 34 3A: position 0x92B4, brake released + LSSTOP (see status.rs).
        (
            vec![0xE4, 0x08, 0xD3, 0x12, 0x34, 0x3A, 0x91, 0xF0],
            rep(
                4,
                ReplyBody::Resolver(ResolverReading {
                    position: 0x92B4,
                    status: JointStatus { brake_released: true, lsstop: true, ..JointStatus::default() },
                }),
            ),
        ),
        // D2 reply 7F 00 25: ResH = 0xFF (b5), ResL = 0x00, limit switch + restricted mode.
        (
            vec![0xE3, 0x08, 0xD2, 0x7F, 0x00, 0x25, 0xE4, 0xF0],
            rep(
                3,
                ReplyBody::FastResolver(ResolverReading {
                    position: 0xFF00,
                    status: JointStatus {
                        limit_switch: true,
                        restricted_mode: true,
                        ..JointStatus::default()
                    },
                }),
            ),
        ),
        // D4 reply: 24 V = 0x036B, 5 V = 0x02FA, 12 V = 0x0394.
        (
            vec![0xE5, 0x0B, 0xD4, 0x03, 0x6B, 0x02, 0xFA, 0x03, 0x94, 0x51, 0xF0],
            rep(5, ReplyBody::Voltages(Voltages { raw_24v: 0x036B, raw_5v: 0x02FA, raw_12v: 0x0394 })),
        ),
        // D4 reply whose data holds 0xF0 (24V_L): delimited by LENGTH, not by 0xF0.
        (
            vec![0xE5, 0x0B, 0xD4, 0x03, 0xF0, 0x02, 0xFA, 0x03, 0x94, 0x96, 0xF0],
            rep(5, ReplyBody::Voltages(Voltages { raw_24v: 0x03F0, raw_5v: 0x02FA, raw_12v: 0x0394 })),
        ),
        // "TIMEOUT" from the module.
        (
            vec![0xE2, 0x0C, 0xD0, 0x54, 0x49, 0x4D, 0x45, 0x4F, 0x55, 0x54, 0x05, 0xF0],
            rep(2, ReplyBody::Faulhaber { answer: Answer::Timeout }),
        ),
        (
            vec![0xE2, 0x0B, 0xD0, 0x4C, 0x49, 0x4D, 0x56, 0x41, 0x4C, 0x70, 0xF0],
            rep(2, ReplyBody::Faulhaber { answer: Answer::LimVal }),
        ),
        // D5 reply 0x27: load 9, PHASE (opening), BRAKE (released).
        (
            vec![0xE6, 0x06, 0xD5, 0x27, 0x96, 0xF0],
            rep(6, ReplyBody::Gripper(GripperLoad { load: 9, opening: true, brake_released: true })),
        ),
        // Gripper D1 reply 0x05: LIMIT + BRAKE.
        (
            vec![0xE6, 0x06, 0xD1, 0x05, 0x32, 0xF0],
            rep(
                6,
                ReplyBody::GripperStatus(GripperStatus {
                    current_limit: true,
                    opening: false,
                    brake_released: true,
                }),
            ),
        ),
        // D0 without data (the module answers "UC").
        (vec![0xE2, 0x05, 0xD0, 0x20, 0xF0], req(2, text(""))),
        // D1 with an unknown byte 0x77: raw CRC 0xF0, sent as 0xF1.
        (
            vec![0xE1, 0x06, 0xD1, 0x77, 0xF1, 0xF0],
            req(1, Command::BrakeLimit(D1Action::Unknown { byte: 0x77 })),
        ),
        // Short messages.
        (vec![0xE2, b'U', b'C', 0xF0], rep(2, ReplyBody::Short { text: ShortCode::UnknownCommand })),
        (vec![0xE3, b'T', b'O', 0xF0], rep(3, ReplyBody::Short { text: ShortCode::Timeout })),
        (vec![0xE4, b'X', b'Y', 0xF0], rep(4, ReplyBody::Short { text: ShortCode::Other(*b"XY") })),
    ]
}

#[test]
fn encode_and_decode_vectors() {
    for (bytes, msg) in vectors() {
        assert_eq!(encode_message(&msg).unwrap(), bytes, "{msg:?}");
        let mut buf = [0u8; 8];
        if bytes.len() > 8 {
            assert!(matches!(msg.encode_into(&mut buf), Err(EncodeError::BufferTooSmall { .. })));
        }
        let d = decode_message(&bytes, msg.direction(), CrcMode::Strict).unwrap();
        assert_eq!(d.message, msg);
        assert_eq!(d.crc_mismatch, None);
        // Auto guesses right on all of these but the D5 reply (a byte with bits 6-7 clear
        // also reads as a D5 request; host -> module wins).
        let auto = decode_message(&bytes, Direction::Auto, CrcMode::Strict).unwrap();
        if bytes[2] != 0xD5 || msg.direction() == Direction::ToModule {
            assert_eq!(auto.message, msg, "auto");
        }
    }
}

/// The source's four example messages (kv01.md), with the CRC this procedure expects.
const SOURCE_EXAMPLES: [(&[u8], Direction, u8, u8); 4] = [
    (&[0xE2, 0x07, 0xD0, 0x45, 0x4E, 0x20, 0xF0], Direction::ToModule, 0xFB, 0x20),
    (&[0xE2, 0x07, 0xD0, 0x4F, 0x4B, 0xB5, 0xF0], Direction::FromModule, 0x23, 0xB5),
    (&[0xE2, 0x06, 0xD1, 0xB1, 0x50, 0xF0], Direction::ToModule, 0x6F, 0x50),
    (&[0xE2, 0x06, 0xD1, 0x08, 0xE0, 0xF0], Direction::FromModule, 0xC1, 0xE0),
];

#[test]
fn source_examples_rejected_in_strict_mode() {
    for (bytes, dir, expected, received) in SOURCE_EXAMPLES {
        for d in [dir, Direction::Auto] {
            let err = decode_message(bytes, d, CrcMode::Strict).unwrap_err();
            assert_eq!(err, DecodeError::Crc { expected, received });
            let text = err.to_string();
            assert!(
                text.contains(&format!("{expected:#04x}")) && text.contains(&format!("{received:#04x}")),
                "{text}"
            );
        }
    }
}

#[test]
fn source_examples_accepted_with_warning_in_lenient_mode() {
    let want = [
        req(2, text("EN")),
        rep(2, ReplyBody::Faulhaber { answer: Answer::Controller(faulhaber::Reply::Ok) }),
        req(2, Command::BrakeLimit(D1Action::ReleaseBrake)),
        rep(2, ReplyBody::Status(JointStatus { brake_released: true, ..JointStatus::default() })),
    ];
    for ((bytes, dir, expected, received), want) in SOURCE_EXAMPLES.into_iter().zip(want) {
        for d in [dir, Direction::Auto] {
            let got = decode_message(bytes, d, CrcMode::Lenient).unwrap();
            assert_eq!(got.message, want);
            assert_eq!(got.crc_mismatch, Some(CrcMismatch { expected, received }));
        }
    }
    // The stream decoder: strict counts four CRC failures, lenient four accepted mismatches.
    let all: Vec<u8> = SOURCE_EXAMPLES.iter().flat_map(|e| e.0.iter().copied()).collect();
    let mut strict = StreamDecoder::new(MessageScanner::new(Direction::Auto, CrcMode::Strict));
    strict.push(&all);
    strict.flush();
    assert_eq!(strict.next_frame(), None);
    assert_eq!(strict.stats().corrupt_frames, 4);
    assert_eq!(strict.stats().frames, 0);
    let mut lenient = StreamDecoder::new(MessageScanner::new(Direction::Auto, CrcMode::Lenient));
    lenient.push(&all);
    let got: Vec<_> = std::iter::from_fn(|| lenient.next_frame()).collect();
    assert_eq!(got.len(), 4);
    assert_eq!(got.iter().filter(|d| d.crc_mismatch.is_some()).count(), 4);
    assert_eq!(lenient.stats().garbage_bytes, 0);
}

#[test]
fn encoder_refuses_f0_in_host_data() {
    // "V" 0xF0 "1": the 0xF0 is data byte 2, frame offset 4.
    let m = req(2, text("V\u{f0}1"));
    assert_eq!(encode_message(&m), Err(EncodeError::EndInData { offset: 4 }));
    assert!(encode_message(&m).unwrap_err().to_string().contains("offset 4"));
    let m = req(2, Command::Other { code: 0xF0, data: vec![] });
    assert_eq!(encode_message(&m), Err(EncodeError::EndInData { offset: 2 }));
    let m = req(2, Command::BrakeLimit(D1Action::Unknown { byte: 0xF0 }));
    assert_eq!(encode_message(&m), Err(EncodeError::EndInData { offset: 3 }));
    // Replies may carry 0xF0 in data (D4 above); text must be Latin-1.
    let m = req(2, text("V\u{2013}1"));
    assert_eq!(encode_message(&m), Err(EncodeError::NotLatin1 { ch: '\u{2013}', offset: 4 }));
    let m = req(6, Command::Gripper { speed: 32, opening: false });
    assert!(matches!(encode_message(&m), Err(EncodeError::OutOfRange { .. })));
    let m = req(2, text(&"A".repeat(251)));
    assert_eq!(encode_message(&m), Err(EncodeError::TooLong { len: 256 }));
    assert_eq!(encode_message(&req(2, text(&"A".repeat(250)))).map(|v| v.len()), Ok(255));
    // 235 data bytes make a 240-byte message: LENGTH would be 0xF0 (offset 1).
    assert_eq!(encode_message(&req(2, text(&"A".repeat(235)))), Err(EncodeError::EndInData { offset: 1 }));
    let long_reply = rep(2, ReplyBody::Faulhaber { answer: Answer::parse(&"A".repeat(235)) });
    let bytes = encode_message(&long_reply).unwrap();
    assert_eq!(bytes[1], 0xF0);
    assert_eq!(decode_message(&bytes, Direction::Auto, CrcMode::Strict).unwrap().message, long_reply);
    // D1 status kinds must match the address.
    let m = rep(6, ReplyBody::Status(JointStatus::default()));
    assert!(matches!(encode_message(&m), Err(EncodeError::StatusAddress { .. })));
    let m = rep(1, ReplyBody::GripperStatus(GripperStatus::default()));
    assert!(matches!(encode_message(&m), Err(EncodeError::StatusAddress { .. })));
    let m = rep(1, ReplyBody::Short { text: ShortCode::Other(*b"a1") });
    assert!(matches!(encode_message(&m), Err(EncodeError::ShortCode(_))));
}

#[test]
fn decode_errors() {
    let s = CrcMode::Strict;
    let to = Direction::ToModule;
    assert_eq!(decode_message(&[], to, s), Err(DecodeError::TooShort { received: 0 }));
    assert_eq!(decode_message(&[0xE0, 5, 0xD3, 0, 0xF0], to, s), Err(DecodeError::Address(0xE0)));
    assert_eq!(decode_message(&[0xE4, 4, 0xD3, 0xF0], to, s), Err(DecodeError::LengthField(4)));
    assert_eq!(
        decode_message(&[0xE4, 0x06, 0xD3, 0x13, 0xF0], Direction::FromModule, s),
        Err(DecodeError::Length { expected: 6, received: 5 })
    );
    // To a module, the 0xF0 at offset 4 (the CRC position of a 6-byte message) is refused.
    assert_eq!(
        decode_message(&[0xE4, 0x06, 0xD3, 0x13, 0xF0], to, s),
        Err(DecodeError::EndInBody { offset: 4 })
    );
    assert_eq!(
        decode_message(&[0xE4, 0x05, 0xD3, 0x13, 0xF0, 0], to, s),
        Err(DecodeError::Length { expected: 5, received: 6 })
    );
    assert_eq!(
        decode_message(&[0xE4, 0x05, 0xD3, 0x13, 0xF1], to, s),
        Err(DecodeError::End { received: 0xF1 })
    );
    assert_eq!(decode_message(&[0xE2, b'U', b'C', 0xF0], to, s), Err(DecodeError::ShortToModule));
    // 0xF0 inside a host message: refused even in lenient mode.
    assert_eq!(
        decode_message(&[0xE2, 0x06, 0xD1, 0xF0, 0x00, 0xF0], to, CrcMode::Lenient),
        Err(DecodeError::EndInBody { offset: 3 })
    );
}

#[test]
fn shapes_that_do_not_fit_are_kept_raw() {
    // D3 reply with a reserved bit (bit 6 of byte 3) set: kept as "other".
    let m = rep(4, ReplyBody::Other { code: 0xD3, data: vec![0x12, 0x34, 0x40] });
    let bytes = encode_message(&m).unwrap();
    assert_eq!(decode_message(&bytes, Direction::FromModule, CrcMode::Strict).unwrap().message, m);
    // D1 joint status with a bit above 3.
    let m = rep(2, ReplyBody::Other { code: 0xD1, data: vec![0x10] });
    let bytes = encode_message(&m).unwrap();
    assert_eq!(decode_message(&bytes, Direction::FromModule, CrcMode::Strict).unwrap().message, m);
    // A raw reply that would read back as a short message.
    let m = rep(2, ReplyBody::Other { code: b'A', data: [0xF0].repeat(60) });
    assert_eq!(encode_message(&m), Err(EncodeError::LooksShort));
}

#[test]
fn typed_faulhaber_inside_d0() {
    let r = faulhaber::Request::parse("3 v -250").unwrap();
    let m = req(2, Command::d0(&r));
    assert_eq!(m, req(2, text("3V-250")));
    let Message::Request(Request { command, .. }) = &m else { panic!() };
    assert_eq!(command.faulhaber_request(), Some(Ok(r)));
    let answer = Answer::parse("Invalid parameter");
    assert_eq!(answer, Answer::Controller(faulhaber::Reply::Error(ControllerError::InvalidParameter)));
    assert_eq!(Answer::parse("LSSTOP"), Answer::LsStop);
}
