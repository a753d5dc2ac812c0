//! What the host knows and wants of one 1209A: the intent (mode and set-point), the
//! register mirror, the trusted readings; the frame it needs this cycle, and what an
//! answer changes.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use motus_axis::{Fault, FaultKind};
use motus_nfv2_protocol::{wire_time, Command, CommandCode as C, DriveMode, DriveStatus, Frame, Revision};

use super::registers::{Reg, Registers};
use super::status::{error_cause, level_faults, StatusFilter, INPUT_ENABLE};
use super::{DriveConfig, DriveSnapshot, IntentKind};
use crate::samples::{latch_correction, Gate, GateBounds, PositionSample, SampleHistory, Verdict};
use crate::scheduler::SchedulerConfig;
use crate::stream::{lock_source, speed_command, StreamCommand, StreamLink, COUNTS_PER_S_PER_SPEED_UNIT};

/// Stream commands kept for inspection.
const STREAM_LOG: usize = 1 << 16;

/// What the host wants the drive to do.
#[derive(Debug, Clone)]
pub(crate) enum Intent {
    /// Attached, nothing commanded yet: only queries are sent.
    Unknown,
    /// Mode ERROR (bridge off) on request.
    Disabled,
    /// POSITION mode towards (or holding) `target`, counts.
    Position { target: i64 },
    /// SPEED mode at `speed` units.
    Jog { speed: i64 },
    /// HOMING until the drive reports "synchronized".
    Homing,
    /// Following a host trajectory (POS_INCREMENT, or SPEED before 2014).
    Stream(StreamLink),
    /// The drive left its mode by itself (ERROR): nothing is sent until a fault reset.
    Faulted,
}

/// The outcome of one exchange for the drive.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Outcome {
    /// A valid answer.
    Answer(Frame),
    /// The frame needed no answer (unpacked set-point frames); sent.
    Unanswered,
    /// An expected answer did not come (time-out, corrupt, wrong shape) or the link failed.
    Missed,
}

/// When and how long an exchange was on the line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Timing {
    pub(crate) request_at: Instant,
    pub(crate) reply_at: Instant,
    pub(crate) request_len: usize,
    pub(crate) baud: u32,
}

/// What an outcome did, for the statistics.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct Absorbed {
    pub(crate) answered: bool,
    pub(crate) missed: bool,
    pub(crate) rejected: bool,
}

/// One drive's runtime state (inside the scheduler's shared state).
#[derive(Debug)]
pub(crate) struct DriveRuntime {
    pub(crate) config: DriveConfig,
    pub(crate) rev: Revision,
    pub(crate) regs: Registers,
    pub(crate) intent: Intent,
    pub(crate) history: SampleHistory,
    gate: Gate,
    status: StatusFilter,
    current_ma: Option<i64>,
    inputs: Option<u8>,
    want_inputs: bool,
    /// Digital-input readings so far.
    pub(crate) inputs_read: u64,
    fault: Option<Fault>,
    fault_from_error: bool,
    last_answer: Option<Instant>,
    started: Instant,
    last_request_len: usize,
    frames: u64,
    pub(crate) stream_log: VecDeque<StreamCommand>,
}

impl DriveRuntime {
    pub(crate) fn new(config: DriveConfig, rev: Revision, sc: &SchedulerConfig, now: Instant) -> Self {
        DriveRuntime {
            config,
            rev,
            regs: Registers::default(),
            intent: Intent::Unknown,
            history: SampleHistory::new(sc.history, sc.where_margin, sc.max_gap)
                .with_max_delay(sc.where_max_delay)
                .with_still_band(sc.where_still_band),
            gate: Gate::default(),
            status: StatusFilter::default(),
            current_ma: None,
            inputs: None,
            want_inputs: true,
            inputs_read: 0,
            fault: None,
            fault_from_error: false,
            last_answer: None,
            started: now,
            last_request_len: 15,
            frames: 0,
            stream_log: VecDeque::new(),
        }
    }

    pub(crate) fn address(&self) -> u8 {
        self.config.address
    }

    /// The raw byte of `mode` in this drive's revision.
    pub(crate) fn mode_raw(&self, mode: DriveMode) -> Option<i64> {
        mode.to_raw(self.rev).map(i64::from)
    }

