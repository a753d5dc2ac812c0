//! Stops have owners: who pressed the emergency stop, and who may reset it.
//!
//! Every press is recorded (user, role, time). A student may reset an E-stop pressed only
//! by students (their own, or another student's during their slot: the lab lets only the
//! slot holder reset), never one an administrator (a teacher) pressed: that one waits for an
//! administrator. Supervisor trips and drive faults are not E-stops: the slot holder resets
//! them (the machine must stay remotely recoverable).

use std::time::{SystemTime, UNIX_EPOCH};

use motus_lab::Role;

/// One press of the E-stop.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Press {
    /// Who.
    pub(crate) user: String,
    /// Their role then.
    pub(crate) role: Role,
    /// When.
    pub(crate) at: SystemTime,
}

impl Press {
    fn describe(&self) -> String {
        format!("{} ({}) at {}", self.user, self.role.as_str(), utc(self.at))
    }
}

/// The presses since the last reset.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct EStopOwners {
    /// The first press.
    first: Option<Press>,
    /// The first press by someone above a student (an administrator), if any.
    staff: Option<Press>,
    /// Presses after the first.
    more: usize,
}

impl EStopOwners {
    /// Records a press.
    pub(crate) fn press(&mut self, p: Press) {
        if p.role > Role::Student && self.staff.is_none() {
            self.staff = Some(p.clone());
        }
        if self.first.is_none() {
            self.first = Some(p);
        } else {
            self.more += 1;
        }
    }

    /// Forgets every press (after a reset).
    pub(crate) fn clear(&mut self) {
        *self = EStopOwners::default();
    }

    /// Whether a caller with `role` may reset, and if not why (names who pressed).
    pub(crate) fn may_reset(&self, role: Role) -> Result<(), String> {
        match &self.staff {
            Some(p) if role < Role::Admin => Err(format!(
                "the emergency stop was pressed by {}: only an administrator can reset it",
                p.describe()
            )),
            _ => Ok(()),
        }
    }

    /// For the safety view's diagnosis: "emergency stop by admin (admin) at ...".
    pub(crate) fn diagnosis(&self) -> String {
        let Some(first) = &self.first else { return "emergency stop".into() };
        let mut s = format!("emergency stop by {}", first.describe());
        if let Some(staff) = self.staff.as_ref().filter(|p| *p != first) {
            s.push_str(&format!(", and by {}", staff.describe()));
        }
        if self.more > 0 {
            s.push_str(&format!(" (pressed {} times)", self.more + 1));
        }
        if self.staff.is_some() {
            s.push_str("; an administrator must reset it");
        }
        s
    }
}

/// `YYYY-MM-DDTHH:MM:SSZ`.
pub(crate) fn utc(t: SystemTime) -> String {
    let secs = t.duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let days = i64::try_from(secs / 86_400).unwrap_or(0);
    let rem = secs % 86_400;
    // Howard Hinnant's civil_from_days.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z", rem / 3600, rem % 3600 / 60, rem % 60)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use std::time::Duration;

    fn press(user: &str, role: Role, secs: u64) -> Press {
        Press { user: user.into(), role, at: UNIX_EPOCH + Duration::from_secs(secs) }
    }

    #[test]
    fn formats_utc() {
        assert_eq!(utc(UNIX_EPOCH), "1970-01-01T00:00:00Z");
        assert_eq!(utc(UNIX_EPOCH + Duration::from_secs(951_782_400)), "2000-02-29T00:00:00Z");
        assert_eq!(utc(UNIX_EPOCH + Duration::from_secs(1_767_225_599)), "2025-12-31T23:59:59Z");
    }

    #[test]
    fn a_student_resets_a_students_stop_never_an_admins() {
        let mut o = EStopOwners::default();
        o.press(press("student", Role::Student, 0));
        assert!(o.may_reset(Role::Student).is_ok());
        assert_eq!(o.diagnosis(), "emergency stop by student (student) at 1970-01-01T00:00:00Z");
        // An admin presses too: the stop is the admin's now, whoever pressed first.
        o.press(press("teacher", Role::Admin, 60));
        let why = o.may_reset(Role::Student).unwrap_err();
        assert!(why.contains("teacher (admin) at 1970-01-01T00:01:00Z"), "{why}");
        assert!(why.contains("only an administrator"), "{why}");
        assert!(o.may_reset(Role::Admin).is_ok());
        assert!(o.diagnosis().contains("and by teacher (admin)"), "{}", o.diagnosis());
        // A student pressing again does not take it over.
        o.press(press("student", Role::Student, 120));
        assert!(o.may_reset(Role::Student).is_err());
        o.clear();
        assert!(o.may_reset(Role::Student).is_ok());
        assert_eq!(o.diagnosis(), "emergency stop");
        o.press(press("teacher", Role::Admin, 0));
        assert!(o.may_reset(Role::Viewer).is_err());
        assert!(o.diagnosis().ends_with("an administrator must reset it"));
    }
}
