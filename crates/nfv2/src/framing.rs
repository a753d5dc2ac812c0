//! Checking that an NFv2 answer is the one expected (the bus master finds answers with the
//! codec's [`motus_nfv2_protocol::FrameScanner`]).
//!
//! A frame starts with `'#' n !n` (not with line silence); its CRC-8 covers the address and
//! the commands. The NFv2 CRC (polynomial 0xD8, an even polynomial) misses 7 of the 255
//! possible corruptions of a single data byte, so the driver does not rely on it alone:
//! an answer is accepted only from the addressed slave, with exactly the queried codes in
//! order and the expected number of values each ([`AnswerShape`]); values then pass the
//! plausibility checks of [`crate::samples`] and the status debouncing of the drive.

use motus_nfv2_protocol::{Command, CommandCode, DeviceProfile, Frame, Revision};

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
