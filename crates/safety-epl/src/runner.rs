//! [`OnlineSupervisor`]: the supervisor in the loop of a POWERLINK segment.
//!
//! Every received frame goes through [`OnlineSupervisor::on_frame`]: a SoC starts a new
//! supervisor cycle (sample ages are counted in SoCs), a PRes of a supervised node updates its
//! axes' samples. Both re-evaluate the rules at once and apply the decision through the
//! [`Fanout`]: the first unsafe decision quick-stops every target before `on_frame` returns.
//! Between frames, [`OnlineSupervisor::tick`] stops the targets when the last lease expired
//! (no frames: stale data is unsafe, and a silent segment must not keep drives running).
//!
//! As a safety node ([`OnlineSupervisor::with_safety_node`]) the supervisor is also a CN of
//! the segment: the loop gives the node every frame before evaluating it, and the node
//! publishes the decision in its PRes ([`crate::safety_node`]).
//!
//! Time comes from a [`motus_clock::Clock`] ([`OnlineSupervisor::with_clock`]; the system
//! clock by default): the reaction time, the lease checks between frames, and the waits of
//! [`OnlineSupervisor::run`] on its link. On a threaded [`motus_clock::VirtualClock`] shared
//! with an in-process segment ([`motus_epl::transport::MemHub::with_clock`]), the loop that
//! `motus safety run` and the station run is tested on virtual time.

use motus_realtime::MailboxReceiver;
use std::io;
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use motus_clock::{SharedClock, SystemClock};
use motus_epl::sim::Percentiles;
use motus_epl::EthLink;
use motus_epl_protocol::{EplFrame, Message};
use motus_safety::{CycleInput, Fanout, Mode, Restart, RuleSet, Sample, StopTarget, Supervisor};

use crate::inputs::InputMap;
use crate::safety_node::SafetyNode;

/// Options of the online supervisor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OnlineConfig {
    /// Operating mode (set by the station, never by a student program).
    pub mode: Mode,
    /// After a stop: wait for [`OnlineSupervisor::reset`] (default) or resume by itself.
    pub restart: Restart,
}

impl Default for OnlineConfig {
    fn default() -> Self {
        Self { mode: Mode::Normal, restart: Restart::Manual }
    }
}

/// A change of SafeToRun.
#[derive(Debug, Clone, PartialEq)]
pub enum OnlineEvent {
    /// SafeToRun became true.
    Safe {
        /// Supervisor cycle (SoC count).
        cycle: u64,
        /// The drives stay stopped until [`OnlineSupervisor::reset`] (manual restart).
        held: bool,
    },
    /// SafeToRun fell (or was false at the first evaluation).
    Unsafe {
        /// Supervisor cycle (SoC count).
        cycle: u64,
        /// Why (the first failing rule with predicted distances, stale data, or the
        /// configuration changes).
        diagnosis: String,
        /// Time from the reception of the frame to the stop leaving Motus (all targets told).
        reaction: Option<Duration>,
        /// Targets that failed to stop.
        errors: Vec<String>,
    },
}

/// A command to a running supervisor ([`OnlineSupervisor::run`]), sent through its channel
/// by the operator (`motus safety run`'s standard input, the station's stop and reset), by
/// the [`crate::IntegrityWatcher`], or by the station installing an administrator's rules.
#[derive(Debug)]
pub enum Command {
    /// Operator stop: every target stops now ([`OnlineSupervisor::stop_all`]).
    StopAll,
    /// Operator reset after a stop (manual restart; [`OnlineSupervisor::reset`]).
    Reset,
    /// A fresh integrity check of the configuration (`Err` names what is wrong).
    Integrity(Result<(), String>),
    /// New approved rules: every target is stopped and held until a reset
    /// ([`OnlineSupervisor::replace_rules`]); ignored when they equal the running rules.
    Rules {
        /// The rules.
        rules: Box<RuleSet>,
        /// Their inputs (the segment's value map for the rules' nodes).
        inputs: Box<InputMap>,
    },
}

