//! One CiA 402 drive: power state machine, modes, profile position / velocity, homing.

use crate::error::DriveError;
use crate::io::{fixed, DriveIo, IoError};
use crate::settings::{DriveSettings, Profile};
use motus_canopen_protocol::SdoAbortCode;
use motus_cia402_protocol::{cw, index, sw, DeviceCommand, HomingStatus, Mode, PowerState};
use motus_clock::SharedClock;
use std::time::{Duration, Instant};

/// Whether a profile-position target is absolute or relative (controlword bit 6).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MoveKind {
    /// Target is an absolute position.
    Absolute,
    /// Target is relative to the current target / position.
    Relative,
}

/// A CiA 402 drive reached through a [`DriveIo`].
pub struct Drive<Io: DriveIo> {
    io: Io,
    settings: DriveSettings,
    /// The last controlword written (to make clean edges on bits 4 and 7).
    last_cw: u16,
    /// Software position limits (min, max) when known.
    limits: Option<(i32, i32)>,
    /// The time of every wait (the clock of the object access, [`DriveIo::clock`]).
    clock: SharedClock,
}

impl<Io: DriveIo> Drive<Io> {
    /// A driver for the drive behind `io`. Its waits (enable, mode change, set-point
    /// acknowledge, move, homing, fault reset) run on the clock of `io`
    /// ([`DriveIo::clock`]): the system clock, or a virtual one in tests.
    pub fn new(io: Io, settings: DriveSettings) -> Self {
        let clock = io.clock();
        Self { io, settings, last_cw: 0, limits: None, clock }
    }

    /// The clock of this driver's waits.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }

    /// The object access underneath.
    pub fn io(&self) -> &Io {
        &self.io
    }

    /// The node id.
    pub fn node(&self) -> u8 {
        self.io.node()
    }

    /// The settings.
    pub fn settings(&self) -> &DriveSettings {
        &self.settings
    }

    /// The last controlword this driver wrote.
    pub fn last_controlword(&self) -> u16 {
        self.last_cw
    }

    /// Reads the statusword and decodes the power state.
    pub fn state(&self) -> Result<(PowerState, u16), DriveError> {
        let sw = self.io.statusword()?;
        Ok((PowerState::from_statusword(sw), sw))
    }

    /// Writes a controlword and remembers it.
    pub fn write_controlword(&mut self, word: u16) -> Result<(), DriveError> {
        self.io.write_controlword(word)?;
        self.last_cw = word;
        Ok(())
    }

    /// Reads the error code 0x603F (None when the drive lacks it or does not answer).
    pub fn error_code(&self) -> Option<u16> {
        let raw = self.io.read(index::ERROR_CODE, 0).ok()?;
        fixed::<2>(self.node(), index::ERROR_CODE, 0, &raw).ok().map(u16::from_le_bytes)
    }

    fn fault(&self) -> DriveError {
        DriveError::Fault { node: self.node(), code: self.error_code() }
    }

    /// Brings the drive to "operation enabled" through the standard path
    /// (shutdown, switch on, enable operation). A drive in fault is not reset behind the
    /// caller's back: that returns [`DriveError::Fault`].
    pub fn enable(&mut self) -> Result<(), DriveError> {
        let start = self.clock.now();
        let limit = self.settings.transition_timeout * 4;
        let mut last_sent: Option<(PowerState, Instant)> = None;
        loop {
            let (state, word) = self.state()?;
            let command = match state {
                PowerState::OperationEnabled => return Ok(()),
                PowerState::Fault => return Err(self.fault()),
                PowerState::NotReadyToSwitchOn | PowerState::FaultReactionActive => None,
                PowerState::SwitchOnDisabled => Some(DeviceCommand::Shutdown),
                PowerState::ReadyToSwitchOn => Some(DeviceCommand::SwitchOn),
                PowerState::SwitchedOn => Some(DeviceCommand::EnableOperation),
                PowerState::QuickStopActive => Some(DeviceCommand::DisableVoltage),
            };
            if let Some(c) = command {
                // Send once per state, again only if the drive ignores it for a while.
                let resend = match last_sent {
                    Some((s, at)) => s != state || self.clock.elapsed(at) >= self.settings.transition_timeout,
                    None => true,
                };
                if resend {
                    self.write_controlword(c.controlword())?;
                    last_sent = Some((state, self.clock.now()));
                }
            }
            if self.clock.elapsed(start) > limit {
                return Err(DriveError::StateTimeout {
                    node: self.node(),
                    state,
                    statusword: word,
                    target: PowerState::OperationEnabled,
                    waited: self.clock.elapsed(start),
                });
            }
            self.clock.sleep(self.settings.poll_interval);
        }
    }

