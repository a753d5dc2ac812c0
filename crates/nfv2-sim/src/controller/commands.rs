//! What the controller does with a frame: set-points into the communication buffer,
//! queries answered from the values published at the end of the last regulator cycle.
//!
//! As the reference interpreter (`NF_Interpreter` in `nfv2.c`):
//! - set-commands are applied if the frame is addressed to this controller or broadcast
//!   ([`AddressPlan::accepts`](motus_nfv2_protocol::AddressPlan::accepts)); queries are
//!   answered only for its own address, never for a broadcast;
//! - a command carrying several values updates only the first (one drive), a command
//!   without values (k = 0) on a set-code does nothing;
//! - commands the 1209A's buffer does not hold (servos, display, distance, motion
//!   duration...) are skipped; the rest of the frame is processed;
//! - one answer frame carries every supported query of the request, in order, with the
//!   controller's address; a frame without one gets no answer.
//!
//! Our readings where the sources are silent:
//! - `SetDrivesMaxSpeed`, `SetDrivesMaxCurrent`, `SetDrivesMaxAcceleration` <= 0 are
//!   ignored; a current limit above the 13 A hardware rating is clamped to it;
//! - `SetDrivesMode` other than ERROR is ignored while ENABLE is absent (the E-stop must
//!   not restart motion when the loop is closed again); `SetDrivesMode` clears the
//!   over-current latch;
//! - `SetDrivesMisc`: bit 0 sets "synchronized", bit 1 clears it (both: cleared);
//! - `SetDrivesMaxAcceleration` (0x19, Rev2013+) is accepted although the seed's buffer
//!   does not list it: it sets the trajectory generator's acceleration (counts/s²).

use std::time::Duration;

use motus_nfv2_protocol::{answer, Command, CommandCode, DriveMode, DrivesMisc, Frame};

use super::Controller;

impl Controller {
    /// Handles one frame received at `now` (advancing to `now` first): applies its
    /// set-points and returns the answer to its queries, if it has to answer.
    pub fn handle(&mut self, frame: &Frame, now: Duration) -> Option<Frame> {
        self.advance_to(now);
        if !self.plan.accepts(self.address, frame.address) {
            return None;
        }
        for command in frame.commands.iter().filter(|c| !c.is_query()) {
            self.apply(command, now);
        }
        if !self.plan.answers(self.address, frame.address) {
            return None;
        }
        answer(frame, self.address, |code| self.read(code))
    }

    /// What a query for `code` reads now (as of the last regulator cycle), or `None` if
    /// the 1209A does not answer that code. Values are clamped to the revision's widths.
    #[must_use]
    pub fn read(&self, code: CommandCode) -> Option<Command> {
        use CommandCode as C;
        let p = &self.published;
        let values: Vec<i64> = match code {
            C::ReadDeviceStatus => vec![i64::from(p.device_status)],
            C::ReadDeviceVitals => p.vitals_mv.to_vec(),
            C::ReadAnalogInputs => p.analog_mv.to_vec(),
            // The counter is a 32-bit register: it wraps.
            C::ReadDrivesPosition => vec![i64::from(p.position as i32)],
            C::ReadDrivesCurrent => vec![p.current_ma],
            C::ReadDrivesStatus => vec![i64::from(p.status)],
            C::ReadDigitalInputs => vec![i64::from(p.digital_inputs)],
            _ => return None,
        };
        let (lo, hi) = self.revision.value_kind(code)?.range()?;
        Some(Command::values(code, values.into_iter().map(|v| v.clamp(lo, hi)).collect::<Vec<_>>()))
    }

    /// Applies one set-command received at `now`.
    fn apply(&mut self, command: &Command, now: Duration) {
        match command.for_device(1) {
            Command::Values { code, values } => {
                if let Some(&value) = values.first() {
                    self.apply_value(code, value, now);
                }
            }
            Command::Regulators { code, values } => {
                let Some(&gains) = values.first() else { return };
                match code {
                    CommandCode::SetCurrentRegulator => self.current_pid.set_gains(gains),
                    CommandCode::SetSpeedRegulator => self.speed_pid.set_gains(gains),
                    CommandCode::SetPositionRegulator => self.position_pid.set_gains(gains),
                    _ => {}
                }
            }
            Command::Query { .. } | Command::Unknown { .. } => {}
        }
    }

    fn apply_value(&mut self, code: CommandCode, value: i64, now: Duration) {
        use CommandCode as C;
        let set = &mut self.set;
        match code {
            C::SetDrivesMode => {
                let Ok(raw) = u8::try_from(value) else { return };
                let mode = DriveMode::from_raw(raw, self.revision);
                if !self.inputs.enable && mode != DriveMode::Error {
                    tracing::debug!(address = self.address, ?mode, "ENABLE absent: mode change ignored");
                    return;
                }
                set.mode = mode;
                self.flags.overcurrent = false;
            }
            C::SetDrivesSpeed => set.speed = value,
            C::SetDrivesCurrent => set.current_ma = value,
            C::SetDrivesPosition => set.position = value,
            C::SetDrivesPwm => set.pwm = value,
            C::SetDrivesMaxCurrent if value > 0 => {
                set.max_current_ma = value.min(self.config.hardware_max_current_ma);
            }
            C::SetDrivesMaxSpeed if value > 0 => set.max_speed = value,
            C::SetDrivesMaxAcceleration if value > 0 => set.max_acceleration = value,
            C::SetDrivesMinPosition => set.min_position = value,
            C::SetDrivesMaxPosition => set.max_position = value,
            C::SetDrivesMisc => {
                let bits = u32::try_from(value).unwrap_or(0);
                if bits & DrivesMisc::SET_SYNCHRONIZED != 0 {
                    self.flags.synchronized = true;
                }
                if bits & DrivesMisc::RESET_SYNCHRONIZED != 0 {
                    self.flags.synchronized = false;
                }
            }
            C::SetDigitalOutputs => self.inputs.digital_outputs = (value & 0xFF) as u8,
            _ => {
                tracing::trace!(address = self.address, %code, value, "not in the 1209A buffer: skipped");
                return;
            }
        }
        // The reference's command watchdog restarts on mode and motion set-points.
        if matches!(
            code,
            C::SetDrivesMode
                | C::SetDrivesSpeed
                | C::SetDrivesCurrent
                | C::SetDrivesPosition
                | C::SetDrivesPwm
        ) {
            self.last_motion_command = now.max(self.time);
            self.flags.watchdog = false;
        }
    }
}
