//! Property tests: round trips for every message type, the 0xF0 rule, and decoders that never
//! panic and always resynchronise.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use motus_kv01_protocol::faulhaber::{self, Query};
use motus_kv01_protocol::*;
use proptest::prelude::*;

fn address() -> impl Strategy<Value = Address> {
    (1u8..=6).prop_map(|j| Address::joint(j).unwrap())
}

fn joint_address() -> impl Strategy<Value = Address> {
    (1u8..=5).prop_map(|j| Address::joint(j).unwrap())
}

/// Latin-1 text without 0xF0 (host data), up to `max` characters.
fn host_text(max: usize) -> impl Strategy<Value = String> {
    proptest::collection::vec(any::<u8>().prop_filter("no END", |b| *b != END), 0..=max)
        .prop_map(|v| v.into_iter().map(char::from).collect())
}

fn any_text(max: usize) -> impl Strategy<Value = String> {
    proptest::collection::vec(any::<u8>(), 0..=max).prop_map(|v| v.into_iter().map(char::from).collect())
}

fn other_code() -> impl Strategy<Value = u8> {
    any::<u8>().prop_filter("not a known code nor END", |c| !(0xD0..=0xD5).contains(c) && *c != END)
}

fn command() -> impl Strategy<Value = Command> {
    prop_oneof![
        host_text(250).prop_map(|text| Command::Faulhaber { text }),
        any::<u8>()
            .prop_filter("no END", |b| *b != END)
            .prop_map(|b| Command::BrakeLimit(D1Action::from_byte(b))),
        host_text(250).prop_map(|text| Command::Fast { text }),
        Just(Command::ReadResolver),
        Just(Command::ReadVoltages),
        (0u8..=31, any::<bool>()).prop_map(|(speed, opening)| Command::Gripper { speed, opening }),
        (other_code(), proptest::collection::vec(any::<u8>().prop_filter("no END", |b| *b != END), 0..20))
            .prop_map(|(code, data)| Command::Other { code, data }),
    ]
}

fn joint_status() -> impl Strategy<Value = JointStatus> {
    (0u8..16).prop_map(JointStatus::from_bits)
}

fn resolver() -> impl Strategy<Value = ResolverReading> {
    (any::<u16>(), joint_status()).prop_map(|(position, status)| ResolverReading { position, status })
}

fn reply() -> impl Strategy<Value = Reply> {
    prop_oneof![
        (address(), any_text(250))
            .prop_map(|(a, t)| Reply::new(a, ReplyBody::Faulhaber { answer: Answer::parse(&t) })),
        (address(), any::<i64>()).prop_map(|(a, v)| Reply::new(
            a,
            ReplyBody::Faulhaber { answer: Answer::Controller(faulhaber::Reply::Value(v)) }
        )),
        (joint_address(), joint_status()).prop_map(|(a, s)| Reply::new(a, ReplyBody::Status(s))),
        (0u8..8).prop_map(|b| Reply::new(
            Address::GRIPPER,
            ReplyBody::GripperStatus(GripperStatus::from_byte(b).unwrap())
        )),
        (address(), resolver()).prop_map(|(a, r)| Reply::new(a, ReplyBody::FastResolver(r))),
        (address(), resolver()).prop_map(|(a, r)| Reply::new(a, ReplyBody::Resolver(r))),
        (address(), any::<[u8; 6]>())
            .prop_map(|(a, b)| Reply::new(a, ReplyBody::Voltages(Voltages::from_bytes(b)))),
        (address(), 0u8..128)
            .prop_map(|(a, b)| Reply::new(a, ReplyBody::Gripper(GripperLoad::from_byte(b).unwrap()))),
        (address(), b'A'..=b'Z', b'A'..=b'Z').prop_map(|(a, x, y)| Reply::new(
            a,
            ReplyBody::Short { text: ShortCode::from_bytes([x, y]).unwrap() }
        )),
        (address(), other_code(), proptest::collection::vec(any::<u8>(), 0..20))
            .prop_map(|(a, code, data)| Reply::new(a, ReplyBody::Other { code, data })),
    ]
}

fn message() -> impl Strategy<Value = Message> {
    prop_oneof![
        (address(), command()).prop_map(|(a, c)| Message::request(a, c)),
        reply().prop_map(Message::Reply),
    ]
}