    /// Stops motion (halt, then waits for standstill) and switches the power stage off
    /// ("ready to switch on"). A drive in fault or already off is left as it is.
    pub fn disable(&mut self) -> Result<(), DriveError> {
        let (state, _) = self.state()?;
        if state == PowerState::OperationEnabled {
            self.halt()?;
            self.wait_standstill(self.settings.transition_timeout * 5)?;
            self.write_controlword(DeviceCommand::DisableOperation.controlword())?;
            self.wait_state(PowerState::SwitchedOn)?;
        }
        let (state, _) = self.state()?;
        if matches!(state, PowerState::SwitchedOn) {
            self.write_controlword(DeviceCommand::Shutdown.controlword())?;
            self.wait_state(PowerState::ReadyToSwitchOn)?;
        }
        Ok(())
    }

    /// Waits for standstill after a halt: statusword bit 10 (with halt set it means
    /// "velocity 0") or a zero 0x606C reading. Fails on fault or time-out.
    pub fn wait_standstill(&self, timeout: Duration) -> Result<(), DriveError> {
        let start = self.clock.now();
        loop {
            let (state, word) = self.state()?;
            if matches!(state, PowerState::Fault | PowerState::FaultReactionActive) {
                return Err(self.fault());
            }
            if word & sw::TARGET_REACHED != 0 || self.velocity().ok() == Some(0) {
                return Ok(());
            }
            if self.clock.elapsed(start) > timeout {
                return Err(DriveError::MotionTimeout {
                    node: self.node(),
                    what: "halt".into(),
                    statusword: word,
                    waited: self.clock.elapsed(start),
                });
            }
            self.clock.sleep(self.settings.poll_interval);
        }
    }

    /// Waits until the drive is in `target`.
    pub fn wait_state(&self, target: PowerState) -> Result<(), DriveError> {
        let start = self.clock.now();
        loop {
            let (state, word) = self.state()?;
            if state == target {
                return Ok(());
            }
            if state == PowerState::Fault && target != PowerState::Fault {
                return Err(self.fault());
            }
            if self.clock.elapsed(start) > self.settings.transition_timeout {
                return Err(DriveError::StateTimeout {
                    node: self.node(),
                    state,
                    statusword: word,
                    target,
                    waited: self.clock.elapsed(start),
                });
            }
            self.clock.sleep(self.settings.poll_interval);
        }
    }

    /// Clears a fault with a 0 -> 1 edge of controlword bit 7 (transition 15). When the
    /// cause is still present the drive stays in fault and this returns
    /// [`DriveError::FaultPersists`]. A drive not in fault is left alone.
    pub fn fault_reset(&mut self) -> Result<(), DriveError> {
        let (state, _) = self.state()?;
        if !matches!(state, PowerState::Fault | PowerState::FaultReactionActive) {
            return Ok(());
        }
        // A clean edge: bit 7 low first (with everything else off), then high.
        self.write_controlword(0x0000)?;
        self.clock.sleep(self.settings.fault_reset_pulse);
        self.write_controlword(cw::FAULT_RESET)?;
        let start = self.clock.now();
        let result = loop {
            let (state, _) = self.state()?;
            if !matches!(state, PowerState::Fault | PowerState::FaultReactionActive) {
                break Ok(());
            }
            if self.clock.elapsed(start) > self.settings.transition_timeout {
                break Err(DriveError::FaultPersists { node: self.node(), code: self.error_code() });
            }
            self.clock.sleep(self.settings.poll_interval);
        };
        // Bit 7 back low so the next reset is an edge again.
        self.write_controlword(0x0000)?;
        result
    }

