//! Codec tests with frames computed by hand from `specs/ps1a.md` (command table, status
//! reply table, checksum = 8-bit sum of ADR..PN with carry ignored), plus property tests.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_ps1a_protocol::*;
use proptest::prelude::*;

fn frame(addr: u8, command: Command) -> Vec<u8> {
    CommandFrame::new(addr, command).encode()
}

#[test]
fn status_request_to_module_3() {
    // ADR=03 N=00 KOD=00 CHSUM=03+00+00=03
    assert_eq!(frame(3, Command::StatusRequest), [0x03, 0x00, 0x00, 0x03]);
}

#[test]
fn move_absolute_1000() {
    // ADR=03 N=03 KOD=04, 1000 = 0x0003E8 LSB first: E8 03 00;
    // CHSUM = 03+03+04+E8+03+00 = 0xF5
    assert_eq!(
        frame(3, Command::MoveAbsolute { target: U24::new(1000).unwrap() }),
        [0x03, 0x03, 0x04, 0xE8, 0x03, 0x00, 0xF5]
    );
}

#[test]
fn move_relative_minus_1000() {
    // -1000 two's complement 24 bit = 0xFFFC18 -> 18 FC FF;
    // CHSUM = 01+03+05+18+FC+FF = 0x21C -> 0x1C
    assert_eq!(
        frame(1, Command::MoveRelative { increment: I24::new(-1000).unwrap() }),
        [0x01, 0x03, 0x05, 0x18, 0xFC, 0xFF, 0x1C]
    );
}

#[test]
fn set_speed_and_acceleration() {
    // V = 300 = 0x012C -> LV=2C HV=01, A=8; CHSUM = 02+03+03+2C+01+08 = 0x3D
    assert_eq!(
        frame(2, Command::SetSpeed { speed: 300, acceleration: Acceleration::new(8).unwrap() }),
        [0x02, 0x03, 0x03, 0x2C, 0x01, 0x08, 0x3D]
    );
}

#[test]
fn set_parameters_defaults() {
    // ADR=00 N=0B KOD=01, then ADR 00, DS 27 (39), TVZ 00, COMS 00, MXP FF FF 00,
    // VNRB 0A, ANRB 08, VNNB 05, ANNB 08.
    // CHSUM = 0B+01+27+FF+FF+0A+08+05+08 = 0x250 -> 0x50 (checked with Python sum() % 256)
    assert_eq!(
        frame(0, Command::SetParameters { parameters: Parameters::default() }),
        [0x00, 0x0B, 0x01, 0x00, 0x27, 0x00, 0x00, 0xFF, 0xFF, 0x00, 0x0A, 0x08, 0x05, 0x08, 0x50]
    );
}

#[test]
fn control_byte_power_and_reference() {
    // D0|D2 = 0x05; CHSUM = 04+01+02+05 = 0x0C
    assert_eq!(frame(4, Command::ControlByte { control: ControlByte(0x05) }), [0x04, 0x01, 0x02, 0x05, 0x0C]);
}

#[test]
fn every_parameterless_command() {
    for (cmd, code) in [
        (Command::JogPlus, 6u8),
        (Command::JogMinus, 7),
        (Command::Reset, 8),
        (Command::Stop, 9),
        (Command::Home, 10),
    ] {
        assert_eq!(frame(15, cmd), [15, 0, code, 15 + code]);
    }
}

#[test]
fn status_reply_example() {
    // Module 3, LBS = 0x21 (after reset + in motion), HBS = 0x03, position 70000 = 0x011170
    // -> 70 11 01; CSUM = 03+05+21+03+70+11+01 = 0xAE
    let bytes = [0x03, 0x05, 0x21, 0x03, 0x70, 0x11, 0x01, 0xAE];
    let r = StatusReply::decode(&bytes).unwrap();
    assert_eq!(r.addr, 3);
    assert!(r.low.has(LowStatus::AFTER_RESET | LowStatus::IN_MOTION));
    assert!(r.high.has(HighStatus::REFERENCE_SWITCH | HighStatus::ENCODER_ZERO));
    assert_eq!(r.position.get(), 70000);
    assert_eq!(r.to_bytes(), bytes);
}

