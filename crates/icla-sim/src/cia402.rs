//! Device side of the CiA 402 power drive system state machine (specs/canopen.md 2.2-2.5):
//! commands decoded from the controlword with `motus_cia402_protocol`, transitions
//! 0-16, the fault reset on a 0 -> 1 edge of bit 7 (only when the cause is gone), the quick
//! stop option code 0x605A, the shutdown / disable operation option codes 0x605B / 0x605C
//! (0 = power off at once, 1 = ramp down with the profile deceleration) and the fault
//! reaction option code 0x605E (0 = power off, 1 = profile deceleration, 2-4 = quick stop
//! deceleration).

use motus_cia402_protocol::{cw, next_state, DeviceCommand, PowerState};

use crate::motion::Regime;

/// Option codes and ramps the state machine needs.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Options {
    /// 0x605A quick stop option code.
    pub quick_stop: i16,
    /// 0x605B shutdown option code.
    pub shutdown: i16,
    /// 0x605C disable operation option code.
    pub disable_operation: i16,
    /// 0x605E fault reaction option code.
    pub fault_reaction: i16,
    /// 0x6084 profile deceleration.
    pub profile_deceleration: f64,
    /// 0x6085 quick stop deceleration.
    pub quick_stop_deceleration: f64,
}

/// The power state machine of one drive.
#[derive(Debug, Clone, PartialEq)]
pub struct Power {
    state: PowerState,
    /// A ramp-down still running after leaving operation enabled (option code 1).
    ramp_down: Option<f64>,
}

impl Default for Power {
    fn default() -> Self {
        Self::new()
    }
}

impl Power {
    /// After initialisation: transitions 0 and 1 done, "switch on disabled".
    pub fn new() -> Self {
        Self { state: PowerState::SwitchOnDisabled, ramp_down: None }
    }

    /// The state.
    pub fn state(&self) -> PowerState {
        self.state
    }

    /// Applies a new controlword (`prev` = the previous one); returns the transition numbers taken.
    pub fn on_controlword(&mut self, prev: u16, word: u16, o: &Options, cause_active: bool) -> Vec<u8> {
        let mut taken = Vec::new();
        if word & cw::FAULT_RESET != 0 {
            if prev & cw::FAULT_RESET == 0 && self.state == PowerState::Fault && !cause_active {
                self.state = PowerState::SwitchOnDisabled;
                taken.push(15);
            }
            return taken;
        }
        let Some(command) = DeviceCommand::from_controlword(word) else {
            return taken;
        };
        while let Some((to, n)) = next_state(self.state, command, o.quick_stop) {
            self.enter(to, n, o);
            taken.push(n);
            // 0x0F in "ready to switch on": 3, then 4 at once.
            if n != 3 || command != DeviceCommand::SwitchOnEnableOperation {
                break;
            }
        }
        taken
    }

    fn enter(&mut self, to: PowerState, n: u8, o: &Options) {
        self.ramp_down = match n {
            5 if o.disable_operation == 1 => Some(o.profile_deceleration),
            8 if o.shutdown == 1 => Some(o.profile_deceleration),
            4 | 16 => None,
            _ => self.ramp_down,
        };
        self.state = to;
        // Option 0: disable the drive function at once, no "quick stop active" phase.
        if n == 11 && o.quick_stop == 0 {
            self.state = PowerState::SwitchOnDisabled;
        }
    }

    /// A fault was detected (transition 13); false if already in fault handling.
    pub fn fault(&mut self, o: &Options) -> bool {
        if matches!(self.state, PowerState::Fault | PowerState::FaultReactionActive) {
            return false;
        }
        self.ramp_down = None;
        self.state = if o.fault_reaction == 0 { PowerState::Fault } else { PowerState::FaultReactionActive };
        true
    }