    /// The homing mode of this revision (HOMING in 2014, SYNC_POS0 before).
    pub(crate) fn homing_raw(&self) -> Option<i64> {
        self.mode_raw(DriveMode::Homing).or_else(|| self.mode_raw(DriveMode::SyncPos0))
    }

    /// The streaming mode of this revision (POS_INCREMENT in 2014, SPEED before).
    pub(crate) fn stream_raw(&self) -> Option<i64> {
        self.mode_raw(DriveMode::PosIncrement).or_else(|| self.mode_raw(DriveMode::Speed))
    }

    /// The acceleration the drive ramps with (as last set by us, else its power-on value).
    pub(crate) fn acceleration(&self) -> f64 {
        let a = self.regs.value(Reg::MaxAcceleration).or(self.regs.confirmed(Reg::MaxAcceleration));
        a.unwrap_or(self.config.device_acceleration) as f64
    }

    pub(crate) fn status(&self) -> Option<DriveStatus> {
        self.status.status()
    }

    pub(crate) fn inputs(&self) -> Option<u8> {
        self.inputs
    }

    /// Reads the digital inputs in the next frame.
    pub(crate) fn request_inputs(&mut self) {
        self.want_inputs = true;
    }

    pub(crate) fn fault(&self) -> Option<&Fault> {
        self.fault.as_ref()
    }

    fn set_mode(&mut self, raw: i64) {
        self.regs.set(Reg::Mode, raw);
    }

    /// POSITION mode towards `target` at the default profile speed.
    pub(crate) fn hold_at(&mut self, target: i64) {
        self.position(target, self.config.speed, None);
    }

    /// POSITION mode towards `target` at `speed` units, `acceleration` counts/s².
    pub(crate) fn position(&mut self, target: i64, speed: i64, acceleration: Option<i64>) {
        if let Some(a) = acceleration {
            self.regs.set(Reg::MaxAcceleration, a);
        }
        self.regs.set(Reg::Speed, speed.abs().max(1));
        self.regs.every_cycle(Reg::Speed, false);
        self.regs.set(Reg::Position, target);
        self.regs.every_cycle(Reg::Position, true);
        if let Some(raw) = self.mode_raw(DriveMode::Position) {
            self.set_mode(raw);
        }
        self.intent = Intent::Position { target };
    }

    /// SPEED mode at `speed` units.
    pub(crate) fn jog(&mut self, speed: i64, acceleration: Option<i64>) {
        if let Some(a) = acceleration {
            self.regs.set(Reg::MaxAcceleration, a);
        }
        self.regs.release(Reg::Position);
        self.regs.set(Reg::Speed, speed);
        self.regs.every_cycle(Reg::Speed, true);
        if let Some(raw) = self.mode_raw(DriveMode::Speed) {
            self.set_mode(raw);
        }
        self.intent = Intent::Jog { speed };
    }

    /// HOMING mode.
    pub(crate) fn home(&mut self) {
        self.regs.release(Reg::Position);
        self.regs.release(Reg::Speed);
        if let Some(raw) = self.homing_raw() {
            if !matches!(self.intent, Intent::Homing) {
                self.regs.force(Reg::Mode);
            }
            self.set_mode(raw);
        }
        self.intent = Intent::Homing;
    }

    /// Follow `link`'s source.
    pub(crate) fn stream(&mut self, link: StreamLink) {
        self.regs.release(Reg::Position);
        self.regs.set(Reg::Speed, 0);
        self.regs.every_cycle(Reg::Speed, true);
        if let Some(raw) = self.stream_raw() {
            self.set_mode(raw);
        }
        self.intent = Intent::Stream(link);
    }

    /// Mode ERROR (bridge off).
    pub(crate) fn disable(&mut self) {
        self.regs.release(Reg::Position);
        self.regs.release(Reg::Speed);
        if let Some(raw) = self.mode_raw(DriveMode::Error) {
            self.set_mode(raw);
        }
        self.intent = Intent::Disabled;
    }