#[test]
fn decoding_names_the_fault() {
    let err = CommandFrame::decode(&[0x03, 0x00, 0x00, 0x04]).unwrap_err();
    assert_eq!(err, DecodeError::Checksum { expected: 0x03, received: 0x04 });
    assert!(err.to_string().contains("expected 0x03, received 0x04"));

    assert_eq!(CommandFrame::decode(&[0x03, 0x00, 0x0B, 0x0E]).unwrap_err(), DecodeError::UnknownCode(11));
    assert!(matches!(
        CommandFrame::decode(&[0x03, 0x01, 0x00, 0x00, 0x04]).unwrap_err(),
        DecodeError::WrongParameterCount { code: 0, declared: 1, expected: 0, .. }
    ));
    assert!(matches!(
        CommandFrame::decode(&[0x03, 0x03, 0x04, 0xE8]).unwrap_err(),
        DecodeError::TooShort { .. }
    ));
    assert!(matches!(
        CommandFrame::decode(&[0x03, 0x00, 0x00, 0x03, 0x00]).unwrap_err(),
        DecodeError::TooLong { .. }
    ));
    // A = 0 is not an acceleration number. CHSUM = 02+03+03+2C+01+00 = 0x35
    assert!(matches!(
        CommandFrame::decode(&[0x02, 0x03, 0x03, 0x2C, 0x01, 0x00, 0x35]).unwrap_err(),
        DecodeError::InvalidParameter { name: "A", value: 0, .. }
    ));
    assert_eq!(StatusReply::decode(&[1, 4, 0, 0, 0, 0, 0, 5]).unwrap_err(), DecodeError::WrongReplyLength(4));
    assert_eq!(
        StatusReply::decode(&[0x03, 0x05, 0x21, 0x03, 0x70, 0x11, 0x01, 0xAF]).unwrap_err(),
        DecodeError::Checksum { expected: 0xAE, received: 0xAF }
    );
}

#[test]
fn stream_resynchronises_after_garbage() {
    let good = frame(3, Command::MoveAbsolute { target: U24::new(1000).unwrap() });
    let mut bytes = vec![0xFF, 0x42, 0x07, 0x00];
    bytes.extend_from_slice(&good);
    bytes.extend_from_slice(&[0x03, 0x00, 0x00, 0x09]); // bad checksum
    bytes.extend_from_slice(&frame(3, Command::Stop));
    let mut s = CommandStream::default();
    for chunk in bytes.chunks(3) {
        s.push(chunk);
    }
    let mut events = vec![];
    while let Some(e) = s.next_event() {
        events.push(e);
    }
    let frames: Vec<_> = events
        .iter()
        .filter_map(|e| match e {
            StreamEvent::Frame(f) => Some(f.command),
            _ => None,
        })
        .collect();
    assert_eq!(frames, vec![Command::MoveAbsolute { target: U24::new(1000).unwrap() }, Command::Stop]);
    assert!(events.contains(&StreamEvent::Corrupt(ChecksumError { addr: 3, expected: 3, received: 9 })));
}

