//! The 1209A's status word as the driver trusts it, and what it means for an axis.
//!
//! The NFv2 CRC misses some single-byte corruptions, and a wrong fault bit would stop a
//! head (or hide a fault), so the bits that drive decisions — limit switches, synchronized,
//! communication fault, following error, power stage, over-current, ERROR — change only
//! when **two consecutive answers** agree; the other bits (HOME and index sensors, the
//! limit-acting flags 10-12) are shown as last read. This costs one cycle of latency.
//!
//! Mapping to the axis model:
//!
//! | bits | axis |
//! |---|---|
//! | 0 / 1 limit switch up / down | `limit_positive` / `limit_negative` (swapped for a negative scale) |
//! | 4 synchronized | `homed` |
//! | 15 error | not `enabled`; a fault when we did not ask for ERROR, with the cause: limit switch, over-current (13), power stage (14), or the ENABLE input (digital input bit 3) |
//! | 7 communication fault | fault: the drive's 2 s command watchdog zeroed a set-point |
//! | 8 following error | fault while set |
//! | 9 power stage voltage low | fault while set: no motion possible |
//! | 10 / 11 / 12 position / speed / current limit acting | informational (the drive clamps) |

use motus_axis::{Fault, FaultKind};
use motus_nfv2_protocol::DriveStatus;

/// Bits that change only when two consecutive answers agree.
pub(crate) const DEBOUNCED: u16 = DriveStatus::LIMIT_SWITCH_UP
    | DriveStatus::LIMIT_SWITCH_DOWN
    | DriveStatus::SYNCHRONIZED
    | DriveStatus::COMMUNICATION_FAULT
    | DriveStatus::FOLLOWING_ERROR
    | DriveStatus::POWER_STAGE_VOLTAGE_LOW
    | DriveStatus::OVERCURRENT
    | DriveStatus::POWER_STAGE_FAULT
    | DriveStatus::ERROR;

/// ENABLE input bit of `ReadDigitalInputs` (the simulator's reading; the reference
/// firmware reports LIM_POS, LIM_NEG, HOME in bits 0-2).
pub const INPUT_ENABLE: u8 = 1 << 3;

/// The debounced status word.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct StatusFilter {
    /// Debounced bits (the [`DEBOUNCED`] mask) and the sequence number of the first of
    /// the two answers that agreed on them.
    accepted: Option<(u16, u64)>,
    /// The last word read and its sequence number.
    last: Option<(u16, u64)>,
}

impl StatusFilter {
    /// A status word read in the answer to frame `seq`.
    pub(crate) fn push(&mut self, word: u16, seq: u64) {
        let masked = word & DEBOUNCED;
        if let Some((prev, prev_seq)) = self.last {
            let agreed = prev & DEBOUNCED == masked;
            if agreed && self.accepted.map_or(true, |(a, _)| a != masked) {
                self.accepted = Some((masked, prev_seq));
            }
        }
        self.last = Some((word, seq));
    }

    /// The status to act on: debounced bits plus the others as last read.
    pub(crate) fn status(&self) -> Option<DriveStatus> {
        let (accepted, _) = self.accepted?;
        let (last, _) = self.last?;
        Some(DriveStatus(accepted | (last & !DEBOUNCED)))
    }

    /// The word as last read (not debounced).
    pub(crate) fn raw(&self) -> Option<DriveStatus> {
        self.last.map(|(w, _)| DriveStatus(w))
    }

    /// Sequence number of the first answer showing the debounced bits as they are now.
    pub(crate) fn since(&self) -> Option<u64> {
        self.accepted.map(|(_, s)| s)
    }
}

/// Why the drive is in ERROR, from its status and its digital inputs.
pub(crate) fn error_cause(status: DriveStatus, inputs: Option<u8>) -> Fault {
    let s = status;
    if s.contains(DriveStatus::LIMIT_SWITCH_UP) || s.contains(DriveStatus::LIMIT_SWITCH_DOWN) {
        let which = if s.contains(DriveStatus::LIMIT_SWITCH_UP) {
            "LIM_POS (status bit 0)"
        } else {
            "LIM_NEG (status bit 1)"
        };
        return Fault {
            kind: FaultKind::LimitSwitch,
            reason: format!(
                "limit switch {which} closed: the 1209A entered ERROR; fault-reset, then move away from the switch"
            ),
        };
    }
    if s.contains(DriveStatus::OVERCURRENT) {
        return Fault {
            kind: FaultKind::Other,
            reason: "over-current trip (status bit 13): the 1209A switched the bridge off and entered ERROR"
                .into(),
        };
    }
    if s.contains(DriveStatus::POWER_STAGE_FAULT) {
        return Fault { kind: FaultKind::Other, reason: "power stage fault (status bit 14): ERROR".into() };
    }
    match inputs {
        Some(i) if i & INPUT_ENABLE == 0 => Fault {
            kind: FaultKind::EmergencyStop,
            reason: "ENABLE input removed (emergency stop): the 1209A stopped the drive and entered ERROR; \
                     close the E-stop loop, then fault-reset"
                .into(),
        },
        _ => Fault {
            kind: FaultKind::Other,
            reason: format!(
                "the 1209A entered ERROR by itself (status {s}; no limit switch, no over-current)"
            ),
        },
    }
}

/// Faults shown while their bit is set (not latched by the host).
pub(crate) fn level_faults(status: DriveStatus) -> Vec<Fault> {
    let mut faults = Vec::new();
    if status.contains(DriveStatus::POWER_STAGE_VOLTAGE_LOW) {
        faults.push(Fault {
            kind: FaultKind::Other,
            reason:
                "power stage supply low (status bit 9): the bridge is off, no motion until the supply returns"
                    .into(),
        });
    }
    if status.contains(DriveStatus::COMMUNICATION_FAULT) {
        faults.push(Fault {
            kind: FaultKind::CommunicationTimeout,
            reason: "the 1209A's 2 s command watchdog zeroed the set-point (status bit 7); the next motion command \
                     clears it"
                .into(),
        });
    }
    if status.contains(DriveStatus::FOLLOWING_ERROR) {
        faults.push(Fault {
            kind: FaultKind::FollowingError,
            reason: "trajectory following error (status bit 8)".into(),
        });
    }
    faults
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fault_bit_needs_two_answers() {
        let mut f = StatusFilter::default();
        f.push(0x0010, 1);
        assert_eq!(f.status(), None);
        f.push(0x0010, 2);
        assert_eq!(f.status(), Some(DriveStatus(0x0010)));
        assert_eq!(f.since(), Some(1));
        // A single corrupted word with ERROR set is not believed; the index bit (3) is
        // shown at once.
        f.push(0x8018, 3);
        assert_eq!(f.status(), Some(DriveStatus(0x0018)));
        f.push(0x0010, 4);
        assert_eq!(f.status(), Some(DriveStatus(0x0010)));
        f.push(0x8000, 5);
        f.push(0x8000, 6);
        assert_eq!(f.status(), Some(DriveStatus(0x8000)));
        assert_eq!(f.since(), Some(5));
    }

    #[test]
    fn causes() {
        let limit = error_cause(DriveStatus(0x8001), None);
        assert_eq!(limit.kind, FaultKind::LimitSwitch);
        assert!(limit.reason.contains("LIM_POS"));
        assert_eq!(error_cause(DriveStatus(0x8000), Some(0b0000)).kind, FaultKind::EmergencyStop);
        assert_eq!(error_cause(DriveStatus(0x8000), Some(INPUT_ENABLE)).kind, FaultKind::Other);
        assert_eq!(level_faults(DriveStatus(0x0280)).len(), 2);
    }
}
