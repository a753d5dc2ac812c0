//! What a module does with each request (`specs/kv01.md`, "Commands"): D0 through the
//! LSSTOP / restricted-mode filter to the controller (or "TIMEOUT"), D1 brake / restricted
//! mode (0xE6: current limitation), D2 fast message, D3 resolver, D4 voltages, D5 gripper,
//! "UC" for what it does not know and "TO" once the safety time-out has tripped.
//!
//! Choices where the source is silent:
//! - Only the `V` command is a "speed command" the filter blocks (parsed like the
//!   controller does, so `v 500` and `0V500` count).
//! - A D1 byte the module does not know (0xC0/0xC1 on joints, 0xB*/0xA* on the gripper),
//!   D5 on joints, D0/D2 without data, and any other command code are answered "UC".
//! - D2 forwards its text without waiting for the controller's answer (that is what makes
//!   it fast): the reply comes after the turnaround, even with a slow or unreachable
//!   controller. A blocked D2 speed command is answered per [`D2Refusal`].
//! - The controller's answer must arrive within the module's wait, counted from the end of
//!   the forwarded request (`CR` added, 9600 Bd); otherwise "TIMEOUT" after the wait. The
//!   command has still reached the controller.
//! - 0xA0 leaves restricted mode and clears LSSTOP when the switch is released; while it
//!   is pressed, 0xA0 changes nothing (the reply shows the unchanged bits).
//! - On the gripper module the D3 status bit "brake released" is the open/close motor's
//!   software brake (BRAKE); the other three bits are 0.

use std::time::Duration;

use motus_kv01_protocol::{
    faulhaber, Answer, Command, D1Action, JointStatus, Reply, ReplyBody, Request, ResolverReading, ShortCode,
};
use motus_serial::LineSettings;

use super::{Module, TimedReply};
use crate::config::{millis, D2Refusal};
use crate::supply;

impl Module {
    /// Answers `request` at time `now` (advancing first); `None` when it is not for this
    /// module or the module is deaf.
    pub fn handle(&mut self, request: &Request, now: Duration) -> Option<Reply> {
        self.respond(request, now).map(|r| r.reply)
    }

    /// Like [`Self::handle`], with the time the reply is due after the request.
    pub fn respond(&mut self, request: &Request, now: Duration) -> Option<TimedReply> {
        if request.address != self.address {
            return None;
        }
        self.advance_to(now);
        self.check_safety_timeout(now);
        if self.faults.deaf {
            return None;
        }
        let turnaround = millis(self.cm.turnaround_ms);
        if self.timed_out {
            return Some(self.timed(ReplyBody::Short { text: ShortCode::Timeout }, turnaround));
        }
        self.last_message = Some(now);
        let uc = ReplyBody::Short { text: ShortCode::UnknownCommand };
        let (body, delay) = match &request.command {
            Command::Faulhaber { text } if text.is_empty() => (uc, turnaround),
            Command::Fast { text } if text.is_empty() => (uc, turnaround),
            Command::Faulhaber { text } => match self.refusal(text) {
                Some(answer) => (ReplyBody::Faulhaber { answer }, turnaround),
                None => {
                    let (answer, wait) = self.forward(text);
                    (ReplyBody::Faulhaber { answer }, turnaround + wait)
                }
            },
            Command::Fast { text } => match (self.refusal(text), self.cm.d2_refusal) {
                (Some(answer), D2Refusal::Answer) => (ReplyBody::Faulhaber { answer }, turnaround),
                (Some(_), D2Refusal::Resolver) => (ReplyBody::FastResolver(self.reading()), turnaround),
                (None, _) => {
                    self.forward(text);
                    (ReplyBody::FastResolver(self.reading()), turnaround)
                }
            },
            Command::BrakeLimit(action) => (self.d1(*action).unwrap_or(uc), turnaround),
            Command::ReadResolver => (ReplyBody::Resolver(self.reading()), turnaround),
            Command::ReadVoltages => {
                (ReplyBody::Voltages(supply::measure(&self.supply, &mut self.rng)), turnaround)
            }
            Command::Gripper { speed, opening } => match &mut self.gripper {
                Some(g) => {
                    g.command(*speed, *opening);
                    (ReplyBody::Gripper(g.load()), turnaround)
                }
                None => (uc, turnaround),
            },
            Command::Other { .. } => (uc, turnaround),
        };
        Some(self.timed(body, delay))
    }

    fn timed(&self, body: ReplyBody, delay: Duration) -> TimedReply {
        TimedReply { reply: Reply::new(self.address, body), delay }
    }

    /// The module's own answer to a speed command it blocks, if it does.
    fn refusal(&self, text: &str) -> Option<Answer> {
        let rpm = faulhaber::Request::parse(text).ok()?.velocity()?;
        if self.restricted {
            (rpm.unsigned_abs() > self.cm.restricted_rpm.unsigned_abs()).then_some(Answer::LimVal)
        } else {
            self.lsstop.then_some(Answer::LsStop)
        }
    }

    /// Sends `text` to the controller; its answer (or "TIMEOUT") and the time the exchange
    /// took, from the end of the host's request.
    fn forward(&mut self, text: &str) -> (Answer, Duration) {
        let link = LineSettings::n81(self.cm.controller_baud);
        let request_time = link.wire_time(text.chars().count() + 1);
        let answer = if self.controller.listens_at(self.cm.controller_baud) {
            let drive = self.joint.drive(self.demand, self.controller.current_limits());
            self.controller.execute(text, &drive)
        } else {
            None
        };
        let wait = millis(self.cm.controller_wait_ms);
        let latency = millis(self.cm.controller_latency_ms) + self.faults.controller_delay;
        match answer {
            Some(a) => {
                let answer_time = latency + link.wire_time(a.chars().count() + 2);
                if answer_time <= wait {
                    return (Answer::parse(&a), request_time + answer_time);
                }
                (Answer::Timeout, request_time + wait)
            }
            None => (Answer::Timeout, request_time + wait),
        }
    }

    fn joint_status(&self) -> JointStatus {
        if let Some(g) = &self.gripper {
            return JointStatus { brake_released: g.status().brake_released, ..JointStatus::default() };
        }
        JointStatus {
            brake_released: self.brake_released,
            limit_switch: self.joint.switch().is_some(),
            lsstop: self.lsstop,
            restricted_mode: self.restricted,
        }
    }

    fn reading(&self) -> ResolverReading {
        ResolverReading { position: self.resolver_raw(), status: self.joint_status() }
    }

    /// D1: the status reply, or `None` for a byte this module does not know ("UC").
    fn d1(&mut self, action: D1Action) -> Option<ReplyBody> {
        if let Some(g) = &mut self.gripper {
            match action {
                D1Action::EnableCurrentLimit => g.set_current_limit(true),
                D1Action::DisableCurrentLimit => g.set_current_limit(false),
                _ => return None,
            }
            return Some(ReplyBody::GripperStatus(g.status()));
        }
        match action {
            D1Action::ReleaseBrake => self.brake_released = true,
            D1Action::EngageBrake => self.brake_released = false,
            D1Action::EnterRestrictedMode => self.restricted = true,
            D1Action::LeaveRestrictedMode => {
                if self.joint.switch().is_none() {
                    self.restricted = false;
                    self.lsstop = false;
                }
            }
            _ => return None,
        }
        Some(ReplyBody::Status(self.joint_status()))
    }
}