    /// Decelerates to rest at `acceleration` (counts/s²; the drive's setting if `None`).
    pub(crate) fn stop(&mut self, acceleration: Option<i64>) {
        if let Some(a) = acceleration {
            self.regs.set(Reg::MaxAcceleration, a);
        }
        let Some(latest) = self.history.latest() else { return };
        let v = self.history.velocity().unwrap_or(0.0);
        let a = self.acceleration().max(1.0);
        let stop_at = latest.counts + (v * v.abs() / (2.0 * a)).round() as i64;
        match self.intent {
            Intent::Jog { .. } => {
                self.regs.set(Reg::Speed, 0);
                self.intent = Intent::Jog { speed: 0 };
            }
            Intent::Position { .. } => {
                self.regs.set(Reg::Position, stop_at);
                self.intent = Intent::Position { target: stop_at };
            }
            Intent::Stream(_) | Intent::Homing => self.hold_at(stop_at),
            Intent::Unknown | Intent::Disabled | Intent::Faulted => {}
        }
    }

    /// Clears the host's fault latch and holds the present position.
    pub(crate) fn fault_reset(&mut self) -> Result<(), String> {
        if self.inputs.is_some_and(|i| i & INPUT_ENABLE == 0) {
            return Err("the ENABLE input is absent (E-stop loop open): close it before a fault reset".into());
        }
        self.fault = None;
        self.fault_from_error = false;
        let Some(latest) = self.history.latest() else {
            return Err("no position reading yet".into());
        };
        self.regs.force(Reg::Mode);
        self.hold_at(latest.counts);
        Ok(())
    }

    /// Latches a fault raised by the drive's own ERROR: stop sending set-points.
    fn latch(&mut self, fault: Fault) {
        tracing::warn!(address = self.address(), reason = %fault.reason, "1209A fault");
        self.fault_from_error = true;
        self.want_inputs |= fault.kind == FaultKind::Other;
        self.fault = Some(fault);
        self.regs.release(Reg::Position);
        self.regs.release(Reg::Speed);
        if let Some(raw) = self.mode_raw(DriveMode::Error) {
            self.set_mode(raw);
        }
        self.intent = Intent::Faulted;
    }

    /// The frame for this cycle.
    pub(crate) fn build(
        &mut self,
        seq: u64,
        now: Instant,
        cycle: u64,
        period: Duration,
        baud: u32,
        sc: &SchedulerConfig,
    ) -> Frame {
        if let Intent::Stream(link) = &self.intent {
            let link = link.clone();
            let mut source = lock_source(&link.source);
            if source.finished(now) {
                let target = source.position(link.index, now).round() as i64;
                drop(source);
                self.position(target, link.max_units, None);
            } else {
                let delivery = wire_time(self.last_request_len, baud) + Duration::from_micros(500);
                let previous = self.regs.value(Reg::Speed).unwrap_or(0) as f64 * COUNTS_PER_S_PER_SPEED_UNIT;
                let acceleration = self.acceleration();
                let latest = self.history.latest();
                let command =
                    speed_command(&link, &mut *source, now, delivery, period, latest, previous, acceleration);
                drop(source);
                self.regs.set(Reg::Speed, command.speed_units);
                if self.stream_log.len() == STREAM_LOG {
                    self.stream_log.pop_front();
                }
                self.stream_log.push_back(command);
            }
        }
        let mut frame = Frame::new(self.address());
        for (r, v) in self.regs.due() {
            let command = Command::values(r.code(), [v]);
            if let Err(e) = command.encoded_len(self.rev) {
                tracing::warn!(address = self.address(), error = %e, "set-point not sent");
                self.regs.release(r);
                continue;
            }
            frame.commands.push(command);
            self.regs.sent(seq, r, v);
        }
        // NFv2 answers carry no sequence number: after a time-out, or when the slave's
        // decoder was held up by noise, the answer to an earlier frame may still come. The
        // queries rotate through three orders of equal length, so an answer to either of the
        // two previous frames cannot pass for this one's (the answer shape includes the
        // order): position and drive status, drive status and position, position and
        // device status (`ReadDeviceStatus`: ERROR, supply, over-current, watchdog bits).
        self.frames += 1;
        let position = |f: &mut Frame| {
            f.commands.push(Command::query(C::ReadDrivesPosition));
            if sc.verify_position {
                f.commands.push(Command::query(C::ReadDrivesPosition));
            }
        };
        match self.frames % 3 {
            0 => {
                position(&mut frame);
                frame.commands.push(Command::query(C::ReadDrivesStatus));
            }
            1 => {
                frame.commands.push(Command::query(C::ReadDrivesStatus));
                position(&mut frame);
            }
            _ => {
                position(&mut frame);
                frame.commands.push(Command::query(C::ReadDeviceStatus));
            }
        }
        if sc.current_every > 0 && cycle % u64::from(sc.current_every) == 0 {
            frame.commands.push(Command::query(C::ReadDrivesCurrent));
        }
        // Half a period out of phase with the current, so one frame carries at most one
        // of them (a long answer shifts the midpoint timestamp of its sample).
        let inputs_due =
            sc.inputs_every > 0 && (cycle + u64::from(sc.inputs_every / 2)) % u64::from(sc.inputs_every) == 0;
        if self.want_inputs || inputs_due {
            frame.commands.push(Command::query(C::ReadDigitalInputs));
        }
        self.last_request_len = frame.encoded_len(self.rev).unwrap_or(self.last_request_len);
        frame
    }