#[test]
fn json_round_trip_and_shape() {
    let f = CommandFrame::new(3, Command::MoveAbsolute { target: U24::new(1000).unwrap() });
    let json = serde_json::to_string(&f).unwrap();
    assert_eq!(json, r#"{"addr":3,"command":"move_absolute","target":1000}"#);
    let back: CommandFrame = serde_json::from_str(&json).unwrap();
    assert_eq!(back, f);
    let r = StatusReply::decode(&[0x03, 0x05, 0x21, 0x03, 0x70, 0x11, 0x01, 0xAE]).unwrap();
    let json = serde_json::to_value(r).unwrap();
    assert_eq!(json["lbs_flags"], serde_json::json!(["after_reset", "in_motion"]));
    let back: StatusReply = serde_json::from_value(json).unwrap();
    assert_eq!(back, r);
    assert!(serde_json::from_str::<CommandFrame>(
        r#"{"addr":3,"command":"move_absolute","target":16777216}"#
    )
    .is_err());
}

fn any_command() -> impl Strategy<Value = Command> {
    let acc = (1u8..=10).prop_map(|a| Acceleration::new(a).unwrap());
    let params = (
        any::<u8>(),
        any::<u8>(),
        0u8..4,
        0u8..4,
        0u32..(1 << 24),
        any::<u8>(),
        acc.clone(),
        any::<u8>(),
        acc.clone(),
    )
        .prop_map(|(address, ds, tvz, coms, mxp, vnrb, anrb, vnnb, annb)| Parameters {
            address,
            ds,
            tvz: DdaCycle::from_code(tvz).unwrap(),
            coms: BaudRate::from_code(coms).unwrap(),
            max_position: U24::new(mxp).unwrap(),
            vnrb,
            anrb,
            vnnb,
            annb,
        });
    prop_oneof![
        Just(Command::StatusRequest),
        params.prop_map(|parameters| Command::SetParameters { parameters }),
        any::<u8>().prop_map(|b| Command::ControlByte { control: ControlByte(b) }),
        (any::<u16>(), acc).prop_map(|(speed, acceleration)| Command::SetSpeed { speed, acceleration }),
        (0u32..(1 << 24)).prop_map(|t| Command::MoveAbsolute { target: U24::new(t).unwrap() }),
        (-(1i32 << 23)..(1 << 23)).prop_map(|i| Command::MoveRelative { increment: I24::new(i).unwrap() }),
        Just(Command::JogPlus),
        Just(Command::JogMinus),
        Just(Command::Reset),
        Just(Command::Stop),
        Just(Command::Home),
    ]
}

proptest! {
    #[test]
    fn command_round_trip(addr in any::<u8>(), command in any_command()) {
        let f = CommandFrame::new(addr, command);
        let bytes = f.encode();
        prop_assert_eq!(bytes.len(), command.frame_len());
        prop_assert_eq!(CommandFrame::decode(&bytes).unwrap(), f);
        let json = serde_json::to_string(&f).unwrap();
        prop_assert_eq!(serde_json::from_str::<CommandFrame>(&json).unwrap(), f);
    }

    #[test]
    fn reply_round_trip(addr in any::<u8>(), lbs in any::<u8>(), hbs in any::<u8>(), pos in 0u32..(1 << 24)) {
        let r = StatusReply { addr, low: LowStatus(lbs), high: HighStatus(hbs), position: U24::new(pos).unwrap() };
        let bytes = r.to_bytes();
        prop_assert_eq!(StatusReply::decode(&bytes).unwrap(), r);
        let json = serde_json::to_string(&r).unwrap();
        prop_assert_eq!(serde_json::from_str::<StatusReply>(&json).unwrap(), r);
    }

    #[test]
    fn decoders_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..40)) {
        let _ = CommandFrame::decode(&bytes);
        let _ = StatusReply::decode(&bytes);
        let mut s = CommandStream::default();
        s.push(&bytes);
        while s.next_event().is_some() {}
        let mut r = ReplyStream::default();
        r.push(&bytes);
        while r.next_event().is_some() {}
    }

    #[test]
    fn reply_stream_finds_frames_in_garbage(
        garbage in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..12), 1..6),
        replies in proptest::collection::vec((any::<u8>(), any::<u8>(), 0u32..(1 << 24)), 1..6),
        chunk in 1usize..9,
    ) {
        // Garbage is chosen so that it cannot contain the byte 5 (the reply's N), which
        // would make it frame-shaped; the decoder must then find every reply.
        let mut bytes = vec![];
        let mut want = vec![];
        for (g, (addr, lbs, pos)) in garbage.iter().zip(replies.iter()) {
            bytes.extend(g.iter().map(|b| if *b == 5 { 6 } else { *b }));
            let r = StatusReply { addr: *addr, low: LowStatus(*lbs), high: HighStatus(0), position: U24::new(*pos).unwrap() };
            bytes.extend_from_slice(&r.to_bytes());
            want.push(r);
        }
        let mut s = ReplyStream::default();
        let mut got = vec![];
        for c in bytes.chunks(chunk) {
            s.push(c);
            while let Some(e) = s.next_event() {
                if let StreamEvent::Frame(f) = e { got.push(f); }
            }
        }
        // Every reply must be found, unless a chance frame swallowed it: garbage followed by
        // a reply whose first bytes look like N = 5 can form a frame whose 8-bit checksum
        // happens to be valid (1 in 256; the regression file keeps such a case). Such a
        // frame is then reported itself, so a missing reply always comes with an extra one.
        let extra = got.iter().filter(|g| !want.contains(g)).count();
        for w in &want {
            prop_assert!(got.contains(w) || extra > 0, "missing {:?} and no chance frame", w);
        }
    }
}
