//! The CiA 402 power drive system state machine (spec 2.2-2.4).

use serde::{Deserialize, Serialize};

/// A state of the power drive system, decoded from the statusword with the masks of
/// spec 2.3.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PowerState {
    /// Not ready to switch on (initialising).
    NotReadyToSwitchOn,
    /// Switch on disabled.
    SwitchOnDisabled,
    /// Ready to switch on.
    ReadyToSwitchOn,
    /// Switched on (power section on, drive function off).
    SwitchedOn,
    /// Operation enabled (drive function on).
    OperationEnabled,
    /// Quick stop active.
    QuickStopActive,
    /// Fault reaction active.
    FaultReactionActive,
    /// Fault.
    Fault,
}

impl PowerState {
    /// Decodes the state from a statusword (spec 2.3: mask 0x4F for the states with
    /// bit 6 or bit 3 decisive, 0x6F for the others). Patterns that match no state
    /// (e.g. 0x0001 with bit 5 clear) decode as [`PowerState::NotReadyToSwitchOn`]
    /// only when they match it; otherwise the closest reading by the 0x4F mask.
    pub fn from_statusword(sw: u16) -> Self {
        match sw & 0x004F {
            0x0000 => return Self::NotReadyToSwitchOn,
            0x0040 => return Self::SwitchOnDisabled,
            0x000F => return Self::FaultReactionActive,
            0x0008 => return Self::Fault,
            _ => {}
        }
        match sw & 0x006F {
            0x0021 => Self::ReadyToSwitchOn,
            0x0023 => Self::SwitchedOn,
            0x0027 => Self::OperationEnabled,
            0x0007 => Self::QuickStopActive,
            // Bit 5 clear while ready/switched on: a drive mid-transition. Treat it by
            // the low bits, the safest (least enabled) reading first.
            _ if sw & 0x0008 != 0 => Self::Fault,
            _ if sw & 0x0004 != 0 => Self::QuickStopActive,
            _ if sw & 0x0002 != 0 => Self::SwitchedOn,
            _ if sw & 0x0001 != 0 => Self::ReadyToSwitchOn,
            _ => Self::SwitchOnDisabled,
        }
    }

    /// The state's statusword pattern (bits 0-3, 5, 6), e.g. operation enabled = 0x0027.
    pub fn statusword_bits(self) -> u16 {
        match self {
            Self::NotReadyToSwitchOn => 0x0000,
            Self::SwitchOnDisabled => 0x0040,
            Self::ReadyToSwitchOn => 0x0021,
            Self::SwitchedOn => 0x0023,
            Self::OperationEnabled => 0x0027,
            Self::QuickStopActive => 0x0007,
            Self::FaultReactionActive => 0x000F,
            Self::Fault => 0x0008,
        }
    }

    /// The state's name as the standard writes it.
    pub fn name(self) -> &'static str {
        match self {
            Self::NotReadyToSwitchOn => "not ready to switch on",
            Self::SwitchOnDisabled => "switch on disabled",
            Self::ReadyToSwitchOn => "ready to switch on",
            Self::SwitchedOn => "switched on",
            Self::OperationEnabled => "operation enabled",
            Self::QuickStopActive => "quick stop active",
            Self::FaultReactionActive => "fault reaction active",
            Self::Fault => "fault",
        }
    }
}

impl std::fmt::Display for PowerState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A device-control command (controlword bits 0-3 and 7; spec 2.2). Fault reset is not
/// a level but the 0 -> 1 edge of bit 7, handled separately.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DeviceCommand {
    /// Shutdown (0x06): transitions 2, 6, 8.
    Shutdown,
    /// Switch on (0x07): transition 3.
    SwitchOn,
    /// Switch on + enable operation (0x0F): transition 3 then 4.
    SwitchOnEnableOperation,
    /// Disable voltage (0x00): transitions 7, 9, 10, 12.
    DisableVoltage,
    /// Quick stop (0x02): transitions 7, 10, 11.
    QuickStop,
    /// Disable operation (0x07): transition 5.
    DisableOperation,
    /// Enable operation (0x0F): transitions 4, 16.
    EnableOperation,
}

impl DeviceCommand {
    /// The typical controlword for the command (bits 4-15 clear).
    pub fn controlword(self) -> u16 {
        match self {
            Self::Shutdown => 0x0006,
            Self::SwitchOn | Self::DisableOperation => 0x0007,
            Self::SwitchOnEnableOperation | Self::EnableOperation => 0x000F,
            Self::DisableVoltage => 0x0000,
            Self::QuickStop => 0x0002,
        }
    }