/// What [`OnlineSupervisor::run`] reports to its caller.
#[derive(Debug, Clone, PartialEq)]
pub enum ServeEvent {
    /// SafeToRun changed, or the targets were stopped.
    Online(OnlineEvent),
    /// The integrity result changed (`Err` names what is wrong).
    Integrity(Result<(), String>),
    /// New rules were installed (the targets are stopped and held).
    RulesInstalled,
    /// An operator reset was applied.
    Reset,
    /// An operator stop was applied.
    Stopped,
    /// The end of one pass of the loop (a frame, or `poll` without one).
    Pass,
}

/// Reaction times collected by an [`OnlineSupervisor`].
#[derive(Debug, Clone, Default)]
pub struct ReactionStats {
    /// One entry per stop caused by a frame: ns from its reception to the stop sent.
    pub samples_ns: Vec<u64>,
}

impl ReactionStats {
    /// p50/p99/max.
    pub fn percentiles(&self) -> Percentiles {
        Percentiles::of(&self.samples_ns)
    }
}

/// The supervisor in the loop of a segment (see the module documentation).
pub struct OnlineSupervisor {
    supervisor: Supervisor,
    inputs: InputMap,
    fanout: Fanout,
    samples: Vec<Option<Sample>>,
    cycle: u64,
    origin: Instant,
    config: OnlineConfig,
    integrity: Result<(), String>,
    safe: Option<bool>,
    reaction: ReactionStats,
    frames: u64,
    integrity_checks: u64,
    clock: SharedClock,
    node: Option<SafetyNode>,
}

impl OnlineSupervisor {
    /// A supervisor for `rules` fed by `inputs`, stopping `targets`; `origin` is the epoch of
    /// lease times (give the same one to an [`crate::EplLeaseTarget`]). Integrity starts as
    /// "not checked": call [`OnlineSupervisor::set_integrity`] before anything may run.
    pub fn new(
        rules: RuleSet,
        inputs: InputMap,
        targets: Vec<Box<dyn StopTarget>>,
        origin: Instant,
        config: OnlineConfig,
    ) -> Self {
        let n = rules.axes().len();
        Self {
            supervisor: Supervisor::new(rules),
            inputs,
            fanout: Fanout::new(targets).with_restart(config.restart),
            samples: vec![None; n],
            cycle: 0,
            origin,
            config,
            integrity: Err("configuration integrity not checked yet".into()),
            safe: None,
            reaction: ReactionStats::default(),
            frames: 0,
            integrity_checks: 0,
            clock: SystemClock::shared(),
            node: None,
        }
    }

    /// Takes part in the segment as `node`, a safety node whose target is among this
    /// supervisor's targets ([`SafetyNode::new`]): [`OnlineSupervisor::run`] gives it every
    /// frame first (a PReq for it is answered with the decision of the frames before) and
    /// polls it on every pass.
    #[must_use]
    pub fn with_safety_node(mut self, node: SafetyNode) -> Self {
        self.node = Some(node);
        self
    }

    /// The safety node, when the supervisor is one.
    pub fn safety_node(&self) -> Option<&SafetyNode> {
        self.node.as_ref()
    }

    /// The safety node, to take its events.
    pub fn safety_node_mut(&mut self) -> Option<&mut SafetyNode> {
        self.node.as_mut()
    }

    /// Runs on `clock` (the link's and the lease target's; `origin` is an instant of it).
    #[must_use]
    pub fn with_clock(mut self, clock: SharedClock) -> Self {
        self.clock = clock;
        self
    }

    /// The clock.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }

    /// Installs new rules (an administrator's approved change): every target is stopped
    /// first and held (manual restart), the samples start afresh and the integrity counts as
    /// unchecked until the next [`OnlineSupervisor::set_integrity`].
    pub fn replace_rules(&mut self, rules: RuleSet, inputs: InputMap) {
        self.fanout.stop_all();
        self.samples = vec![None; rules.axes().len()];
        self.supervisor = Supervisor::new(rules);
        self.inputs = inputs;
        self.integrity = Err("new rules installed: integrity not checked yet".into());
        self.safe = Some(false);
    }