    fn gate_bounds(&self) -> GateBounds {
        GateBounds {
            speed: self.config.plausible_speed,
            acceleration: 2.0 * self.acceleration() + self.config.plausible_extra_acceleration,
            base: 16.0,
            jitter: Duration::from_millis(1),
        }
    }

    /// Takes the outcome of the exchange of frame `seq`.
    pub(crate) fn absorb(
        &mut self,
        seq: u64,
        outcome: Outcome,
        timing: Timing,
        sc: &SchedulerConfig,
    ) -> Absorbed {
        let mut result = Absorbed::default();
        match outcome {
            Outcome::Missed => {
                self.regs.lost(seq);
                result.missed = true;
            }
            Outcome::Unanswered => self.regs.confirm(seq),
            Outcome::Answer(answer) => {
                self.regs.confirm(seq);
                self.last_answer = Some(timing.reply_at);
                result.answered = true;
                let answer_len = answer.encoded_len(self.rev).unwrap_or(timing.request_len);
                let correction = latch_correction(
                    wire_time(timing.request_len, timing.baud),
                    wire_time(answer_len, timing.baud),
                    sc.turnaround,
                    sc.latch_age,
                );
                result.rejected = !self.read(&answer, seq, timing, correction);
            }
        }
        self.evaluate();
        result
    }

    /// Reads the values of an answer; false if its position was rejected.
    fn read(&mut self, answer: &Frame, seq: u64, timing: Timing, correction: Duration) -> bool {
        let mut accepted = true;
        let positions: Vec<i64> = answer
            .commands
            .iter()
            .filter(|c| c.code() == C::ReadDrivesPosition)
            .filter_map(|c| c.int_values().and_then(|v| v.first().copied()))
            .collect();
        if let Some(&counts) = positions.first() {
            if positions.iter().all(|&p| p == counts) {
                let sample = PositionSample::new(timing.request_at, timing.reply_at, counts, correction);
                let bounds = self.gate_bounds();
                match self.gate.check(sample, &bounds) {
                    Verdict::Accept => self.history.push(sample),
                    Verdict::Reject => accepted = false,
                }
            } else {
                accepted = false;
            }
        }
        let first = |code| answer.int_values(code).and_then(|v| v.first().copied());
        if let Some(word) = first(C::ReadDrivesStatus).and_then(|w| u16::try_from(w).ok()) {
            self.status.push(word, seq);
        }
        if let Some(ma) = first(C::ReadDrivesCurrent).filter(|ma| ma.abs() <= 30_000) {
            self.current_ma = Some(ma);
        }
        if let Some(bits) = first(C::ReadDigitalInputs).and_then(|b| u8::try_from(b).ok()) {
            self.inputs = Some(bits);
            self.inputs_read += 1;
            self.want_inputs = false;
        }
        accepted
    }

