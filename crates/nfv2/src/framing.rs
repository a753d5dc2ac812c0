//! Finding an NFv2 answer in received bytes for the bus master ([`motus_serial::Framing`]),
//! built on the codec's frame parser, and checking that an answer is the one expected.
//!
//! A frame starts with `'#' n !n` (not with line silence); its CRC-8 covers the address and
//! the commands. The NFv2 CRC (polynomial 0xD8, an even polynomial) misses 7 of the 255
//! possible corruptions of a single data byte, so the driver does not rely on it alone:
//! an answer is accepted only from the addressed slave, with exactly the queried codes in
//! order and the expected number of values each ([`AnswerShape`]); values then pass the
//! plausibility checks of [`crate::samples`] and the status debouncing of the drive.

use motus_nfv2_protocol::{Command, CommandCode, DeviceProfile, Frame, RawFrame, Revision, START};
use motus_serial::FrameScan;

/// Looks for one NFv2 frame at the start of `buf`, splitting its commands with `rev`.
///
/// `Skip { corrupt: true }` for a frame-shaped candidate whose CRC or commands are bad,
/// `Skip { corrupt: false }` for a byte that cannot start a frame.
#[must_use]
pub fn scan_frame(buf: &[u8], rev: Revision) -> FrameScan<Frame> {
    let Some(&[start, n, complement]) = buf.first_chunk::<3>() else {
        return match buf.first() {
            Some(&b) if b != START => FrameScan::Skip { corrupt: false },
            _ => FrameScan::Incomplete,
        };
    };
    if start != START || complement != !n || n <= 3 {
        return FrameScan::Skip { corrupt: false };
    }
    let len = usize::from(n) + 1;
    let Some(candidate) = buf.get(..len) else { return FrameScan::Incomplete };
    match RawFrame::parse(candidate).and_then(|raw| raw.decode(rev)) {
        Ok(frame) => FrameScan::Frame { frame, len },
        Err(_) => FrameScan::Skip { corrupt: true },
    }
}

/// What a valid answer to a request must look like: the slave's address and, in order,
/// each queried code the device answers with its number of values.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AnswerShape {
    /// The addressed slave.
    pub address: u8,
    /// Queried codes the device answers, with the number of values each.
    pub values: Vec<(CommandCode, usize)>,
}

impl AnswerShape {
    /// The answer `profile`'s device gives to `request`; `None` if it sends none.
    #[must_use]
    pub fn of(request: &Frame, profile: &DeviceProfile, rev: Revision) -> Option<AnswerShape> {
        let values: Vec<(CommandCode, usize)> = request
            .queries()
            .filter(|&code| rev.width(code).is_some())
            .filter_map(|code| profile.answer_count(code).map(|n| (code, n)))
            .collect();
        (!values.is_empty()).then_some(AnswerShape { address: request.address, values })
    }

    /// True if `answer` has exactly this shape.
    #[must_use]
    pub fn matches(&self, answer: &Frame) -> bool {
        answer.address == self.address
            && answer.commands.len() == self.values.len()
            && answer.commands.iter().zip(&self.values).all(|(command, &(code, count))| {
                matches!(command, Command::Values { code: c, values } if *c == code && values.len() == count)
            })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic)]
    use super::*;

    // From the codec's vectors (tests/vectors.rs of motus-nfv2-protocol, CRC by an
    // independent script): query ReadDrivesPosition to address 1.
    const QUERY: [u8; 7] = [0x23, 0x06, 0xF9, 0x01, 0x1A, 0x00, 0x20];

    #[test]
    fn finds_a_frame_after_noise_and_flags_bad_crcs() {
        let rev = Revision::LATEST;
        assert!(matches!(scan_frame(&[0x00], rev), FrameScan::Skip { corrupt: false }));
        assert!(matches!(scan_frame(&QUERY[..2], rev), FrameScan::Incomplete));
        assert!(matches!(scan_frame(&QUERY[..6], rev), FrameScan::Incomplete));
        match scan_frame(&QUERY, rev) {
            FrameScan::Frame { frame, len } => {
                assert_eq!(len, 7);
                assert_eq!(frame.address, 1);
            }
            other => panic!("{other:?}"),
        }
        let mut bad = QUERY;
        bad[6] ^= 1;
        assert!(matches!(scan_frame(&bad, rev), FrameScan::Skip { corrupt: true }));
        // '#' with a wrong complement is not a frame start.
        assert!(matches!(
            scan_frame(&[0x23, 0x06, 0xF8, 1, 2, 3, 4], rev),
            FrameScan::Skip { corrupt: false }
        ));
    }

    #[test]
    fn answer_shape_is_exact() {
        use CommandCode as C;
        let mut request = Frame::new(2);
        request.commands.push(Command::values(C::SetDrivesPosition, [10]));
        request.commands.push(Command::query(C::ReadDrivesPosition));
        request.commands.push(Command::query(C::ReadDrivesSpeed)); // not answered by a 1209A
        request.commands.push(Command::query(C::ReadDrivesStatus));
        let shape = AnswerShape::of(&request, &DeviceProfile::axis_1209a(), Revision::LATEST).unwrap();
        assert_eq!(shape.values, vec![(C::ReadDrivesPosition, 1), (C::ReadDrivesStatus, 1)]);
        let good = Frame {
            address: 2,
            commands: vec![
                Command::values(C::ReadDrivesPosition, [5]),
                Command::values(C::ReadDrivesStatus, [0]),
            ],
        };
        assert!(shape.matches(&good));
        let mut wrong_address = good.clone();
        wrong_address.address = 1;
        assert!(!shape.matches(&wrong_address));
        let mut missing = good.clone();
        missing.commands.pop();
        assert!(!shape.matches(&missing));
        let mut two_values = good;
        two_values.commands[0] = Command::values(C::ReadDrivesPosition, [5, 6]);
        assert!(!shape.matches(&two_values));
        let mut only_set = Frame::new(2);
        only_set.commands.push(Command::values(C::SetDrivesMode, [4]));
        assert_eq!(AnswerShape::of(&only_set, &DeviceProfile::axis_1209a(), Revision::LATEST), None);
    }
}