    /// The outcome of the last integrity check (`Err` names what changed).
    pub fn set_integrity(&mut self, result: Result<(), String>) {
        self.integrity = result;
    }

    /// Changes the mode (the station's homing procedure).
    pub fn set_mode(&mut self, mode: Mode) {
        self.config.mode = mode;
    }

    /// Current SafeToRun (`None` before the first evaluation).
    pub fn safe_to_run(&self) -> Option<bool> {
        self.safe
    }

    /// The supervisor (rules, last reaches).
    pub fn supervisor(&self) -> &Supervisor {
        &self.supervisor
    }

    /// Reaction times so far.
    pub fn reaction(&self) -> &ReactionStats {
        &self.reaction
    }

    /// Frames processed.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Integrity check results applied ([`Command::Integrity`]), changed or not: a count
    /// that grows shows the configuration is being watched.
    pub fn integrity_checks(&self) -> u64 {
        self.integrity_checks
    }

    /// How many times the targets were stopped.
    pub fn stops(&self) -> u64 {
        self.fanout.stops()
    }

    /// Latest sample per axis (rules order).
    pub fn samples(&self) -> &[Option<Sample>] {
        &self.samples
    }

    /// Processes one received frame (`at`: its reception time).
    pub fn on_frame(&mut self, bytes: &[u8], at: Instant) -> Option<OnlineEvent> {
        let frame = EplFrame::decode(bytes).ok()?;
        self.frames += 1;
        match &frame.message {
            Message::Soc(_) => {
                self.cycle += 1;
            }
            Message::PRes(pres) => {
                let mut any = false;
                for i in self.inputs.axes_of(frame.src_node).collect::<Vec<_>>() {
                    // A payload too short for the map leaves the old sample to go stale.
                    if let Some(s) = self.inputs.sample(i, &pres.payload, self.cycle) {
                        if let Some(slot) = self.samples.get_mut(i) {
                            *slot = Some(s);
                            any = true;
                        }
                    }
                }
                if !any {
                    return None;
                }
            }
            _ => return None,
        }
        self.evaluate(at)
    }

    fn evaluate(&mut self, at: Instant) -> Option<OnlineEvent> {
        let now = at.saturating_duration_since(self.origin);
        let input = CycleInput {
            now,
            cycle: self.cycle,
            mode: self.config.mode,
            samples: &self.samples,
            params_ok: self.integrity.is_ok(),
        };
        let decision = self.supervisor.evaluate(&input);
        let report = self.fanout.apply(decision);
        let sent = self.clock.now();
        let safe = decision.safe_to_run();
        let was = self.safe.replace(safe);
        if was == Some(safe) && !report.stopped {
            return None;
        }
        if safe {
            return Some(OnlineEvent::Safe { cycle: self.cycle, held: self.fanout.held() });
        }
        let reaction = report.stopped.then(|| sent.saturating_duration_since(at));
        if let Some(r) = reaction {
            self.reaction.samples_ns.push(u64::try_from(r.as_nanos()).unwrap_or(u64::MAX));
        }
        let diagnosis = match (&self.integrity, decision.diagnosis()) {
            (Err(changes), _) => changes.clone(),
            (Ok(()), Some(d)) => d.to_string(),
            (Ok(()), None) => "unsafe".into(),
        };
        Some(OnlineEvent::Unsafe {
            cycle: self.cycle,
            diagnosis,
            reaction,
            errors: report.errors.iter().map(ToString::to_string).collect(),
        })
    }