    /// Quick stop (controlword 0x0002): the drive stops on its quick-stop ramp per 0x605A.
    pub fn quick_stop(&mut self) -> Result<(), DriveError> {
        self.write_controlword(DeviceCommand::QuickStop.controlword())
    }

    /// Halt (controlword bit 8): stop with the profile deceleration, stay enabled.
    pub fn halt(&mut self) -> Result<(), DriveError> {
        let word = (self.last_cw & !cw::NEW_SET_POINT) | cw::HALT | 0x000F;
        self.write_controlword(word)
    }

    /// Reads 0x6502 (None when the drive does not have it).
    pub fn supported_modes(&self) -> Result<Option<u32>, DriveError> {
        match self.io.read(index::SUPPORTED_MODES, 0) {
            Ok(raw) => {
                Ok(Some(u32::from_le_bytes(fixed::<4>(self.node(), index::SUPPORTED_MODES, 0, &raw)?)))
            }
            Err(IoError::Refused { code, .. }) if code == SdoAbortCode::from_raw(0x0602_0000) => Ok(None),
            Err(e) => Err(e.into()),
        }
    }

    /// Reads the mode displayed in 0x6061.
    pub fn mode_display(&self) -> Result<Mode, DriveError> {
        let raw = self.io.read(index::MODES_DISPLAY, 0)?;
        let [b] = fixed::<1>(self.node(), index::MODES_DISPLAY, 0, &raw)?;
        Ok(Mode::from_i8(i8::from_le_bytes([b])))
    }

    /// Selects a mode of operation and waits until 0x6061 displays it.
    pub fn set_mode(&mut self, mode: Mode) -> Result<(), DriveError> {
        if self.mode_display()? == mode {
            return Ok(());
        }
        if let (Some(supported), Some(bit)) = (self.supported_modes()?, mode.supported_bit()) {
            if supported & bit == 0 {
                return Err(DriveError::ModeUnsupported { node: self.node(), mode, supported });
            }
        }
        self.io.write(index::MODES_OF_OPERATION, 0, &mode.to_i8().to_le_bytes())?;
        let start = self.clock.now();
        loop {
            let displayed = self.mode_display()?;
            if displayed == mode {
                return Ok(());
            }
            if self.clock.elapsed(start) > self.settings.transition_timeout {
                return Err(DriveError::ModeRefused { node: self.node(), wanted: mode, displayed });
            }
            self.clock.sleep(self.settings.poll_interval);
        }
    }

    /// Writes the profile velocity, acceleration and deceleration.
    pub fn set_profile(&mut self, profile: &Profile) -> Result<(), DriveError> {
        if profile.velocity == 0 || profile.acceleration == 0 || profile.deceleration == 0 {
            return Err(DriveError::InvalidArgument {
                node: self.node(),
                reason: format!("profile values must be positive: {profile:?}"),
            });
        }
        self.io.write(index::PROFILE_VELOCITY, 0, &profile.velocity.to_le_bytes())?;
        self.io.write(index::PROFILE_ACCELERATION, 0, &profile.acceleration.to_le_bytes())?;
        self.io.write(index::PROFILE_DECELERATION, 0, &profile.deceleration.to_le_bytes())?;
        Ok(())
    }

    /// Sets the quick stop option code 0x605A (spec 2.5): 0 coast, 1 slow-down ramp, 2
    /// quick-stop ramp (0x6085), 3 current limit, 4 voltage limit, then "switch on
    /// disabled"; 5-8 the same but staying in "quick stop active".
    pub fn set_quick_stop_option(&mut self, code: i16) -> Result<(), DriveError> {
        if !(0..=8).contains(&code) {
            return Err(DriveError::InvalidArgument {
                node: self.node(),
                reason: format!(
                    "quick stop option code {code} is not 0..=8 (negative codes are vendor specific)"
                ),
            });
        }
        self.io.write(index::QUICK_STOP_OPTION, 0, &code.to_le_bytes())?;
        Ok(())
    }