    /// How the motion generator may run in this state.
    pub fn regime(&self, o: &Options) -> Regime {
        match self.state {
            PowerState::OperationEnabled => Regime::Enabled,
            PowerState::QuickStopActive => Regime::Stopping(match o.quick_stop {
                1 | 5 => o.profile_deceleration,
                _ => o.quick_stop_deceleration,
            }),
            PowerState::FaultReactionActive => Regime::Stopping(match o.fault_reaction {
                1 => o.profile_deceleration,
                _ => o.quick_stop_deceleration,
            }),
            _ => match self.ramp_down {
                Some(dec) => Regime::Stopping(dec),
                None => Regime::Off,
            },
        }
    }

    /// After a motion step: automatic transitions 12 and 14 once the axis stands still.
    pub fn after_step(&mut self, standstill: bool, o: &Options) -> Option<u8> {
        if !standstill {
            return None;
        }
        self.ramp_down = None;
        match self.state {
            PowerState::QuickStopActive if (0..=4).contains(&o.quick_stop) => {
                self.state = PowerState::SwitchOnDisabled;
                Some(12)
            }
            PowerState::FaultReactionActive => {
                self.state = PowerState::Fault;
                Some(14)
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    fn opts(qs: i16) -> Options {
        Options {
            quick_stop: qs,
            shutdown: 0,
            disable_operation: 1,
            fault_reaction: 2,
            profile_deceleration: 400.0,
            quick_stop_deceleration: 2000.0,
        }
    }

    #[test]
    fn path_to_operation_enabled_and_quick_stop() {
        let o = opts(2);
        let mut p = Power::new();
        assert_eq!(p.on_controlword(0, 0x06, &o, false), vec![2]);
        assert_eq!(p.on_controlword(0x06, 0x0F, &o, false), vec![3, 4], "0x0F from ready: 3 then 4");
        assert_eq!(p.state(), PowerState::OperationEnabled);
        assert_eq!(p.regime(&o), Regime::Enabled);
        // Mode bits do not change the command: 0x5F keeps operation enabled.
        assert!(p.on_controlword(0x0F, 0x5F, &o, false).is_empty());
        assert_eq!(p.on_controlword(0x5F, 0x02, &o, false), vec![11]);
        assert_eq!(p.regime(&o), Regime::Stopping(2000.0));
        assert_eq!(p.after_step(false, &o), None);
        assert_eq!(p.after_step(true, &o), Some(12));
        assert_eq!(p.state(), PowerState::SwitchOnDisabled);
    }

    #[test]
    fn quick_stop_option_6_stays_and_returns_with_16() {
        let o = opts(6);
        let mut p = Power::new();
        p.on_controlword(0, 0x06, &o, false);
        p.on_controlword(0x06, 0x0F, &o, false);
        p.on_controlword(0x0F, 0x02, &o, false);
        assert_eq!(p.after_step(true, &o), None);
        assert_eq!(p.state(), PowerState::QuickStopActive);
        assert_eq!(p.on_controlword(0x02, 0x0F, &o, false), vec![16]);
    }

    #[test]
    fn fault_reset_needs_an_edge_and_no_cause() {
        let o = opts(2);
        let mut p = Power::new();
        assert!(p.fault(&o));
        assert!(!p.fault(&o));
        assert_eq!(p.state(), PowerState::FaultReactionActive);
        assert_eq!(p.after_step(true, &o), Some(14));
        // Cause still active: no transition.
        assert!(p.on_controlword(0x00, 0x80, &o, true).is_empty());
        // Cause gone but bit 7 already high: no edge.
        assert!(p.on_controlword(0x80, 0x80, &o, false).is_empty());
        assert_eq!(p.on_controlword(0x00, 0x80, &o, false), vec![15]);
        assert_eq!(p.state(), PowerState::SwitchOnDisabled);
    }

    #[test]
    fn disable_operation_option_1_ramps_down() {
        let o = opts(2);
        let mut p = Power::new();
        p.on_controlword(0, 0x06, &o, false);
        p.on_controlword(0x06, 0x0F, &o, false);
        assert_eq!(p.on_controlword(0x0F, 0x07, &o, false), vec![5]);
        assert_eq!(p.regime(&o), Regime::Stopping(400.0));
        p.after_step(true, &o);
        assert_eq!(p.regime(&o), Regime::Off);
    }
}
