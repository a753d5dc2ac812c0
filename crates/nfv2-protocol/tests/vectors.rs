//! Fixed test vectors.
//!
//! Every frame below was computed once by an independent Python script (run with
//! python3, not part of the build) that builds `'#', n, !n, address, body, crc` and
//! implements the CRC from the published description literally: polynomial 0xD8,
//! bit by bit, MSB first, init 0, no reflection, no final XOR, over bytes 3..n-1.
//! Its output is pasted here; byte meanings are commented.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use motus_nfv2_protocol::{
    decode_frame, encode_frame, Command, CommandCode as C, DecodeError, Frame, Regulator, Revision,
};

const LATEST: Revision = Revision::LATEST;

fn check(bytes: &[u8], rev: Revision, expected: &Frame) {
    assert_eq!(&decode_frame(bytes, rev).unwrap(), expected);
    assert_eq!(encode_frame(expected, rev).unwrap(), bytes);
}

#[test]
fn single_query() {
    // 23 '#', 06 n (7 bytes), F9 !n, 01 address, 1A ReadDrivesPosition, 00 k = 0 (query),
    // 20 CRC.
    let bytes = [0x23, 0x06, 0xF9, 0x01, 0x1A, 0x00, 0x20];
    let mut f = Frame::new(1);
    f.commands.push(Command::query(C::ReadDrivesPosition));
    check(&bytes, LATEST, &f);
}

#[test]
fn answer_to_the_query() {
    // 23, 0A n, F5 !n, 01 address, 1A ReadDrivesPosition, 04 k, E8 03 00 00 = 1000 (LE),
    // 70 CRC.
    let bytes = [0x23, 0x0A, 0xF5, 0x01, 0x1A, 0x04, 0xE8, 0x03, 0x00, 0x00, 0x70];
    let mut f = Frame::new(1);
    f.commands.push(Command::values(C::ReadDrivesPosition, [1000]));
    check(&bytes, LATEST, &f);
}

#[test]
fn packed_pan_tilt_request_and_answer() {
    // Request: 23, 0E n, F1 !n, 01 address,
    //   13 SetDrivesPosition, 04 k, 78 EC FF FF = -5000,
    //   1A ReadDrivesPosition, 00 (query), 1F ReadDrivesStatus, 00 (query), F0 CRC.
    let request = [0x23, 0x0E, 0xF1, 0x01, 0x13, 0x04, 0x78, 0xEC, 0xFF, 0xFF, 0x1A, 0x00, 0x1F, 0x00, 0xF0];
    let f = Frame {
        address: 1,
        commands: vec![
            Command::values(C::SetDrivesPosition, [-5000]),
            Command::query(C::ReadDrivesPosition),
            Command::query(C::ReadDrivesStatus),
        ],
    };
    check(&request, LATEST, &f);
    assert_eq!(f.queries().collect::<Vec<_>>(), [C::ReadDrivesPosition, C::ReadDrivesStatus]);

    // Answer: 23, 0E, F1, 01 address, 1A, 04, 82 EC FF FF = -4990, 1F ReadDrivesStatus,
    //   02 k, 10 00 = 0x0010 (synchronized), A8 CRC.
    let answer = [0x23, 0x0E, 0xF1, 0x01, 0x1A, 0x04, 0x82, 0xEC, 0xFF, 0xFF, 0x1F, 0x02, 0x10, 0x00, 0xA8];
    let a = Frame {
        address: 1,
        commands: vec![
            Command::values(C::ReadDrivesPosition, [-4990]),
            Command::values(C::ReadDrivesStatus, [0x0010]),
        ],
    };
    check(&answer, LATEST, &a);
}

#[test]
fn unknown_command_is_skipped_by_length_and_kept() {
    // 23, 0C n, F3 !n, 02 address,
    //   60 unknown code, 03 k, AA BB CC (skipped, kept raw),
    //   10 SetDrivesMode, 01 k, 04 POSITION, C0 CRC.
    let bytes = [0x23, 0x0C, 0xF3, 0x02, 0x60, 0x03, 0xAA, 0xBB, 0xCC, 0x10, 0x01, 0x04, 0xC0];
    let f = Frame {
        address: 2,
        commands: vec![
            Command::Unknown { code: 0x60, raw: vec![0xAA, 0xBB, 0xCC] },
            Command::values(C::SetDrivesMode, [4]),
        ],
    };
    for rev in Revision::ALL {
        check(&bytes, rev, &f);
    }
}

#[test]
fn revision_changes_the_speed_width() {
    // 23, 08, F7, 01, 11 SetDrivesSpeed, 02 k, 9C FF = -100 as i16, 08 CRC.
    let rev2012 = [0x23, 0x08, 0xF7, 0x01, 0x11, 0x02, 0x9C, 0xFF, 0x08];
    // 23, 0A, F5, 01, 11 SetDrivesSpeed, 04 k, 9C FF FF FF = -100 as i32, 58 CRC.
    let rev2014 = [0x23, 0x0A, 0xF5, 0x01, 0x11, 0x04, 0x9C, 0xFF, 0xFF, 0xFF, 0x58];
    let mut f = Frame::new(1);
    f.commands.push(Command::values(C::SetDrivesSpeed, [-100]));
    check(&rev2012, Revision::Rev2012, &f);
    check(&rev2014, Revision::Rev2013, &f);
    check(&rev2014, Revision::Rev2014, &f);

    // The same bytes read with the wrong revision: a 2-byte frame is a cut value for a
    // 4-byte table...
    assert!(matches!(
        decode_frame(&rev2012, Revision::Rev2014),
        Err(DecodeError::TruncatedValue { code: C::SetDrivesSpeed, len: 2, width: 4, .. })
    ));
    // ...and a 4-byte one is two values for a 2-byte table (-100 = 9C FF, then FF FF = -1).
    let two = decode_frame(&rev2014, Revision::Rev2012).unwrap();
    assert_eq!(two.int_values(C::SetDrivesSpeed), Some(&[-100, -1][..]));
}