    /// Sets the quick-stop deceleration 0x6085 (inc/s^2).
    pub fn set_quick_stop_deceleration(&mut self, deceleration: u32) -> Result<(), DriveError> {
        if deceleration == 0 {
            return Err(DriveError::InvalidArgument {
                node: self.node(),
                reason: "quick-stop deceleration must be positive".into(),
            });
        }
        self.io.write(index::QUICK_STOP_DECELERATION, 0, &deceleration.to_le_bytes())?;
        Ok(())
    }

    /// Sets the following error window 0x6065 (inc) and time-out 0x6066 (ms): beyond the
    /// window for longer than the time-out, the drive sets statusword bit 13.
    pub fn set_following_error(&mut self, window: u32, timeout_ms: u16) -> Result<(), DriveError> {
        self.io.write(index::FOLLOWING_ERROR_WINDOW, 0, &window.to_le_bytes())?;
        self.io.write(index::FOLLOWING_ERROR_TIMEOUT, 0, &timeout_ms.to_le_bytes())?;
        Ok(())
    }

    /// Writes the software position limits 0x607D and checks targets against them.
    pub fn set_software_limits(&mut self, min: i32, max: i32) -> Result<(), DriveError> {
        if min > max {
            return Err(DriveError::InvalidArgument {
                node: self.node(),
                reason: format!("software limits reversed: min {min} > max {max}"),
            });
        }
        self.io.write(index::SOFTWARE_POSITION_LIMIT, 1, &min.to_le_bytes())?;
        self.io.write(index::SOFTWARE_POSITION_LIMIT, 2, &max.to_le_bytes())?;
        self.limits = Some((min, max));
        Ok(())
    }

    /// Reads the software position limits from the drive (0/0 means "off" on many drives).
    pub fn read_software_limits(&mut self) -> Result<Option<(i32, i32)>, DriveError> {
        let n = self.node();
        let min = i32::from_le_bytes(fixed::<4>(
            n,
            index::SOFTWARE_POSITION_LIMIT,
            1,
            &self.io.read(index::SOFTWARE_POSITION_LIMIT, 1)?,
        )?);
        let max = i32::from_le_bytes(fixed::<4>(
            n,
            index::SOFTWARE_POSITION_LIMIT,
            2,
            &self.io.read(index::SOFTWARE_POSITION_LIMIT, 2)?,
        )?);
        self.limits = if min == 0 && max == 0 { None } else { Some((min, max)) };
        Ok(self.limits)
    }

    fn require_enabled(&self) -> Result<u16, DriveError> {
        let (state, word) = self.state()?;
        match state {
            PowerState::OperationEnabled => Ok(word),
            PowerState::Fault | PowerState::FaultReactionActive => Err(self.fault()),
            other => Err(DriveError::NotEnabled { node: self.node(), state: other }),
        }
    }

    /// Starts a profile-position move with the set-point handshake: write 0x607A, raise
    /// controlword bit 4, wait for statusword bit 12 (set-point acknowledge), lower bit 4.
    /// `immediate` sets bit 5 (change set immediately). Returns once the drive took the
    /// set-point; [`Drive::wait_target_reached`] waits for the end.
    pub fn start_move(&mut self, target: i32, kind: MoveKind, immediate: bool) -> Result<(), DriveError> {
        self.require_enabled()?;
        if let (MoveKind::Absolute, Some((min, max))) = (kind, self.limits) {
            if target < min || target > max {
                return Err(DriveError::BeyondLimit { node: self.node(), target: target.into(), min, max });
            }
        }
        self.set_mode(Mode::ProfilePosition)?;
        self.io.write(index::TARGET_POSITION, 0, &target.to_le_bytes())?;
        let mut base = 0x000F;
        if kind == MoveKind::Relative {
            base |= cw::RELATIVE;
        }
        if immediate {
            base |= cw::CHANGE_SET_IMMEDIATELY;
        }
        if self.last_cw & (cw::NEW_SET_POINT | cw::HALT) != 0 {
            self.write_controlword(base)?;
        }
        self.write_controlword(base | cw::NEW_SET_POINT)?;
        let acked = self.wait_status(
            sw::SET_POINT_ACKNOWLEDGE,
            sw::SET_POINT_ACKNOWLEDGE,
            self.settings.set_point_timeout,
            "set-point acknowledge",
        );
        // Lower bit 4 whatever happened, so the next set-point is an edge again.
        self.write_controlword(base)?;
        match acked {
            Ok(_) => Ok(()),
            Err(DriveError::MotionTimeout { statusword, waited, .. }) => {
                Err(DriveError::SetPointNotAcknowledged { node: self.node(), statusword, waited })
            }
            Err(e) => Err(e),
        }
    }