    /// Checks the lease between frames; stops the targets when it expired.
    pub fn tick(&mut self, now: Instant) -> Option<OnlineEvent> {
        let report = self.fanout.check_expiry(now.saturating_duration_since(self.origin));
        if !report.stopped {
            return None;
        }
        self.safe = Some(false);
        Some(OnlineEvent::Unsafe {
            cycle: self.cycle,
            diagnosis: "no data from the segment: SafeToRun lease expired".into(),
            reaction: None,
            errors: report.errors.iter().map(ToString::to_string).collect(),
        })
    }

    /// The operator's reset after a stop (manual restart): the next safe decision lets the
    /// drives run again.
    pub fn reset(&mut self) {
        self.fanout.reset();
        // Report the next safe decision as a change.
        self.safe = None;
    }

    /// True while stopped and waiting for [`OnlineSupervisor::reset`].
    pub fn held(&self) -> bool {
        self.fanout.held()
    }

    /// Stops every target now (operator emergency stop); the next safe decision releases.
    pub fn stop_all(&mut self) {
        self.fanout.stop_all();
        self.safe = Some(false);
    }

    /// The outcome of the last integrity check (`Err` names what is wrong).
    pub fn integrity(&self) -> &Result<(), String> {
        &self.integrity
    }

    /// Applies one command (see [`Command`]); returns what to report, if anything.
    pub fn apply(&mut self, command: Command) -> Option<ServeEvent> {
        match command {
            Command::StopAll => {
                self.stop_all();
                Some(ServeEvent::Stopped)
            }
            Command::Reset => {
                self.reset();
                Some(ServeEvent::Reset)
            }
            Command::Integrity(result) => {
                self.integrity_checks += 1;
                let changed = result != self.integrity;
                self.set_integrity(result);
                changed.then(|| ServeEvent::Integrity(self.integrity.clone()))
            }
            Command::Rules { rules, inputs } => {
                if rules.config() == self.supervisor.rules().config() {
                    return None;
                }
                tracing::warn!("safety supervisor: new rules installed, drives stopped and held");
                self.replace_rules(*rules, *inputs);
                Some(ServeEvent::RulesInstalled)
            }
        }
    }

