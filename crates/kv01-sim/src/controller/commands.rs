//! The controller's command interpreter (`specs/faulhaber.md` §1.4, §1.5): parse, check
//! the node prefix, execute, answer (`OK` only in answer mode 2, values always, error
//! strings for what it cannot do).

use motus_kv01_protocol::faulhaber::{Command, ControllerError, Reply, Request};

use super::{Controller, Drive, Mode, MAX_ACCELERATION, MAX_CURRENT_MA};

/// Baud rates a controller accepts (`specs/faulhaber.md` §1.1).
const BAUD_RATES: [i32; 9] = [600, 1200, 2400, 4800, 9600, 19_200, 38_400, 57_600, 115_200];

impl Controller {
    fn ok(&self) -> Option<String> {
        (self.settings.answer_mode == 2).then(|| Reply::Ok.to_string())
    }

    fn error(&self, e: ControllerError) -> Option<String> {
        (self.settings.answer_mode == 2).then(|| e.text().to_owned())
    }

    /// Executes one command text (without terminator); the answer, or `None` when the
    /// controller stays silent.
    pub(crate) fn execute(&mut self, text: &str, drive: &Drive) -> Option<String> {
        let request = match Request::parse(text) {
            Ok(r) => r,
            Err(e) => return (self.settings.answer_mode == 2).then(|| e.controller_reply().to_string()),
        };
        if request.node.is_some_and(|n| n != self.settings.node) {
            return None;
        }
        let invalid = || Err(ControllerError::InvalidParameter);
        let in_range = |n: i32, lo: i32, hi: i32| if (lo..=hi).contains(&n) { Ok(()) } else { invalid() };
        let result: Result<(), ControllerError> = match request.command {
            Command::Query(q) => return Some(self.query(q, drive)),
            Command::AnalogInput(i) => {
                return match i {
                    1..=5 => Some("0".to_owned()),
                    _ => self.error(ControllerError::InvalidParameter),
                };
            }
            Command::Save | Command::EepSave => {
                self.saved = self.settings.clone();
                return Some(Reply::EepromWritingDone.to_string());
            }
            Command::Unknown(_) => Err(ControllerError::UnknownCommand),
            Command::Voltage(_) => Err(ControllerError::CommandNotAvailable),
            Command::Enable | Command::Disable => {
                self.enabled = request.command == Command::Enable;
                self.target_rpm = 0;
                self.mode = Mode::Velocity;
                self.ramp_rpm = drive.rpm;
                Ok(())
            }
            Command::Velocity(n) => in_range(n, -self.rpm_range, self.rpm_range).map(|()| {
                self.mode = Mode::Velocity;
                self.target_rpm = n.clamp(-self.settings.max_speed, self.settings.max_speed);
            }),
            Command::LoadAbsolute(n) => {
                self.loaded = i64::from(n);
                Ok(())
            }
            Command::LoadRelative(n) => {
                self.loaded = self.loaded.saturating_add(i64::from(n));
                Ok(())
            }
            Command::Move => {
                let (lo, hi) = (i64::from(self.settings.lower_limit), i64::from(self.settings.upper_limit));
                self.target_position =
                    if self.settings.limits_active { self.loaded.clamp(lo, hi) } else { self.loaded };
                self.mode = Mode::Position;
                Ok(())
            }
            Command::Home(n) => {
                let new = n.unwrap_or(0);
                let shift = self.position(drive) - i64::from(new);
                self.home_offset = drive.counts - f64::from(new);
                self.target_position = self.target_position.saturating_sub(shift);
                self.loaded = self.loaded.saturating_sub(shift);
                Ok(())
            }
            Command::NotifyPosition(_)
            | Command::NotifyPositionOff
            | Command::NotifyVelocity(_)
            | Command::NotifyVelocityOff => Ok(()),
            Command::EnableProgram | Command::Resume => {
                self.program_running = true;
                self.settings.program_enabled = true;
                Ok(())
            }
            Command::DisableProgram => {
                self.program_running = false;
                self.settings.program_enabled = false;
                Ok(())
            }
            Command::AnswerMode(n) => in_range(n, 0, 2).map(|()| {
                self.settings.answer_mode = u8::try_from(n).unwrap_or(2);
            }),
            Command::VelocitySource(n) => in_range(n, 0, 3).map(|()| self.settings.velocity_source = n),
            Command::MaxSpeed(n) => in_range(n, 0, self.rpm_range).map(|()| self.settings.max_speed = n),
            Command::Acceleration(n) => {
                in_range(n, 1, MAX_ACCELERATION).map(|()| self.settings.acceleration = n)
            }
            Command::Deceleration(n) => {
                in_range(n, 1, MAX_ACCELERATION).map(|()| self.settings.deceleration = n)
            }
            Command::PositionLimit(n) => {
                if n >= 0 {
                    self.settings.upper_limit = n;
                } else {
                    self.settings.lower_limit = n;
                }
                Ok(())
            }
            Command::ActivatePositionLimits(n) => {
                in_range(n, 0, 1).map(|()| self.settings.limits_active = n == 1)
            }
            Command::PeakCurrent(n) => {
                in_range(n, 0, MAX_CURRENT_MA).map(|()| self.settings.peak_current = n)
            }
            Command::ContinuousCurrent(n) => {
                in_range(n, 0, MAX_CURRENT_MA).map(|()| self.settings.continuous_current = n)
            }
            Command::Baud(n) => match u32::try_from(n) {
                Ok(b) if BAUD_RATES.contains(&n) => {
                    // Answered at the old rate; later traffic needs the new one.
                    let answer = self.ok();
                    self.settings.baud = b;
                    return answer;
                }
                _ => invalid(),
            },
            Command::NodeAddress(n) => match u8::try_from(n) {
                Ok(node) => {
                    self.settings.node = node;
                    Ok(())
                }
                Err(_) => invalid(),
            },
        };
        match result {
            Ok(()) => self.ok(),
            Err(e) => self.error(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::ControllerConfig;

    fn controller() -> Controller {
        Controller::new(&ControllerConfig::default(), 0.1, 7)
    }

    #[test]
    fn answers_like_answer_mode_2() {
        let mut c = controller();
        let d = Drive::default();
        assert_eq!(c.execute("EN", &d).as_deref(), Some("OK"));
        assert!(c.enabled());
        assert_eq!(c.execute("v 320", &d).as_deref(), Some("OK"));
        assert_eq!(c.target_rpm(), 320);
        assert_eq!(c.execute("V99999", &d).as_deref(), Some("Invalid parameter"));
        assert_eq!(c.execute("V", &d).as_deref(), Some("Invalid parameter"));
        assert_eq!(c.execute("FOO", &d).as_deref(), Some("Unknown command"));
        assert_eq!(c.execute("12", &d).as_deref(), Some("Unknown command"));
        assert_eq!(c.execute("U100", &d).as_deref(), Some("Command not available"));
        assert_eq!(c.execute("0POS", &d).as_deref(), Some("0"));
        assert_eq!(c.execute("3POS", &d), None, "another node's prefix: silent");
        assert_eq!(c.execute("ANSW0", &d), None);
        assert_eq!(c.execute("V100", &d), None, "no confirmation in answer mode 0");
        assert_eq!(c.execute("FOO", &d), None, "no error string in answer mode 0");
        assert_eq!(c.execute("GV", &d).as_deref(), Some("100"), "queries always answer");
        assert_eq!(c.execute("SAVE", &d).as_deref(), Some("EEPROM writing done"));
    }

    #[test]
    fn save_survives_power_cycle_and_baud_change_isolates() {
        let mut c = controller();
        let d = Drive::default();
        c.execute("DIPROG", &d);
        c.execute("SAVE", &d);
        c.execute("ENPROG", &d);
        c.power_cycle(0.0);
        assert!(!c.program_running(), "the saved DIPROG state comes back");
        assert_eq!(c.execute("BAUD19200", &d).as_deref(), Some("OK"));
        assert!(!c.listens_at(9600));
        c.power_cycle(0.0);
        assert!(c.listens_at(9600), "BAUD was not saved");
    }
}