#[test]
fn command_unknown_to_an_old_revision_is_skipped() {
    // ReadDrivesSpeed (0x1C) does not exist before 2013: an old decoder keeps it raw.
    let mut f = Frame::new(1);
    f.commands.push(Command::values(C::ReadDrivesSpeed, [-2]));
    let bytes = encode_frame(&f, Revision::Rev2014).unwrap();
    let old = decode_frame(&bytes, Revision::Rev2012).unwrap();
    assert_eq!(old.commands, [Command::Unknown { code: 0x1C, raw: vec![0xFE, 0xFF, 0xFF, 0xFF] }]);
    // Re-encoding the raw form reproduces the frame.
    assert_eq!(encode_frame(&old, Revision::Rev2012).unwrap(), bytes);
}

#[test]
fn several_values_per_command() {
    // 23, 0E, F1, 01, 11 SetDrivesSpeed, 08 k, 2C 01 00 00 = 300, D4 FE FF FF = -300,
    // A0 CRC.
    let bytes = [0x23, 0x0E, 0xF1, 0x01, 0x11, 0x08, 0x2C, 0x01, 0x00, 0x00, 0xD4, 0xFE, 0xFF, 0xFF, 0xA0];
    let mut f = Frame::new(1);
    f.commands.push(Command::values(C::SetDrivesSpeed, [300, -300]));
    check(&bytes, LATEST, &f);
    // A one-drive slave uses the first value only.
    assert_eq!(f.commands[0].for_device(1), Command::values(C::SetDrivesSpeed, [300]));

    // Vitals answer of a 1209A (4 values): 23, 0E, F1, 01, 03 ReadDeviceVitals, 08 k,
    // 60 09 = 2400, B0 04 = 1200, F4 01 = 500, 4A 01 = 330, 68 CRC.
    let vitals = [0x23, 0x0E, 0xF1, 0x01, 0x03, 0x08, 0x60, 0x09, 0xB0, 0x04, 0xF4, 0x01, 0x4A, 0x01, 0x68];
    let mut v = Frame::new(1);
    v.commands.push(Command::values(C::ReadDeviceVitals, [2400, 1200, 500, 330]));
    check(&vitals, LATEST, &v);
}

#[test]
fn regulator_settings() {
    // 23, 0E, F1, 02, 42 SetPositionRegulator, 08 k,
    //   64 00 P = 100, 05 00 I = 5, 14 00 D = 20, E8 03 T = 1000, A0 CRC.
    let bytes = [0x23, 0x0E, 0xF1, 0x02, 0x42, 0x08, 0x64, 0x00, 0x05, 0x00, 0x14, 0x00, 0xE8, 0x03, 0xA0];
    let mut f = Frame::new(2);
    f.commands
        .push(Command::regulators(C::SetPositionRegulator, [Regulator { p: 100, i: 5, d: 20, t: 1000 }]));
    check(&bytes, LATEST, &f);
}

#[test]
fn empty_frame() {
    // 23, 04 n (smallest accepted), FB !n, 05 address, 08 CRC.
    check(&[0x23, 0x04, 0xFB, 0x05, 0x08], LATEST, &Frame::new(5));
}

#[test]
fn body_errors_after_a_good_crc() {
    // Build bodies by hand and let the encoder-independent path compute the CRC.
    fn with_crc(address: u8, body: &[u8]) -> Vec<u8> {
        let n = u8::try_from(4 + body.len()).unwrap();
        let mut v = vec![0x23, n, !n, address];
        v.extend_from_slice(body);
        v.push(motus_nfv2_protocol::crc::crc8_bitwise(&v[3..]));
        v
    }
    // A lone code byte at the end: no k.
    assert_eq!(
        decode_frame(&with_crc(1, &[0x1A, 0x00, 0x1F]), LATEST),
        Err(DecodeError::MissingLength { offset: 6, code: 0x1F })
    );
    // k runs past the end: decoding stops with an error.
    assert_eq!(
        decode_frame(&with_crc(1, &[0x60, 0x05, 0x01]), LATEST),
        Err(DecodeError::CommandOverrun { offset: 4, code: 0x60, len: 5, available: 1 })
    );
    // k not a multiple of the width.
    assert_eq!(
        decode_frame(&with_crc(1, &[0x13, 0x03, 1, 2, 3]), LATEST),
        Err(DecodeError::TruncatedValue { code: C::SetDrivesPosition, len: 3, width: 4, revision: LATEST })
    );
}

#[test]
fn error_messages_name_the_problem() {
    let e = DecodeError::Crc { expected: 0x20, received: 0x21 };
    assert_eq!(e.to_string(), "CRC mismatch: computed 0x20, frame carries 0x21");
    let e = DecodeError::Length { n: 6, complement: 0xF8 };
    assert_eq!(e.to_string(), "length byte n = 0x06 does not match its complement 0xf8 (expected 0xf9)");
    let e = DecodeError::TruncatedValue { code: C::SetDrivesSpeed, len: 2, width: 4, revision: LATEST };
    assert_eq!(
        e.to_string(),
        "truncated value for set_drives_speed (0x11): 2 parameter bytes is not a multiple of the 4-byte value (rev2014)"
    );
}
