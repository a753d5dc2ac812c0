//! The JSON form used by `motus decode nfv2` / `motus encode nfv2`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use motus_nfv2_protocol::{decode_frame, encode_frame, CommandCode, Frame, Revision};

/// Frames from tests/vectors.rs (CRC by the independent Python script).
const FRAMES: &[&[u8]] = &[
    &[0x23, 0x06, 0xF9, 0x01, 0x1A, 0x00, 0x20],
    &[0x23, 0x0E, 0xF1, 0x01, 0x1A, 0x04, 0x82, 0xEC, 0xFF, 0xFF, 0x1F, 0x02, 0x10, 0x00, 0xA8],
    &[0x23, 0x0C, 0xF3, 0x02, 0x60, 0x03, 0xAA, 0xBB, 0xCC, 0x10, 0x01, 0x04, 0xC0],
    &[0x23, 0x0E, 0xF1, 0x02, 0x42, 0x08, 0x64, 0x00, 0x05, 0x00, 0x14, 0x00, 0xE8, 0x03, 0xA0],
    &[0x23, 0x04, 0xFB, 0x05, 0x08],
];

#[test]
fn decode_json_encode_is_identity() {
    for bytes in FRAMES {
        let frame = decode_frame(bytes, Revision::LATEST).unwrap();
        let json = serde_json::to_string_pretty(&frame).unwrap();
        let back: Frame = serde_json::from_str(&json).unwrap();
        assert_eq!(back, frame);
        assert_eq!(&encode_frame(&back, Revision::LATEST).unwrap(), bytes);
    }
}

#[test]
fn documented_examples() {
    let answer = decode_frame(FRAMES[1], Revision::LATEST).unwrap();
    assert_eq!(
        serde_json::to_string(&answer).unwrap(),
        r#"{"address":1,"commands":[{"kind":"values","code":"read_drives_position","values":[-4990]},{"kind":"values","code":"read_drives_status","values":[16]}]}"#
    );
    let unknown = decode_frame(FRAMES[2], Revision::LATEST).unwrap();
    assert_eq!(
        serde_json::to_string(&unknown).unwrap(),
        r#"{"address":2,"commands":[{"kind":"unknown","code":96,"raw":[170,187,204]},{"kind":"values","code":"set_drives_mode","values":[4]}]}"#
    );
    let reg = decode_frame(FRAMES[3], Revision::LATEST).unwrap();
    assert_eq!(
        serde_json::to_string(&reg).unwrap(),
        r#"{"address":2,"commands":[{"kind":"regulators","code":"set_position_regulator","values":[{"p":100,"i":5,"d":20,"t":1000}]}]}"#
    );
}

#[test]
fn codes_accept_names_numbers_and_hex() {
    let by_number: CommandCode = serde_json::from_str("26").unwrap();
    let by_hex: CommandCode = serde_json::from_str(r#""0x1a""#).unwrap();
    let by_name: CommandCode = serde_json::from_str(r#""read_drives_position""#).unwrap();
    assert_eq!(by_number, CommandCode::ReadDrivesPosition);
    assert_eq!(by_hex, CommandCode::ReadDrivesPosition);
    assert_eq!(by_name, CommandCode::ReadDrivesPosition);
    assert_eq!(serde_json::from_str::<CommandCode>("96").unwrap(), CommandCode::Unknown(0x60));
    assert_eq!(serde_json::to_string(&CommandCode::Unknown(0x60)).unwrap(), "96");
    assert!(serde_json::from_str::<CommandCode>("256").is_err());
    assert!(serde_json::from_str::<CommandCode>(r#""no_such_command""#).is_err());
}

#[test]
fn hand_written_json_encodes() {
    let json = r#"{"address":1,"commands":[
        {"kind":"values","code":"set_drives_position","values":[-5000]},
        {"kind":"query","code":"read_drives_position"},
        {"kind":"query","code":31}]}"#;
    let frame: Frame = serde_json::from_str(json).unwrap();
    assert_eq!(
        encode_frame(&frame, Revision::LATEST).unwrap(),
        [0x23, 0x0E, 0xF1, 0x01, 0x13, 0x04, 0x78, 0xEC, 0xFF, 0xFF, 0x1A, 0x00, 0x1F, 0x00, 0xF0]
    );
}

#[test]
fn typos_are_rejected() {
    // A misspelt field must not silently encode something else.
    let bad = [
        r#"{"address":1,"commands":[{"kind":"query","code":"read_drives_position","values":[1]}]}"#,
        r#"{"address":1,"commands":[{"kind":"values","code":"set_drives_position","value":[1]}]}"#,
        r#"{"adress":1,"commands":[]}"#,
        r#"{"address":1,"commands":[{"kind":"set","code":"set_drives_position","values":[1]}]}"#,
        r#"{"address":256,"commands":[]}"#,
    ];
    for json in bad {
        assert!(serde_json::from_str::<Frame>(json).is_err(), "{json}");
    }
}