    /// The supervisor loop, the only one (`motus safety run`, the station's juggler, the
    /// tests): until `stop` is set or `on_event` breaks, applies the pending `commands`
    /// (operator stop and reset, integrity results, approved rules; a mailbox, never waited
    /// for: [`motus_realtime::mailbox()`]), then reads one frame
    /// from `link` (waiting at most `poll`) and evaluates it ([`OnlineSupervisor::on_frame`]),
    /// or checks the lease when none came ([`OnlineSupervisor::tick`]). Every event goes to
    /// `on_event`, and [`ServeEvent::Pass`] ends every pass (where a caller publishes its
    /// state: it must not block, the lease is renewed from this thread). The thread is
    /// promoted to the cyclic real-time class and takes part in the supervisor's clock (start
    /// it with [`motus_clock::spawn`] on a threaded virtual clock). A link error stops every
    /// target and is returned; on `stop` the targets are left as they are (the caller stops
    /// them, or lets the lease expire).
    ///
    /// # Errors
    /// The link failed.
    pub fn run(
        &mut self,
        link: &dyn EthLink,
        commands: &MailboxReceiver<Command>,
        stop: &AtomicBool,
        poll: Duration,
        mut on_event: impl FnMut(&Self, &ServeEvent) -> ControlFlow<()>,
    ) -> io::Result<()> {
        // The lease must be renewed every cycle: this loop is cyclic work (a no-op unless the
        // binary set a real-time policy).
        motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Cyclic);
        self.clock.join_thread();
        let mut buf = vec![0u8; motus_epl::transport::MAX_FRAME];
        while !stop.load(Ordering::Relaxed) {
            for command in commands.try_take() {
                if let Some(e) = self.apply(command) {
                    if on_event(self, &e).is_break() {
                        return Ok(());
                    }
                }
            }
            let event = match link.recv(&mut buf, poll) {
                Ok(Some((n, at))) => {
                    let raw = buf.get(..n).unwrap_or(&[]);
                    if let Some(node) = self.node.as_mut() {
                        node.on_frame(raw, at);
                    }
                    let e = self.on_frame(raw, at);
                    e.or_else(|| self.tick(self.clock.now()))
                }
                Ok(None) => self.tick(self.clock.now()),
                Err(e) => {
                    tracing::error!(error = %e, "safety supervisor: link failed, stopping every drive");
                    self.stop_all();
                    return Err(e);
                }
            };
            if let Some(e) = event {
                if on_event(self, &ServeEvent::Online(e)).is_break() {
                    break;
                }
            }
            let now = self.clock.now();
            if let Some(node) = self.node.as_mut() {
                node.poll(now);
            }
            if on_event(self, &ServeEvent::Pass).is_break() {
                break;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]
    use super::*;
    use crate::{juggler, EplLeaseTarget};
    use motus_realtime::mailbox as channel;
    use motus_safety::JUGGLER_TOML;
    use std::sync::Arc;

    fn inputs(rules: &RuleSet) -> InputMap {
        InputMap::new(rules, juggler::value_map(rules), 0x10).unwrap()
    }

    #[test]
    fn run_applies_commands_in_order_and_reports_changes_only() {
        let link = motus_epl::open_link(&format!("mem://runner-test-{}", std::process::id()), true).unwrap();
        let rules = RuleSet::from_toml(JUGGLER_TOML).unwrap();
        let origin = Instant::now();
        let target = EplLeaseTarget::new(
            Arc::clone(&link),
            origin,
            Duration::from_millis(20),
            Duration::from_millis(1),
            [0; 8],
        );
        let mut sup = OnlineSupervisor::new(
            rules.clone(),
            inputs(&rules),
            vec![Box::new(target)],
            origin,
            OnlineConfig::default(),
        );
        let changed =
            RuleSet::from_toml(&JUGGLER_TOML.replace("max_sample_age = 3 ", "max_sample_age = 2 ")).unwrap();
        let (tx, rx) = channel();
        tx.send(Command::StopAll).unwrap();
        tx.send(Command::Integrity(Err("drive[thrower].a_stop: 1.0 -> 2.0".into()))).unwrap();
        tx.send(Command::Integrity(Err("drive[thrower].a_stop: 1.0 -> 2.0".into()))).unwrap();
        tx.send(Command::Rules { rules: Box::new(rules.clone()), inputs: Box::new(inputs(&rules)) }).unwrap();
        tx.send(Command::Rules { rules: Box::new(changed.clone()), inputs: Box::new(inputs(&changed)) })
            .unwrap();
        tx.send(Command::Reset).unwrap();
        let stop = AtomicBool::new(false);
        let mut seen = Vec::new();
        sup.run(&*link, &rx, &stop, Duration::from_millis(1), |_, e| {
            if *e == ServeEvent::Pass {
                return ControlFlow::Continue(());
            }
            seen.push(e.clone());
            if *e == ServeEvent::Reset {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        })
        .unwrap();
        assert_eq!(
            seen,
            [
                ServeEvent::Stopped,
                ServeEvent::Integrity(Err("drive[thrower].a_stop: 1.0 -> 2.0".into())),
                ServeEvent::RulesInstalled,
                ServeEvent::Reset,
            ]
        );
        assert_eq!(sup.supervisor().rules().config().supervisor.max_sample_age, 2);
        // Both results count as checks, although only the first changed anything.
        assert_eq!(sup.integrity_checks(), 2);
        assert!(
            sup.integrity().as_ref().unwrap_err().contains("new rules installed"),
            "{:?}",
            sup.integrity()
        );
        assert!(sup.stops() >= 1);
        // The stop flag ends the loop too (a pass without frames, then the flag).
        stop.store(true, Ordering::Relaxed);
        sup.run(&*link, &rx, &stop, Duration::from_millis(1), |_, _| ControlFlow::Continue(())).unwrap();
    }
}
