//! What a device answers, and what an exchange costs on the wire.
//!
//! A slave answers a frame only if it carries at least one query for a code the slave
//! supports; the answer carries the slave's address, the queried codes in order and, for
//! each, as many values as the slave has for it (the size of its communication buffer
//! for that code). Queries for codes it does not support are skipped, as every unknown
//! command is. [`DeviceProfile`] holds those counts so a scheduler can size the answer
//! before sending.
//!
//! Wire time: the 1209A's RS-485 runs at **57600 bps**; with 8N1 framing (10 bits per
//! byte) one byte takes 0.174 ms, so a 7-byte query plus its 11-byte answer already take
//! 3.1 ms. The source's "2 ms communication cycle" is only reachable over USB, or by
//! packing several commands into one frame (see [`FrameBuilder`](crate::FrameBuilder)).

use core::time::Duration;

use crate::code::CommandCode;
use crate::frame::{Frame, OVERHEAD};
use crate::revision::Revision;

/// RS-485 bit rate of the 1209A (bps).
pub const RS485_BAUD: u32 = 57_600;

/// Bits per byte on a UART line with 8 data bits, no parity, 1 stop bit (8N1).
pub const BITS_PER_BYTE_8N1: u32 = 10;

/// Time `bytes` take on a UART line at `baud` bits per second with 8N1 framing.
/// `baud == 0` gives [`Duration::MAX`].
#[must_use]
pub fn wire_time(bytes: usize, baud: u32) -> Duration {
    if baud == 0 {
        return Duration::MAX;
    }
    let bits = (bytes as u128) * u128::from(BITS_PER_BYTE_8N1);
    let nanos = bits * 1_000_000_000 / u128::from(baud);
    Duration::from_nanos(u64::try_from(nanos).unwrap_or(u64::MAX))
}

/// How many values a device answers for each read code (its communication buffer).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceProfile {
    counts: [u8; 256],
}

impl Default for DeviceProfile {
    fn default() -> Self {
        Self::none()
    }
}

impl DeviceProfile {
    /// A device that answers nothing.
    #[must_use]
    pub const fn none() -> Self {
        DeviceProfile { counts: [0; 256] }
    }

    /// The 1209A axis controller, from the seed's communication-buffer table:
    /// `ReadDeviceStatus` 1 value, `ReadDeviceVitals` 4 (indices 0..3),
    /// `ReadAnalogInputs` 2 (AI0, AI1), and one value (one drive) for
    /// `ReadDrivesPosition`, `ReadDrivesCurrent`, `ReadDrivesStatus`, `ReadDigitalInputs`.
    #[must_use]
    pub fn axis_1209a() -> Self {
        use CommandCode as C;
        Self::none()
            .with_answer(C::ReadDeviceStatus, 1)
            .with_answer(C::ReadDeviceVitals, 4)
            .with_answer(C::ReadAnalogInputs, 2)
            .with_answer(C::ReadDrivesPosition, 1)
            .with_answer(C::ReadDrivesCurrent, 1)
            .with_answer(C::ReadDrivesStatus, 1)
            .with_answer(C::ReadDigitalInputs, 1)
    }

    /// Sets the number of values the device answers for `code` (0: does not answer).
    #[must_use]
    pub fn with_answer(mut self, code: CommandCode, values: u8) -> Self {
        if let Some(slot) = self.counts.get_mut(usize::from(code.to_u8())) {
            *slot = values;
        }
        self
    }

    /// Values the device answers for a query of `code`; `None` if it does not answer it.
    #[must_use]
    pub fn answer_count(&self, code: CommandCode) -> Option<usize> {
        match self.counts.get(usize::from(code.to_u8())) {
            Some(&n) if n > 0 => Some(usize::from(n)),
            _ => None,
        }
    }

    /// Encoded size of the device's answer to `request` with `rev`'s widths; `None` if
    /// the device will not answer (no supported query in the frame). Queried codes
    /// without a width in `rev` are skipped by the device and count nothing.
    #[must_use]
    pub fn answer_len(&self, request: &Frame, rev: Revision) -> Option<usize> {
        let mut len = OVERHEAD;
        let mut any = false;
        for code in request.queries() {
            let (Some(count), Some(width)) = (self.answer_count(code), rev.width(code)) else {
                continue;
            };
            any = true;
            len += 2 + count * width;
        }
        any.then_some(len)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::command::Command;

    #[test]
    fn the_spec_wire_time_example() {
        // specs/nfv2.md: one byte 0.174 ms at 57600 bps; 7-byte query + 11-byte answer
        // = 3.1 ms.
        let byte = wire_time(1, RS485_BAUD);
        assert_eq!(byte.as_micros(), 173);
        let mut query = Frame::new(1);
        query.commands.push(Command::query(CommandCode::ReadDrivesPosition));
        let rev = Revision::LATEST;
        let req = query.encoded_len(rev).unwrap_or_default();
        let ans = DeviceProfile::axis_1209a().answer_len(&query, rev).unwrap_or_default();
        assert_eq!((req, ans), (7, 11));
        let t = wire_time(req + ans, RS485_BAUD);
        assert_eq!(t.as_micros(), 3125);
        assert!(t > Duration::from_millis(2));
    }

    #[test]
    fn no_supported_query_means_no_answer() {
        let p = DeviceProfile::axis_1209a();
        let mut f = Frame::new(1);
        f.commands.push(Command::values(CommandCode::SetDrivesPosition, [1]));
        assert_eq!(p.answer_len(&f, Revision::LATEST), None);
        f.commands.push(Command::query(CommandCode::ReadDrivesSpeed)); // not in the 1209A buffer
        assert_eq!(p.answer_len(&f, Revision::LATEST), None);
        f.commands.push(Command::query(CommandCode::ReadDeviceVitals));
        assert_eq!(p.answer_len(&f, Revision::LATEST), Some(5 + 2 + 4 * 2));
    }

    #[test]
    fn zero_baud() {
        assert_eq!(wire_time(1, 0), Duration::MAX);
    }
}