    /// Homing completion, unexpected ERROR, the cause of an E-stop.
    fn evaluate(&mut self) {
        let Some(status) = self.status.status() else { return };
        let mode_set = self.regs.value(Reg::Mode);
        let delivered = mode_set.is_some() && mode_set == self.regs.confirmed(Reg::Mode);
        let after_mode = match (self.status.since(), self.regs.mode_confirmed_seq) {
            (Some(since), Some(mode_seq)) => delivered && since > mode_seq,
            _ => false,
        };
        let active = matches!(
            self.intent,
            Intent::Position { .. } | Intent::Jog { .. } | Intent::Homing | Intent::Stream(_)
        );
        if active && after_mode && status.contains(DriveStatus::ERROR) {
            self.latch(error_cause(status, self.inputs));
            return;
        }
        if matches!(self.intent, Intent::Homing) && after_mode && status.contains(DriveStatus::SYNCHRONIZED) {
            tracing::info!(address = self.address(), "homed (synchronized)");
            if let Some(latest) = self.history.latest() {
                self.hold_at(latest.counts);
            }
        }
        if self.fault_from_error && self.fault.as_ref().is_some_and(|f| f.kind == FaultKind::Other) {
            let refined = error_cause(status, self.inputs);
            if refined.kind == FaultKind::EmergencyStop {
                self.fault = Some(refined);
            }
        }
    }

    /// The snapshot the handles read at `now` (silence is measured up to it).
    pub(crate) fn snapshot(&self, silence: Duration, now: Instant) -> DriveSnapshot {
        let latest = self.history.latest();
        let velocity = self.history.velocity();
        let status = self.status.status();
        let speed = velocity.unwrap_or(0.0).abs();
        let at_rest = speed <= self.config.standstill;
        let (kind, target) = match &self.intent {
            Intent::Unknown => (IntentKind::Unknown, None),
            Intent::Disabled => (IntentKind::Disabled, None),
            Intent::Position { target } => (IntentKind::Position, Some(*target)),
            Intent::Jog { .. } => (IntentKind::Jog, None),
            Intent::Homing => (IntentKind::Homing, None),
            Intent::Stream(_) => (IntentKind::Stream, None),
            Intent::Faulted => (IntentKind::Faulted, None),
        };
        // The drive clamps a target outside its position limits (when min < max).
        let target = target.map(|t| {
            match (self.regs.confirmed(Reg::MinPosition), self.regs.confirmed(Reg::MaxPosition)) {
                (Some(lo), Some(hi)) if lo < hi => t.clamp(lo, hi),
                _ => t,
            }
        });
        let off_target = match (target, latest) {
            (Some(t), Some(s)) => (t - s.counts).abs() > self.config.tolerance,
            (Some(_), None) => true,
            _ => false,
        };
        let moving = match &self.intent {
            // Until the drive has the target, the move has not begun, let alone ended.
            Intent::Position { .. } => off_target || !at_rest || !self.regs.settled(),
            Intent::Jog { speed } => *speed != 0 || !at_rest,
            Intent::Homing | Intent::Stream(_) => true,
            _ => !at_rest,
        };
        let mut faults: Vec<Fault> = self.fault.iter().cloned().collect();
        if let Some(s) = status {
            faults.extend(level_faults(s));
        }
        let since_answer = now.saturating_duration_since(self.last_answer.unwrap_or(self.started));
        if since_answer > silence {
            faults.push(Fault {
                kind: FaultKind::CommunicationTimeout,
                reason: format!("no valid answer from address {} for {since_answer:.0?}", self.address()),
            });
        }
        DriveSnapshot {
            address: self.address(),
            position: latest,
            velocity,
            status,
            raw_status: self.status.raw(),
            current_ma: self.current_ma,
            inputs: self.inputs,
            intent: kind,
            target,
            enabled: status.is_some_and(|s| !s.contains(DriveStatus::ERROR))
                && self.fault.is_none()
                && !matches!(self.intent, Intent::Disabled | Intent::Faulted),
            homed: status.is_some_and(|s| s.contains(DriveStatus::SYNCHRONIZED)),
            moving,
            target_reached: target.is_some() && !moving,
            limit_up: status.is_some_and(|s| s.contains(DriveStatus::LIMIT_SWITCH_UP)),
            limit_down: status.is_some_and(|s| s.contains(DriveStatus::LIMIT_SWITCH_DOWN)),
            faults,
            settled: self.regs.settled(),
            last_answer: self.last_answer,
        }
    }
}
