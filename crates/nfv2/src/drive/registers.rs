//! The host's mirror of a 1209A's set-point buffer, and which values are due in a frame.
//!
//! NFv2 has no acknowledgement of set-points: a slave answers queries only. A frame whose
//! answer arrives intact was received intact (the slave checks the CRC of the whole frame
//! before processing any of it), so every value it carried is **confirmed** by that
//! answer. A value is due in the next frame when it is not confirmed yet, or when its
//! register is sent every cycle (the active motion set-point: the 1209A's 2 s command
//! watchdog zeroes a speed that is not refreshed, and re-sending also repairs a value
//! corrupted on the way within one cycle). Every NFv2 set-point is absolute, so sending a
//! value again is harmless.

use motus_nfv2_protocol::CommandCode;

/// A set-point register of the 1209A, in the order frames carry them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) enum Reg {
    MinPosition,
    MaxPosition,
    MaxSpeed,
    MaxCurrent,
    MaxAcceleration,
    Speed,
    Position,
    Mode,
    Misc,
    Outputs,
}

impl Reg {
    pub(crate) const ALL: [Reg; 10] = [
        Reg::MinPosition,
        Reg::MaxPosition,
        Reg::MaxSpeed,
        Reg::MaxCurrent,
        Reg::MaxAcceleration,
        Reg::Speed,
        Reg::Position,
        Reg::Mode,
        Reg::Misc,
        Reg::Outputs,
    ];

    pub(crate) fn code(self) -> CommandCode {
        use CommandCode as C;
        match self {
            Reg::MinPosition => C::SetDrivesMinPosition,
            Reg::MaxPosition => C::SetDrivesMaxPosition,
            Reg::MaxSpeed => C::SetDrivesMaxSpeed,
            Reg::MaxCurrent => C::SetDrivesMaxCurrent,
            Reg::MaxAcceleration => C::SetDrivesMaxAcceleration,
            Reg::Speed => C::SetDrivesSpeed,
            Reg::Position => C::SetDrivesPosition,
            Reg::Mode => C::SetDrivesMode,
            Reg::Misc => C::SetDrivesMisc,
            Reg::Outputs => C::SetDigitalOutputs,
        }
    }

    fn index(self) -> usize {
        self as usize
    }
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct Register {
    value: Option<i64>,
    confirmed: Option<i64>,
    every_cycle: bool,
    /// Sent in frame `seq` with this value, answer pending.
    in_flight: Option<(u64, i64)>,
}

/// All registers of one drive.
#[derive(Debug, Clone, Default)]
pub(crate) struct Registers {
    regs: [Register; 10],
    /// Sequence number of the frame whose answer last confirmed a mode change.
    pub(crate) mode_confirmed_seq: Option<u64>,
}

impl Registers {
    fn reg(&self, r: Reg) -> Register {
        self.regs.get(r.index()).copied().unwrap_or_default()
    }

    fn reg_mut(&mut self, r: Reg) -> Option<&mut Register> {
        self.regs.get_mut(r.index())
    }

    /// Sets the value to send (sent until confirmed, or every cycle if so marked).
    pub(crate) fn set(&mut self, r: Reg, value: i64) {
        if let Some(reg) = self.reg_mut(r) {
            reg.value = Some(value);
        }
    }

    /// Whether `r` is sent in every frame while it has a value.
    pub(crate) fn every_cycle(&mut self, r: Reg, on: bool) {
        if let Some(reg) = self.reg_mut(r) {
            reg.every_cycle = on;
        }
    }

    /// Stops sending `r` (the slave keeps what it has).
    pub(crate) fn release(&mut self, r: Reg) {
        if let Some(reg) = self.reg_mut(r) {
            reg.value = None;
            reg.every_cycle = false;
        }
    }

    /// Sends `r` again even if its value was confirmed (the slave changed it by itself).
    pub(crate) fn force(&mut self, r: Reg) {
        if let Some(reg) = self.reg_mut(r) {
            reg.confirmed = None;
        }
    }

    /// The value set for `r`, if any.
    pub(crate) fn value(&self, r: Reg) -> Option<i64> {
        self.reg(r).value
    }

    /// The last value of `r` the slave confirmed.
    pub(crate) fn confirmed(&self, r: Reg) -> Option<i64> {
        self.reg(r).confirmed
    }

    /// The values due in the next frame, in frame order.
    pub(crate) fn due(&self) -> Vec<(Reg, i64)> {
        Reg::ALL
            .iter()
            .filter_map(|&r| {
                let reg = self.reg(r);
                let v = reg.value?;
                (reg.every_cycle || reg.confirmed != Some(v)).then_some((r, v))
            })
            .collect()
    }

    /// `r` was sent with `value` in frame `seq`.
    pub(crate) fn sent(&mut self, seq: u64, r: Reg, value: i64) {
        if let Some(reg) = self.reg_mut(r) {
            reg.in_flight = Some((seq, value));
        }
    }

    /// Frame `seq` was received by the slave (its answer arrived, or it needs none).
    pub(crate) fn confirm(&mut self, seq: u64) {
        let mut mode = false;
        for (i, reg) in self.regs.iter_mut().enumerate() {
            if let Some((s, v)) = reg.in_flight {
                if s == seq {
                    mode |= i == Reg::Mode.index() && reg.confirmed != Some(v);
                    reg.confirmed = Some(v);
                    reg.in_flight = None;
                }
            }
        }
        if mode {
            self.mode_confirmed_seq = Some(seq);
        }
    }

    /// Frame `seq` got no valid answer: its values stay due.
    pub(crate) fn lost(&mut self, seq: u64) {
        for reg in &mut self.regs {
            if reg.in_flight.is_some_and(|(s, _)| s == seq) {
                reg.in_flight = None;
            }
        }
    }

    /// True if every value set was confirmed at its current value.
    pub(crate) fn settled(&self) -> bool {
        self.regs.iter().all(|r| r.value.is_none() || r.value == r.confirmed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn due_until_confirmed_or_every_cycle() {
        let mut r = Registers::default();
        r.set(Reg::Mode, 4);
        r.set(Reg::Position, 100);
        r.every_cycle(Reg::Position, true);
        assert_eq!(r.due(), vec![(Reg::Position, 100), (Reg::Mode, 4)]);
        r.sent(1, Reg::Position, 100);
        r.sent(1, Reg::Mode, 4);
        r.lost(1);
        assert!(!r.settled());
        r.sent(2, Reg::Position, 100);
        r.sent(2, Reg::Mode, 4);
        r.confirm(2);
        assert_eq!(r.mode_confirmed_seq, Some(2));
        assert!(r.settled());
        assert_eq!(r.due(), vec![(Reg::Position, 100)]);
        // Re-confirming the same mode does not move the mode-confirmation mark.
        r.force(Reg::Mode);
        r.sent(3, Reg::Mode, 4);
        r.confirm(3);
        assert_eq!(r.mode_confirmed_seq, Some(3));
        r.sent(4, Reg::Position, 100);
        r.confirm(4);
        assert_eq!(r.mode_confirmed_seq, Some(3));
        r.release(Reg::Position);
        assert!(r.due().is_empty());
    }
}
