//! The JSON form used by `motus decode kv01` / `motus encode kv01`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use motus_kv01_protocol::*;

fn decode_json(bytes: &[u8], dir: Direction, mode: CrcMode) -> String {
    serde_json::to_string(&decode_message(bytes, dir, mode).unwrap()).unwrap()
}

fn encode_json(json: &str) -> Vec<u8> {
    let msg: Message = serde_json::from_str(json).unwrap();
    encode_message(&msg).unwrap()
}

#[test]
fn documented_examples() {
    // Vectors from tests/vectors.rs (CRCs by tests/crc_reference.py).
    let en = [0xE2, 0x07, 0xD0, 0x45, 0x4E, 0xFB, 0xF0];
    let json = decode_json(&en, Direction::ToModule, CrcMode::Strict);
    assert_eq!(json, r#"{"direction":"to_module","address":226,"command":"d0","text":"EN"}"#);
    assert_eq!(encode_json(&json), en);

    let d3 = [0xE4, 0x08, 0xD3, 0x12, 0x34, 0x3A, 0x91, 0xF0];
    let json = decode_json(&d3, Direction::FromModule, CrcMode::Strict);
    assert_eq!(
        json,
        r#"{"direction":"from_module","address":228,"command":"d3","position":37556,"brake_released":true,"limit_switch":false,"lsstop":true,"restricted_mode":false}"#
    );
    assert_eq!(encode_json(&json), d3);

    let ok = [0xE2, 0x07, 0xD0, 0x4F, 0x4B, 0xB5, 0xF0];
    let json = decode_json(&ok, Direction::Auto, CrcMode::Lenient);
    assert_eq!(
        json,
        r#"{"direction":"from_module","address":226,"command":"d0","answer":"OK","crc_mismatch":{"expected":35,"received":181}}"#
    );
    // encode accepts decode's output (and computes the right CRC).
    assert_eq!(encode_json(&json), [0xE2, 0x07, 0xD0, 0x4F, 0x4B, 0x23, 0xF0]);
}

#[test]
fn every_kind_prints_and_reads_back() {
    let cases: &[(&[u8], Direction, &str)] = &[
        (
            &[0xE2, 0x06, 0xD1, 0xB1, 0x6F, 0xF0],
            Direction::ToModule,
            r#""command":"d1","action":"release_brake""#,
        ),
        (
            &[0xE1, 0x06, 0xD1, 0x77, 0xF1, 0xF0],
            Direction::ToModule,
            r#""command":"d1","action":"unknown","byte":119"#,
        ),
        (&[0xE4, 0x05, 0xD3, 0x13, 0xF0], Direction::ToModule, r#""command":"d3""#),
        (
            &[0xE6, 0x06, 0xD5, 0x31, 0xD6, 0xF0],
            Direction::ToModule,
            r#""command":"d5","speed":17,"opening":true"#,
        ),
        (
            &[0xE2, 0x06, 0xD1, 0x08, 0xC1, 0xF0],
            Direction::FromModule,
            r#""command":"d1","brake_released":true"#,
        ),
        (
            &[0xE6, 0x06, 0xD1, 0x05, 0x32, 0xF0],
            Direction::FromModule,
            r#""command":"d1_gripper","current_limit":true"#,
        ),
        (
            &[0xE5, 0x0B, 0xD4, 0x03, 0x6B, 0x02, 0xFA, 0x03, 0x94, 0x51, 0xF0],
            Direction::FromModule,
            r#""command":"d4","raw_24v":875,"raw_5v":762,"raw_12v":916,"volts_24v":23.97705078125"#,
        ),
        (&[0xE6, 0x06, 0xD5, 0x27, 0x96, 0xF0], Direction::FromModule, r#""command":"d5","load":9"#),
        (
            &[0xE3, 0x08, 0xD2, 0x7F, 0x00, 0x25, 0xE4, 0xF0],
            Direction::FromModule,
            r#""command":"d2","position":65280"#,
        ),
        (&[0xE2, b'U', b'C', 0xF0], Direction::FromModule, r#""command":"short","text":"UC""#),
        (
            &[0xE2, 0x0C, 0xD0, 0x54, 0x49, 0x4D, 0x45, 0x4F, 0x55, 0x54, 0x05, 0xF0],
            Direction::FromModule,
            r#""answer":"TIMEOUT""#,
        ),
    ];
    for (bytes, dir, part) in cases {
        let json = decode_json(bytes, *dir, CrcMode::Strict);
        assert!(json.contains(part), "{json} lacks {part}");
        assert_eq!(&encode_json(&json), bytes, "{json}");
    }
}

#[test]
fn hand_written_json() {
    let bytes = encode_json(r#"{"direction":"to_module","address":227,"command":"d2","text":"V-100"}"#);
    assert_eq!(bytes, [0xE3, 0x0A, 0xD2, 0x56, 0x2D, 0x31, 0x30, 0x30, 0x95, 0xF0]);
    // volts are output only; raw counts are what is encoded.
    let bytes = encode_json(
        r#"{"direction":"from_module","address":229,"command":"d4","raw_24v":875,"raw_5v":762,"raw_12v":916}"#,
    );
    assert_eq!(bytes, [0xE5, 0x0B, 0xD4, 0x03, 0x6B, 0x02, 0xFA, 0x03, 0x94, 0x51, 0xF0]);
    let bad: Result<Message, _> =
        serde_json::from_str(r#"{"direction":"to_module","address":1,"command":"d3"}"#);
    assert!(bad.is_err());
    let bad: Result<Message, _> =
        serde_json::from_str(r#"{"direction":"from_module","address":226,"command":"short","text":"U"}"#);
    assert!(bad.is_err());
}
