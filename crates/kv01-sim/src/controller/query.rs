//! Answers to the controller's queries (`specs/faulhaber.md` §1.4 "Queries"): values from
//! the simulated drive and settings, status words with the bits the model knows.
//!
//! Inputs: the joint's limit switch is wired to input 1 (OST bit 8, GST position 6, SWS
//! hard-limit bit 16, "fired" bit 24). The temperature is an instantaneous estimate from
//! the current (no thermal model). Values a real unit would report from hardware the model
//! lacks (PWM, analog inputs) read 0.

use motus_kv01_protocol::faulhaber::status::OperationStatus;
use motus_kv01_protocol::faulhaber::Query;

use super::{Controller, Drive, Mode};

/// Free program memory, words (a fixed plausible value).
const FREE_MEMORY_WORDS: i64 = 1536;

fn flags(bits: &[bool]) -> String {
    bits.iter().map(|&b| if b { '1' } else { '0' }).collect()
}

impl Controller {
    /// Current at or above the continuous limit: the current limitation is active.
    fn current_limited(&self, drive: &Drive) -> bool {
        let (_, continuous) = self.current_limits();
        continuous > 0.0 && drive.current_ma.abs() >= continuous * 0.99
    }

    fn operation_status(&self, drive: &Drive) -> u32 {
        let mut bits = 0;
        let mut set = |on: bool, mask: u32| {
            if on {
                bits |= mask;
            }
        };
        set(self.program_running, OperationStatus::PROGRAM_RUNNING);
        set(self.current_limited(drive), OperationStatus::CURRENT_LIMITED);
        set(drive.switch, 1 << 8);
        set(self.target_reached(drive), OperationStatus::POSITION_ATTAINED);
        bits
    }

    /// The answer to query `q`.
    pub(super) fn query(&self, q: Query, drive: &Drive) -> String {
        let s = &self.settings;
        let value: i64 = match q {
            Query::Position => self.position(drive),
            Query::TargetPosition => self.target_position,
            Query::TargetVelocity => i64::from(self.target_rpm),
            Query::Velocity => drive.rpm.round() as i64,
            Query::Pwm => 0,
            Query::ControllerOutput | Query::Current => drive.current_ma.round() as i64,
            Query::CurrentLimit => i64::from(s.continuous_current),
            Query::Temperature => {
                let (_, continuous) = self.current_limits();
                let load =
                    if continuous > 0.0 { (drive.current_ma / continuous).abs().min(2.0) } else { 0.0 };
                (25.0 + 20.0 * load * load).round() as i64
            }
            Query::OperationStatus => i64::from(self.operation_status(drive)),
            Query::Status => {
                return flags(&[
                    self.mode == Mode::Position,
                    s.velocity_source != 0,
                    s.velocity_source == 2,
                    self.enabled,
                    self.target_reached(drive),
                    true,
                    drive.switch,
                ]);
            }
            Query::FaultStatus => return flags(&[false, self.current_limited(drive), false, false]),
            Query::AdditionalStatus => return flags(&[false, false, false, false]),
            Query::SwitchSettings => 1 << 16 | if drive.switch { 1 << 24 } else { 0 },
            Query::ConfigurationStatus => {
                i64::from(s.answer_mode) << 1
                    | i64::from(self.enabled) << 10
                    | i64::from(s.limits_active) << 13
            }
            Query::Version => return self.version.clone(),
            Query::Type => return self.type_name.clone(),
            Query::SerialNumber => i64::from(self.serial),
            Query::NodeAddress => i64::from(s.node),
            Query::MaxSpeed => i64::from(s.max_speed),
            Query::Acceleration => i64::from(s.acceleration),
            Query::Deceleration => i64::from(s.deceleration),
            Query::PositiveLimit => i64::from(s.upper_limit),
            Query::NegativeLimit => i64::from(s.lower_limit),
            Query::PeakCurrent => i64::from(s.peak_current),
            Query::ContinuousCurrent => i64::from(s.continuous_current),
            Query::Memory => FREE_MEMORY_WORDS,
        };
        value.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::ControllerConfig;

    #[test]
    fn status_words() {
        let mut c = Controller::new(&ControllerConfig::default(), 0.1, 7);
        let d = Drive { counts: 1234.4, rpm: -99.6, current_ma: 700.0, switch: true };
        assert_eq!(c.query(Query::Status, &d), "0000011");
        c.execute("EN", &d);
        assert_eq!(c.query(Query::Status, &d), "0001011");
        assert_eq!(c.query(Query::Position, &d), "1234");
        assert_eq!(c.query(Query::Velocity, &d), "-100");
        assert_eq!(c.query(Query::FaultStatus, &d), "0100");
        // Program running (bit 1), current limited (bit 4), input 1 (bit 8).
        assert_eq!(c.query(Query::OperationStatus, &d), (2 + 16 + 256).to_string());
        // ANSW2 (bits 1-2 = 2 -> bit 2), enabled (bit 10).
        assert_eq!(c.query(Query::ConfigurationStatus, &d), (4 + 1024).to_string());
        assert_eq!(c.query(Query::SerialNumber, &d), "7");
    }
}
