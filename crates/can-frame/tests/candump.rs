//! The candump notation (as written by can-utils' `candump -L` and read by `cansend`), the
//! frame's JSON form, its construction limits, and never-panic checks on arbitrary text.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use motus_can_frame::{CanFrame, FrameError, ParseError, MAX_EXTENDED_ID, MAX_STANDARD_ID};
use proptest::prelude::*;

#[test]
fn candump_notation() {
    let f: CanFrame = "601#4064600000000000".parse().unwrap();
    assert_eq!(f.id(), 0x601);
    assert_eq!(f.data(), &[0x40, 0x64, 0x60, 0, 0, 0, 0, 0]);
    assert_eq!(f.dlc(), 8);
    let r: CanFrame = "701#R".parse().unwrap();
    assert!(r.is_remote());
    assert!(r.data().is_empty());
    assert_eq!(r.to_string(), "701#R");
    let r3: CanFrame = "701#R3".parse().unwrap();
    assert_eq!((r3.dlc(), r3.to_string().as_str()), (3, "701#R3"));
    let e: CanFrame = "12345678#00.11".parse().unwrap();
    assert!(e.is_extended());
    assert_eq!(e.to_string(), "12345678#0011");
    assert_eq!("080#".parse::<CanFrame>().unwrap().data(), &[] as &[u8]);
}

#[test]
fn candump_errors() {
    let err = |s: &str| s.parse::<CanFrame>().unwrap_err();
    assert_eq!(err("601#4064600000000000FF"), ParseError::Frame(FrameError::TooLong { len: 9 }));
    assert_eq!(err("801#00"), ParseError::Frame(FrameError::IdOutOfRange { id: 0x801, extended: false }));
    assert_eq!(err("601#4"), ParseError::BadData("4".into())); // odd digit count
    assert_eq!(err("6010"), ParseError::MissingSeparator);
    assert_eq!(err("601##0"), ParseError::CanFd);
    assert_eq!(err("6011#00"), ParseError::BadId("6011".into())); // 4 digits: neither 11 nor 29 bits
    assert_eq!(err("701#R9"), ParseError::BadData("R9".into()));
}

#[test]
fn construction_limits() {
    assert!(CanFrame::new(MAX_STANDARD_ID, &[0; 8]).is_ok());
    assert_eq!(
        CanFrame::new(MAX_STANDARD_ID + 1, &[]),
        Err(FrameError::IdOutOfRange { id: 0x800, extended: false })
    );
    assert!(CanFrame::with_format(MAX_EXTENDED_ID, true, &[]).is_ok());
    assert!(CanFrame::with_format(MAX_EXTENDED_ID + 1, true, &[]).is_err());
    assert_eq!(CanFrame::new(1, &[0; 9]), Err(FrameError::TooLong { len: 9 }));
    assert_eq!(CanFrame::remote(1, false, 9), Err(FrameError::TooLong { len: 9 }));
}

#[test]
fn json_form() {
    let f: CanFrame = "583#43646000E8030000".parse().unwrap();
    let json = serde_json::to_string(&f).unwrap();
    assert_eq!(json, r#"{"id":1411,"extended":false,"rtr":false,"data":[67,100,96,0,232,3,0,0]}"#);
    assert_eq!(serde_json::from_str::<CanFrame>(&json).unwrap(), f);
    let r: CanFrame = serde_json::from_str(r#"{"id":1793,"rtr":true,"dlc":1}"#).unwrap();
    assert_eq!(r.to_string(), "701#R1");
    // an invalid frame is refused, not built
    assert!(serde_json::from_str::<CanFrame>(r#"{"id":2048,"data":[]}"#).is_err());
}

fn frame_strategy() -> impl Strategy<Value = CanFrame> {
    prop_oneof![
        (0u32..=MAX_STANDARD_ID, proptest::collection::vec(any::<u8>(), 0..=8))
            .prop_map(|(id, d)| CanFrame::new(id, &d).unwrap()),
        (0u32..=MAX_EXTENDED_ID, proptest::collection::vec(any::<u8>(), 0..=8))
            .prop_map(|(id, d)| CanFrame::with_format(id, true, &d).unwrap()),
        (0u32..=MAX_EXTENDED_ID, any::<bool>(), 0u8..=8).prop_map(|(id, ext, dlc)| CanFrame::remote(
            id & if ext { MAX_EXTENDED_ID } else { MAX_STANDARD_ID },
            ext,
            dlc
        )
        .unwrap()),
    ]
}

proptest! {
    #[test]
    fn candump_and_json_round_trip(frame in frame_strategy()) {
        prop_assert_eq!(frame.to_string().parse::<CanFrame>().unwrap(), frame.clone());
        let json = serde_json::to_string(&frame).unwrap();
        prop_assert_eq!(serde_json::from_str::<CanFrame>(&json).unwrap(), frame);
    }

    #[test]
    fn candump_parse_never_panics(s in "\\PC{0,40}") {
        let _ = s.parse::<CanFrame>();
    }

    #[test]
    fn candump_like_never_panics(s in "[0-9A-Fa-f]{0,9}#[0-9A-Fa-fRr.#]{0,20}") {
        let _ = s.parse::<CanFrame>();
    }
}