    /// Decodes the command a controlword carries (masks of spec 2.2). Returns `None` when
    /// bit 7 (fault reset) is set or no command matches. The words 0x07 and 0x0F decode as
    /// [`DeviceCommand::SwitchOn`] and [`DeviceCommand::SwitchOnEnableOperation`]; their
    /// meaning in a state is given by [`next_state`].
    pub fn from_controlword(cw: u16) -> Option<Self> {
        if cw & 0x0080 != 0 {
            return None;
        }
        if cw & 0x0082 == 0x0000 {
            Some(Self::DisableVoltage)
        } else if cw & 0x0086 == 0x0002 {
            Some(Self::QuickStop)
        } else if cw & 0x0087 == 0x0006 {
            Some(Self::Shutdown)
        } else if cw & 0x008F == 0x0007 {
            Some(Self::SwitchOn)
        } else if cw & 0x008F == 0x000F {
            Some(Self::SwitchOnEnableOperation)
        } else {
            None
        }
    }
}

/// The transition a command causes in a state (spec 2.4): the target state and the
/// transition number, or `None` if the command does nothing there. `quick_stop_option`
/// is 0x605A: with option codes 5-8 a quick stop stays in "quick stop active" and
/// enable operation returns to "operation enabled" (transition 16); with 0-4 the drive
/// leaves "quick stop active" automatically once stopped (transition 12, not a command).
pub fn next_state(
    state: PowerState,
    command: DeviceCommand,
    quick_stop_option: i16,
) -> Option<(PowerState, u8)> {
    use DeviceCommand as C;
    use PowerState as S;
    let enable = matches!(command, C::EnableOperation | C::SwitchOnEnableOperation);
    let switch_on = matches!(command, C::SwitchOn | C::DisableOperation);
    match state {
        S::SwitchOnDisabled if command == C::Shutdown => Some((S::ReadyToSwitchOn, 2)),
        S::ReadyToSwitchOn if switch_on => Some((S::SwitchedOn, 3)),
        // 0x0F in "ready to switch on": switch on now, enable operation follows (3 then 4).
        S::ReadyToSwitchOn if enable => Some((S::SwitchedOn, 3)),
        S::ReadyToSwitchOn if matches!(command, C::DisableVoltage | C::QuickStop) => {
            Some((S::SwitchOnDisabled, 7))
        }
        S::SwitchedOn if enable => Some((S::OperationEnabled, 4)),
        S::SwitchedOn if command == C::Shutdown => Some((S::ReadyToSwitchOn, 6)),
        S::SwitchedOn if matches!(command, C::DisableVoltage | C::QuickStop) => {
            Some((S::SwitchOnDisabled, 10))
        }
        S::OperationEnabled if switch_on => Some((S::SwitchedOn, 5)),
        S::OperationEnabled if command == C::Shutdown => Some((S::ReadyToSwitchOn, 8)),
        S::OperationEnabled if command == C::DisableVoltage => Some((S::SwitchOnDisabled, 9)),
        S::OperationEnabled if command == C::QuickStop => Some((S::QuickStopActive, 11)),
        S::QuickStopActive if command == C::DisableVoltage => Some((S::SwitchOnDisabled, 12)),
        S::QuickStopActive if enable && (5..=8).contains(&quick_stop_option) => {
            Some((S::OperationEnabled, 16))
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    const ALL: [PowerState; 8] = [
        PowerState::NotReadyToSwitchOn,
        PowerState::SwitchOnDisabled,
        PowerState::ReadyToSwitchOn,
        PowerState::SwitchedOn,
        PowerState::OperationEnabled,
        PowerState::QuickStopActive,
        PowerState::FaultReactionActive,
        PowerState::Fault,
    ];

    #[test]
    fn every_state_pattern_decodes_to_itself_whatever_the_other_bits() {
        // Bits outside 0x6F (voltage enabled, warning, remote, target reached, mode bits)
        // must not change the decoded state.
        for s in ALL {
            for extra in [0x0000, 0x0010, 0x0080, 0x0200, 0x0400, 0x1000, 0x2000, 0xFF90] {
                let mut sw = s.statusword_bits() | extra;
                // Bit 5 is part of the 0x6F patterns; keep it as the pattern says.
                sw = (sw & !0x0020) | (s.statusword_bits() & 0x0020);
                if matches!(
                    s,
                    PowerState::NotReadyToSwitchOn
                        | PowerState::SwitchOnDisabled
                        | PowerState::Fault
                        | PowerState::FaultReactionActive
                ) {
                    // 0x4F states: bit 5 is don't-care.
                    assert_eq!(PowerState::from_statusword(sw | 0x0020), s, "{sw:#06x}");
                }
                assert_eq!(PowerState::from_statusword(sw), s, "{sw:#06x}");
            }
        }
    }

    #[test]
    fn typical_statuswords_from_drives() {
        // Values seen on the wire (spec 2.3 patterns with bit 4 voltage and bit 9 remote).
        assert_eq!(PowerState::from_statusword(0x0250), PowerState::SwitchOnDisabled);
        assert_eq!(PowerState::from_statusword(0x0231), PowerState::ReadyToSwitchOn);
        assert_eq!(PowerState::from_statusword(0x0233), PowerState::SwitchedOn);
        assert_eq!(PowerState::from_statusword(0x1637), PowerState::OperationEnabled);
        assert_eq!(PowerState::from_statusword(0x0217), PowerState::QuickStopActive);
        assert_eq!(PowerState::from_statusword(0x0218), PowerState::Fault);
    }

    #[test]
    fn commands_round_trip_through_their_controlword() {
        for c in [
            DeviceCommand::Shutdown,
            DeviceCommand::SwitchOn,
            DeviceCommand::DisableVoltage,
            DeviceCommand::QuickStop,
        ] {
            assert_eq!(DeviceCommand::from_controlword(c.controlword()), Some(c));
        }
        assert_eq!(DeviceCommand::from_controlword(0x000F), Some(DeviceCommand::SwitchOnEnableOperation));
        // Mode bits do not change the command: 0x1F (new set-point), 0x5F (relative).
        assert_eq!(DeviceCommand::from_controlword(0x005F), Some(DeviceCommand::SwitchOnEnableOperation));
        // Bit 7 is fault reset, not a device command.
        assert_eq!(DeviceCommand::from_controlword(0x0080), None);
        // 0x0004 / 0x0005: enable voltage clear -> disable voltage.
        assert_eq!(DeviceCommand::from_controlword(0x0005), Some(DeviceCommand::DisableVoltage));
    }

    #[test]
    fn the_standard_path_to_operation_enabled_and_back() {
        use DeviceCommand as C;
        use PowerState as S;
        assert_eq!(next_state(S::SwitchOnDisabled, C::Shutdown, 2), Some((S::ReadyToSwitchOn, 2)));
        assert_eq!(next_state(S::ReadyToSwitchOn, C::SwitchOn, 2), Some((S::SwitchedOn, 3)));
        assert_eq!(next_state(S::SwitchedOn, C::EnableOperation, 2), Some((S::OperationEnabled, 4)));
        assert_eq!(next_state(S::OperationEnabled, C::DisableOperation, 2), Some((S::SwitchedOn, 5)));
        assert_eq!(next_state(S::SwitchedOn, C::Shutdown, 2), Some((S::ReadyToSwitchOn, 6)));
        assert_eq!(next_state(S::ReadyToSwitchOn, C::QuickStop, 2), Some((S::SwitchOnDisabled, 7)));
        assert_eq!(next_state(S::OperationEnabled, C::Shutdown, 2), Some((S::ReadyToSwitchOn, 8)));
        assert_eq!(next_state(S::OperationEnabled, C::DisableVoltage, 2), Some((S::SwitchOnDisabled, 9)));
        assert_eq!(next_state(S::SwitchedOn, C::QuickStop, 2), Some((S::SwitchOnDisabled, 10)));
        assert_eq!(next_state(S::OperationEnabled, C::QuickStop, 2), Some((S::QuickStopActive, 11)));
        assert_eq!(next_state(S::QuickStopActive, C::DisableVoltage, 2), Some((S::SwitchOnDisabled, 12)));
        // Transition 16 only for option codes 5-8.
        assert_eq!(next_state(S::QuickStopActive, C::EnableOperation, 2), None);
        assert_eq!(next_state(S::QuickStopActive, C::EnableOperation, 6), Some((S::OperationEnabled, 16)));
        // Nothing leaves "fault" but the fault-reset edge.
        for c in [C::Shutdown, C::SwitchOn, C::EnableOperation, C::DisableVoltage, C::QuickStop] {
            assert_eq!(next_state(S::Fault, c, 2), None);
        }
    }
}