/// A valid message and its bytes (skipping the rare raw reply the encoder refuses).
fn frame() -> impl Strategy<Value = (Message, Vec<u8>)> {
    message().prop_filter_map("encodable", |m| m.encode().ok().map(|b| (m, b)))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn round_trip(m in message()) {
        let bytes = match m.encode() {
            Ok(b) => b,
            Err(EncodeError::LooksShort) => return Ok(()),
            // A 240-byte host message would have LENGTH = 0xF0: refused, rightly.
            Err(EncodeError::EndInData { offset: 1 }) => return Ok(()),
            Err(e) => panic!("{e}"),
        };
        let mut buf = [0u8; MAX_FRAME_LEN];
        let n = m.encode_into(&mut buf).unwrap();
        prop_assert_eq!(&buf[..n], &bytes[..]);
        for mode in [CrcMode::Strict, CrcMode::Lenient] {
            let d = decode_message(&bytes, m.direction(), mode).unwrap();
            prop_assert_eq!(&d.message, &m);
            prop_assert_eq!(d.crc_mismatch, None);
        }
        // JSON: decode's output is accepted by encode and gives the same bytes.
        let json = serde_json::to_string(&decode_message(&bytes, m.direction(), CrcMode::Strict).unwrap()).unwrap();
        let back: Message = serde_json::from_str(&json).unwrap();
        prop_assert_eq!(back.encode().unwrap(), bytes);
    }

    #[test]
    fn f0_only_as_end(m in message()) {
        if let Ok(bytes) = m.encode() {
            prop_assert_eq!(bytes.last(), Some(&END));
            if bytes.len() > 4 {
                prop_assert_ne!(bytes[bytes.len() - 2], END, "CRC position");
            }
            if m.direction() == Direction::ToModule {
                prop_assert!(!bytes[..bytes.len() - 1].contains(&END));
            }
        }
    }

    #[test]
    fn host_text_with_f0_is_refused(a in address(), t in any_text(40)) {
        let m = Message::request(a, Command::Faulhaber { text: t.clone() });
        match (m.encode(), t.chars().position(|c| c == '\u{f0}')) {
            (Ok(bytes), None) => prop_assert!(!bytes[..bytes.len() - 1].contains(&END)),
            (Err(EncodeError::EndInData { offset }), Some(i)) => prop_assert_eq!(offset, 3 + i),
            (r, i) => panic!("{r:?} {i:?}"),
        }
    }

    #[test]
    fn decoder_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
        for dir in [Direction::ToModule, Direction::FromModule, Direction::Auto] {
            for mode in [CrcMode::Strict, CrcMode::Lenient] {
                if let Ok(d) = decode_message(&bytes, dir, mode) {
                    // Every accepted frame re-encodes to itself (CRC aside in lenient mode).
                    if d.crc_mismatch.is_none() {
                        if let Ok(again) = d.message.encode() {
                            prop_assert_eq!(again, bytes.clone());
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn stream_finds_every_frame_in_garbage(
        parts in proptest::collection::vec(
            (proptest::collection::vec(any::<u8>(), 0..40), frame()), 1..8),
        tail in proptest::collection::vec(any::<u8>(), 0..40),
        cuts in proptest::collection::vec(1usize..50, 1..40),
    ) {
        // Replies and requests are mixed, so decode with Auto and compare bytes.
        let mut all = Vec::new();
        let mut want = Vec::new();
        for (garbage, (_, bytes)) in &parts {
            all.extend_from_slice(garbage);
            all.extend_from_slice(bytes);
            want.push(bytes.clone());
        }
        all.extend_from_slice(&tail);
        let mut dec = StreamDecoder::new(MessageScanner::new(Direction::Auto, CrcMode::Strict));
        let mut got = Vec::new();
        let mut rest = &all[..];
        for c in cuts.iter().cycle() {
            if rest.is_empty() { break; }
            let (chunk, r) = rest.split_at((*c).min(rest.len()));
            rest = r;
            dec.push(chunk);
            while let Some(ev) = dec.next_event() {
                if let StreamEvent::Frame(d) = ev { got.push(d.message.encode().unwrap()); }
            }
        }
        dec.flush();
        while let Some(ev) = dec.next_event() {
            if let StreamEvent::Frame(d) = ev { got.push(d.message.encode().unwrap()); }
        }
        prop_assert_eq!(dec.pending(), 0);
        // Garbage may contain chance frames (an 8-bit CRC and no unique start byte make
        // that a 1-in-256 event per candidate), and a chance frame that starts in the
        // garbage may be long (module replies are length-delimited and may carry 0xF0)
        // and swallow the real frames after it. So: the real frames are found in order,
        // and the bytes of the missing ones fit inside the chance frames.
        let mut it = got.iter();
        let mut missing_bytes = 0usize;
        for w in &want {
            let mut probe = it.clone();
            if probe.any(|g| g == w) {
                it = probe;
            } else {
                missing_bytes += w.len();
            }
        }
        let chance_bytes: usize = got.iter().filter(|g| !want.contains(g)).map(Vec::len).sum();
        prop_assert!(
            missing_bytes <= chance_bytes,
            "{} bytes of real frames missing, only {} bytes of chance frames; want {:02X?} got {:02X?}",
            missing_bytes, chance_bytes, want, got
        );
        let s = dec.stats();
        let frame_bytes: usize = got.iter().map(Vec::len).sum();
        prop_assert_eq!(s.garbage_bytes as usize + frame_bytes, all.len());
    }

    #[test]
    fn lenient_stream_exact_without_address_bytes_in_garbage(
        parts in proptest::collection::vec(
            (proptest::collection::vec(0u8..0xE0, 0..20), reply()), 1..6),
        chunk in 1usize..16,
    ) {
        let mut all = Vec::new();
        let mut want = Vec::new();
        for (garbage, r) in &parts {
            let m = Message::Reply(r.clone());
            let Ok(bytes) = m.encode() else { continue };
            all.extend_from_slice(garbage);
            all.extend_from_slice(&bytes);
            want.push(m);
        }
        let mut dec = StreamDecoder::new(MessageScanner::replies(CrcMode::Lenient));
        let mut got = Vec::new();
        for c in all.chunks(chunk) {
            dec.push(c);
            while let Some(d) = dec.next_frame() { got.push(d.message); }
        }
        prop_assert_eq!(got, want);
    }

    #[test]
    fn request_stream_round_trip(
        msgs in proptest::collection::vec((address(), command()), 1..6),
        noise in proptest::collection::vec(any::<u8>(), 0..30),
    ) {
        let mut all = noise.clone();
        let mut want = Vec::new();
        for (a, c) in msgs {
            let m = Message::request(a, c);
            let Ok(bytes) = m.encode() else { continue };
            all.extend_from_slice(&bytes);
            want.push(m);
        }
        let mut dec = StreamDecoder::new(MessageScanner::requests(CrcMode::Strict));
        dec.push(&all);
        dec.flush();
        let got: Vec<Message> = std::iter::from_fn(|| dec.next_frame()).map(|d| d.message).collect();
        let mut it = got.iter();
        for w in &want {
            prop_assert!(it.any(|g| g == w));
        }
    }

    #[test]
    fn stream_never_panics(
        chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..64), 0..20),
        lenient in any::<bool>(),
        dir in 0u8..3,
    ) {
        let dir = [Direction::ToModule, Direction::FromModule, Direction::Auto][usize::from(dir)];
        let mode = if lenient { CrcMode::Lenient } else { CrcMode::Strict };
        let mut dec = StreamDecoder::new(MessageScanner::new(dir, mode));
        for c in &chunks {
            dec.push(c);
            for _ in dec.by_ref() {}
        }
        dec.flush();
        for _ in dec.by_ref() {}
        prop_assert_eq!(dec.pending(), 0);
    }

    #[test]
    fn faulhaber_request_round_trip(r in faulhaber_request()) {
        let text = r.to_string();
        prop_assert_eq!(faulhaber::Request::parse(&text), Ok(r.clone()));
        // Spaces and lower case are ignored.
        let sloppy: String = text.chars().flat_map(|c| [c.to_ascii_lowercase(), ' ']).collect();
        prop_assert_eq!(faulhaber::Request::parse(&sloppy), Ok(r));
    }

    #[test]
    fn faulhaber_parsers_never_panic(s in "\\PC{0,30}", t in any_text(30)) {
        let _ = faulhaber::Request::parse(&s);
        let _ = faulhaber::Request::parse(&t);
        prop_assert_eq!(faulhaber::Reply::parse(&s).to_string(), s.clone());
        prop_assert_eq!(Answer::parse(&t).to_string(), t);
    }
}

fn faulhaber_request() -> impl Strategy<Value = faulhaber::Request> {
    use faulhaber::Command as C;
    let n = any::<i32>();
    let cmd = prop_oneof![
        prop_oneof![
            Just(C::Enable),
            Just(C::Disable),
            Just(C::Move),
            Just(C::NotifyPositionOff),
            Just(C::NotifyVelocityOff),
            Just(C::EnableProgram),
            Just(C::DisableProgram),
            Just(C::Resume),
            Just(C::Save),
            Just(C::EepSave),
        ],
        n.prop_map(C::Velocity),
        n.prop_map(C::LoadAbsolute),
        n.prop_map(C::LoadRelative),
        proptest::option::of(n).prop_map(C::Home),
        proptest::option::of(n).prop_map(C::NotifyPosition),
        n.prop_map(C::NotifyVelocity),
        n.prop_map(C::Voltage),
        n.prop_map(C::AnswerMode),
        n.prop_map(C::VelocitySource),
        n.prop_map(C::MaxSpeed),
        n.prop_map(C::Acceleration),
        n.prop_map(C::Deceleration),
        n.prop_map(C::PositionLimit),
        n.prop_map(C::ActivatePositionLimits),
        n.prop_map(C::PeakCurrent),
        n.prop_map(C::ContinuousCurrent),
        n.prop_map(C::Baud),
        n.prop_map(C::NodeAddress),
        n.prop_map(C::AnalogInput),
        (0..Query::ALL.len()).prop_map(|i| C::Query(Query::ALL[i].0)),
        ("[A-Z]{1,8}", proptest::option::of(any::<i64>())).prop_filter_map("unknown mnemonic", |(m, a)| {
            let s = format!("{m}{}", a.map(|a| a.to_string()).unwrap_or_default());
            match faulhaber::Request::parse(&s) {
                Ok(faulhaber::Request { command: C::Unknown(u), .. }) => Some(C::Unknown(u)),
                _ => None,
            }
        }),
    ];
    (proptest::option::of(any::<u8>()), cmd).prop_map(|(node, command)| faulhaber::Request { node, command })
}