    /// Waits for statusword bit 10 (target reached) in profile position; fails on fault or
    /// following error. Returns the actual position.
    pub fn wait_target_reached(&self, timeout: Duration) -> Result<i32, DriveError> {
        self.wait_status(
            sw::TARGET_REACHED | sw::SET_POINT_ACKNOWLEDGE,
            sw::TARGET_REACHED,
            timeout,
            "move",
        )?;
        Ok(self.io.position()?)
    }

    /// Polls the statusword until `word & mask == value`. Fails on fault, on a following
    /// error (bit 13 in profile position), or on time-out.
    fn wait_status(&self, mask: u16, value: u16, timeout: Duration, what: &str) -> Result<u16, DriveError> {
        let start = self.clock.now();
        loop {
            let (state, word) = self.state()?;
            if matches!(state, PowerState::Fault | PowerState::FaultReactionActive) {
                return Err(self.fault());
            }
            if word & sw::FOLLOWING_ERROR != 0 && what != "homing" {
                return Err(DriveError::FollowingError { node: self.node(), statusword: word });
            }
            if word & mask == value {
                return Ok(word);
            }
            if self.clock.elapsed(start) > timeout {
                return Err(DriveError::MotionTimeout {
                    node: self.node(),
                    what: what.into(),
                    statusword: word,
                    waited: self.clock.elapsed(start),
                });
            }
            self.clock.sleep(self.settings.poll_interval);
        }
    }

    /// Profile velocity: runs at `velocity` (inc/s, signed) until halted or changed.
    pub fn run_velocity(&mut self, velocity: i32) -> Result<(), DriveError> {
        self.require_enabled()?;
        self.set_mode(Mode::ProfileVelocity)?;
        self.io.write(index::TARGET_VELOCITY, 0, &velocity.to_le_bytes())?;
        self.write_controlword(0x000F)
    }

    /// Runs a homing with `method` (0x6098) and waits for "homing completed"
    /// (statusword & 0x3400 == 0x1400). Leaves the drive in profile position mode.
    pub fn home(&mut self, method: i8, timeout: Duration) -> Result<(), DriveError> {
        self.require_enabled()?;
        self.set_mode(Mode::Homing)?;
        self.io.write(index::HOMING_METHOD, 0, &method.to_le_bytes())?;
        self.write_controlword(0x000F)?;
        self.write_controlword(0x000F | cw::HOMING_START)?;
        let start = self.clock.now();
        let result = loop {
            let (state, word) = self.state()?;
            if matches!(state, PowerState::Fault | PowerState::FaultReactionActive) {
                break Err(self.fault());
            }
            match HomingStatus::from_statusword(word) {
                HomingStatus::Completed => break Ok(()),
                HomingStatus::ErrorMoving | HomingStatus::ErrorStopped => {
                    break Err(DriveError::HomingFailed { node: self.node(), statusword: word })
                }
                _ => {}
            }
            if self.clock.elapsed(start) > timeout {
                break Err(DriveError::MotionTimeout {
                    node: self.node(),
                    what: "homing".into(),
                    statusword: word,
                    waited: self.clock.elapsed(start),
                });
            }
            self.clock.sleep(self.settings.poll_interval);
        };
        self.write_controlword(0x000F)?;
        result?;
        self.set_mode(Mode::ProfilePosition)
    }

    /// Reads the actual velocity 0x606C (inc/s).
    pub fn velocity(&self) -> Result<i32, DriveError> {
        let raw = self.io.read(index::VELOCITY_ACTUAL, 0)?;
        Ok(i32::from_le_bytes(fixed::<4>(self.node(), index::VELOCITY_ACTUAL, 0, &raw)?))
    }

    /// Reads the actual position 0x6064 (inc).
    pub fn position(&self) -> Result<i32, DriveError> {
        Ok(self.io.position()?)
    }
}
