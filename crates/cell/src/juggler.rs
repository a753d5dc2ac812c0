//! The juggler on POWERLINK: the simulated segment over UDP (`motus sim epl`: MN + one
//! drive CN per rules axis, needing the safety lease), the online supervisor on its own
//! thread (the loop of `motus safety run`: [`OnlineSupervisor::run`]; integrity of the rules
//! and the drive parameters watched by the same [`IntegrityWatcher`] when the cell names an
//! approval and a key, else as with `--no-integrity`), a passive [`Monitor`] feeding
//! read-only axes, and the shared [`SupervisorSnapshot`].

use std::collections::BTreeMap;
use std::ops::ControlFlow;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError, TryLockError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_axis::{Axis, AxisCommand, AxisError, AxisFlags, AxisState, Capabilities, Fault, FaultKind, Scale};
use motus_epl::sim::pdo::{
    PRES_POSITION_OFFSET, PRES_SPEED_OFFSET, STATUS_ENABLED, STATUS_HOMED, STATUS_LEASE_STOP,
};
use motus_epl::sim::{MnConfig, Segment};
use motus_epl::{open_link, Monitor, MonitorConfig};
use motus_epl_protocol::{NodeValues, Value, ValueMap, ValueSpec, ValueType};
use motus_realtime::{mailbox, MailboxReceiver, MailboxSender};
use motus_safety::predict::Reach;
use motus_safety::{config_files, ConfigFiles, Mode, RuleSet, Sample};
use motus_safety_epl::juggler::{self, Pattern};
use motus_safety_epl::{
    Command, EplLeaseTarget, InputMap, IntegrityWatcher, OnlineConfig, OnlineEvent, OnlineSupervisor,
    ServeEvent,
};
use motus_station::config::{AxisConfig, Supervisor};
use motus_station::devices::DeviceError;

use crate::juggler_program::{ProgramSelector, SelectedCam};
use crate::sim::SimControl;
use crate::{CellError, CellOptions, DeviceCtl};

/// PRes older than this: the drive counts as lost.
const STALE: Duration = Duration::from_millis(250);

/// The supervisor's latest state, as the station shows it.
#[derive(Debug, Clone, PartialEq)]
pub struct SupervisorSnapshot {
    /// SafeToRun (`None` before the first evaluation).
    pub safe_to_run: Option<bool>,
    /// Stopped and waiting for [`JugglerHandle::reset`] (manual restart).
    pub held: bool,
    /// Why SafeToRun fell last (first failing rule, stale data, integrity).
    pub diagnosis: Option<String>,
    /// `Err` names what is wrong with the configuration's integrity (approval, key, changes).
    pub integrity: Result<(), String>,
    /// Integrity is not checked (no approval or key in the cell file).
    pub integrity_disabled: bool,
    /// Reachable ranges per rules axis (name, reach), rules order.
    pub reaches: Vec<(String, Reach)>,
    /// Latest sample per rules axis (name, sample in rules units).
    pub samples: Vec<(String, Option<Sample>)>,
    /// Frames processed.
    pub frames: u64,
    /// Integrity check results the supervisor applied (grows while the files are watched).
    pub integrity_checks: u64,
    /// Operator resets the supervisor applied.
    pub resets: u64,
    /// Times the drives were stopped.
    pub stops: u64,
    /// SafeToRun became true this many times.
    pub safe_events: u64,
    /// SafeToRun fell this many times.
    pub unsafe_events: u64,
}

impl Default for SupervisorSnapshot {
    fn default() -> Self {
        Self {
            safe_to_run: None,
            held: false,
            diagnosis: None,
            integrity: Err("configuration integrity not checked yet".into()),
            integrity_disabled: false,
            reaches: Vec::new(),
            samples: Vec::new(),
            frames: 0,
            integrity_checks: 0,
            resets: 0,
            stops: 0,
            safe_events: 0,
            unsafe_events: 0,
        }
    }
}

/// How often the configuration's integrity is checked.
const INTEGRITY_EVERY: Duration = Duration::from_secs(1);

/// What the monitor last saw of one node.
#[derive(Debug, Clone, Copy)]
struct NodeView {
    position: i32,
    speed: i32,
    status: u16,
    at: Instant,
}

type Views = Arc<Mutex<BTreeMap<u8, NodeView>>>;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The supervisor, the monitor and their shared state.
pub struct JugglerHandle {
    snapshot: Arc<Mutex<SupervisorSnapshot>>,
    /// Notified after each publication of `snapshot`.
    published: Arc<Condvar>,
    ops: Mutex<MailboxSender<Command>>,
    views: Views,
    stop: Arc<AtomicBool>,
    threads: Mutex<Vec<JoinHandle<()>>>,
    program: Option<Arc<ProgramSelector>>,
}

impl std::fmt::Debug for JugglerHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JugglerHandle").field("snapshot", &self.snapshot()).finish()
    }
}

impl JugglerHandle {
    /// The supervisor's latest state.
    pub fn snapshot(&self) -> SupervisorSnapshot {
        lock(&self.snapshot).clone()
    }

    /// Operator stop: revokes the safety lease (every juggler drive quick-stops).
    pub fn stop_all(&self) {
        let _ = lock(&self.ops).send(Command::StopAll);
    }

    /// Operator reset after a stop (manual restart).
    pub fn reset(&self) {
        let _ = lock(&self.ops).send(Command::Reset);
    }

    /// [`JugglerHandle::reset`], then waits up to `timeout` until the supervisor has applied
    /// it and published its next decision; false on time-out. For a caller that must not
    /// show the hold released before the supervisor has decided (the station's E-stop reset:
    /// in between, the supervisor's stale hold would read as a trip).
    pub fn reset_and_wait(&self, timeout: Duration) -> bool {
        let target = lock(&self.snapshot).resets + 1;
        self.reset();
        let guard = lock(&self.snapshot);
        let (_guard, r) = self
            .published
            .wait_timeout_while(guard, timeout, |s| s.resets < target || s.safe_to_run.is_none())
            .unwrap_or_else(PoisonError::into_inner);
        !r.timed_out()
    }

    /// The latest PRes of every drive seen by the monitor: `f(node, position, speed,
    /// status)` in raw drive units, under a short lock (for cyclic trace tasks).
    pub fn for_each_drive(&self, mut f: impl FnMut(u8, i32, i32, u16)) {
        for (node, v) in lock(&self.views).iter() {
            f(*node, v.position, v.speed, v.status);
        }
    }

    /// Installs `rules` in the running supervisor (after the station wrote and approved
    /// them): the drives are stopped and held until an operator's reset.
    ///
    /// # Errors
    /// The rules' axes are not drives of the segment (the message says which).
    pub fn install_rules(&self, rules: RuleSet) -> Result<(), String> {
        let inputs = juggler_inputs(&rules).map_err(|e| format!("rules not installed: {e}"))?;
        let _ = lock(&self.ops).send(Command::Rules { rules: Box::new(rules), inputs: Box::new(inputs) });
        Ok(())
    }

    /// The program the juggler runs (`None`: not selectable here, e.g. a real machine whose
    /// controller is programmed on its own).
    pub fn program(&self) -> Option<Pattern> {
        self.program.as_ref().map(|p| p.get())
    }

    /// Loads `pattern` onto the simulated juggler's controller; it runs from the next
    /// cycle, guarded by the supervisor like any motion.
    ///
    /// # Errors
    /// The juggler's program is not selectable here (no simulated controller).
    pub fn select_program(&self, pattern: Pattern) -> Result<(), String> {
        let p = self.program.as_ref().ok_or_else(|| {
            "the juggler's program runs on its own controller: load it there (only the simulated \
             juggler's program is selected by the station)"
                .to_owned()
        })?;
        tracing::info!(program = pattern.name(), "juggler: program selected");
        p.set(pattern);
        Ok(())
    }

    /// Stops the supervisor and monitor threads.
    pub(crate) fn shutdown(&self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in lock(&self.threads).drain(..) {
            let _ = t.join();
        }
    }
}

/// Reads the rules file.
pub(crate) fn read_rules(path: &Path) -> Result<RuleSet, CellError> {
    config_files::read_rules(path).map_err(|e| CellError::Config(e.to_string()))
}

/// The supervisor's inputs for `rules` on the juggler's segment (the simulated drives' PRes
/// layout).
fn juggler_inputs(rules: &RuleSet) -> Result<InputMap, motus_safety_epl::InputError> {
    InputMap::new(rules, juggler::value_map(rules), STATUS_HOMED)
}

/// The simulated segment (MN + one drive CN per rules axis on `uri`).
pub(crate) struct SegmentSim {
    uri: String,
    rules: RuleSet,
    options: CellOptions,
    program: Arc<ProgramSelector>,
    segment: Option<Segment>,
}

impl SegmentSim {
    pub(crate) fn start(
        uri: &str,
        rules: RuleSet,
        options: CellOptions,
        program: Arc<ProgramSelector>,
    ) -> Result<Self, CellError> {
        let mut s = Self { uri: uri.into(), rules, options, program, segment: None };
        s.spawn()?;
        Ok(s)
    }

    fn spawn(&mut self) -> Result<(), CellError> {
        let err = |reason: String| CellError::Simulator { name: self.uri.clone(), reason };
        let join = || open_link(&self.uri, false).map_err(|e| err(format!("cannot join {}: {e}", self.uri)));
        // The rules' cycle is the segment's (a rules file written for a slower simulated
        // segment gets it); never faster than the configured simulation cycle.
        let rules_cycle = Duration::from_secs_f64(self.rules.config().supervisor.cycle_time.clamp(0.0, 1.0));
        let cycle = self.options.juggler_cycle.max(rules_cycle);
        let config = MnConfig {
            cycle,
            pres_timeout: (cycle / 4).clamp(Duration::from_micros(100), Duration::from_micros(300)),
            // No spinning before each cycle: on a shared host a spinning thread takes CPU the
            // other threads of the cell need (and uses up its fair share, so it waits longer
            // when it wakes); a cycle start a few tens of microseconds late is harmless here.
            busy_wait: Duration::ZERO,
            ..MnConfig::default()
        };
        let pattern = self.program.get();
        let mut b = Segment::builder()
            .config(config)
            .mn_link(join()?)
            .program(Box::new(SelectedCam::new(&self.rules, Arc::clone(&self.program))));
        for (node, params) in juggler::drives(&self.rules, pattern, Some(self.options.drive_lease)) {
            b = b.drive(node, join()?, params);
        }
        self.segment = Some(b.start().map_err(|e| err(e.to_string()))?);
        Ok(())
    }
}

impl SimControl for SegmentSim {
    fn kill(&mut self) {
        if let Some(s) = self.segment.take() {
            s.stop();
        }
    }

    fn restart(&mut self) -> Result<(), CellError> {
        self.kill();
        self.spawn()
    }

    fn is_running(&self) -> bool {
        self.segment.is_some()
    }
}

/// The value map of the drives' PRes for `nodes` (the simulated drives' layout).
fn value_map(nodes: &[u8]) -> ValueMap {
    let v = |name: &str, offset, ty| ValueSpec { name: name.into(), offset, ty };
    ValueMap {
        nodes: nodes
            .iter()
            .map(|n| NodeValues {
                node: *n,
                label: None,
                values: vec![
                    v("status", 0, ValueType::U16),
                    v("position", PRES_POSITION_OFFSET, ValueType::I32),
                    v("speed", PRES_SPEED_OFFSET, ValueType::I32),
                ],
            })
            .collect(),
    }
}

/// Starts the supervisor and the monitor on `uri` for `nodes`.
pub(crate) fn start(
    uri: &str,
    sup: &Supervisor,
    rules: RuleSet,
    nodes: &[u8],
    options: &CellOptions,
    program: Option<Arc<ProgramSelector>>,
) -> Result<JugglerHandle, CellError> {
    let err = |reason: String| CellError::Simulator { name: uri.into(), reason };
    // Integrity: the cell's approved configuration files, or none (disabled).
    let files = match (&sup.approval, &sup.key) {
        (Some(approval), Some(key)) => Some(Ok(ConfigFiles {
            rules: sup.rules.clone(),
            drives: sup.drives.clone(),
            approval: approval.clone(),
            key: key.clone(),
        })),
        (None, None) => None,
        _ => Some(Err("the cell names an approval or a key but not both".to_owned())),
    };
    let link = open_link(uri, true).map_err(|e| err(format!("cannot join {uri}: {e}")))?;
    let origin = Instant::now();
    let inputs = juggler_inputs(&rules).map_err(|e| CellError::Config(e.to_string()))?;
    let renew = Duration::from_secs_f64(rules.config().supervisor.cycle_time.max(0.0001));
    let target = EplLeaseTarget::new(Arc::clone(&link), origin, options.wire_lease, renew, [0; 8]);
    let config = OnlineConfig { mode: Mode::Normal, restart: options.supervisor_restart };
    let mut online = OnlineSupervisor::new(rules.clone(), inputs, vec![Box::new(target)], origin, config);
    let integrity_disabled = files.is_none();
    match &files {
        None => {
            tracing::warn!("juggler supervisor: INTEGRITY CHECK DISABLED (no approval/key in the cell file)");
            online.set_integrity(Ok(()));
        }
        // Fail closed: nothing may run until the cell file is fixed.
        Some(Err(why)) => online.set_integrity(Err(why.clone())),
        // The watcher's first check comes at once.
        Some(Ok(_)) => {}
    }
    let snapshot = Arc::new(Mutex::new(SupervisorSnapshot {
        integrity: online.integrity().clone(),
        integrity_disabled,
        ..SupervisorSnapshot::default()
    }));
    let published = Arc::new(Condvar::new());
    let (tx, rx) = mailbox();
    let stop = Arc::new(AtomicBool::new(false));
    let views: Views = Arc::new(Mutex::new(BTreeMap::new()));
    let mut threads = Vec::new();
    if let Some(Ok(files)) = files {
        // Rules approved anew on disk (`motus safety approve`) are installed as in
        // `motus safety run`; the station's own change arrives through `install_rules` first.
        let watcher =
            IntegrityWatcher::new(files, INTEGRITY_EVERY).reload_rules(rules, Box::new(juggler_inputs));
        threads.push(
            watcher
                .spawn("juggler-integrity", tx.clone(), Arc::clone(&stop))
                .map_err(|e| err(e.to_string()))?,
        );
    }
    {
        let (snap, stop, published) = (Arc::clone(&snapshot), Arc::clone(&stop), Arc::clone(&published));
        let t = std::thread::Builder::new()
            .name("juggler-supervisor".into())
            .spawn(move || supervise(online, &*link, &rx, &snap, &published, &stop))
            .map_err(|e| err(e.to_string()))?;
        threads.push(t);
    }
    {
        let mon_link = open_link(uri, true).map_err(|e| err(format!("cannot join {uri}: {e}")))?;
        let (views, stop) = (Arc::clone(&views), Arc::clone(&stop));
        let mut monitor = Monitor::new(value_map(nodes), MonitorConfig { stale_after: 1 });
        let t = std::thread::Builder::new()
            .name("juggler-monitor".into())
            .spawn(move || {
                motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Device);
                let r = monitor.run(&*mon_link, &stop, |c| {
                    let now = Instant::now();
                    let mut v = lock(&views);
                    for n in c.nodes.iter().filter(|n| n.age == Some(0) && n.valid) {
                        if let (Some(Value::I32(p)), Some(Value::I32(s)), Some(Value::U16(st))) =
                            (n.value("position"), n.value("speed"), n.value("status"))
                        {
                            v.insert(n.node, NodeView { position: p, speed: s, status: st, at: now });
                        }
                    }
                    ControlFlow::Continue(())
                });
                if let Err(e) = r {
                    tracing::warn!(error = %e, "juggler monitor stopped");
                }
            })
            .map_err(|e| err(e.to_string()))?;
        threads.push(t);
    }
    Ok(JugglerHandle {
        snapshot,
        published,
        ops: Mutex::new(tx),
        views,
        stop,
        threads: Mutex::new(threads),
        program,
    })
}

/// The supervisor thread: the one supervisor loop ([`OnlineSupervisor::run`]), publishing
/// its state into `snapshot`.
fn supervise(
    mut sup: OnlineSupervisor,
    link: &dyn motus_epl::EthLink,
    commands: &MailboxReceiver<Command>,
    snapshot: &Mutex<SupervisorSnapshot>,
    published: &Condvar,
    stop: &AtomicBool,
) {
    let mut last_publish = Instant::now();
    let mut names: Vec<String> = sup.supervisor().rules().axes().iter().map(|a| a.name.clone()).collect();
    // This thread's own copy of what it publishes. Readers (web threads, at a lower
    // priority) hold the shared snapshot's lock while they copy it; a reader preempted there
    // must never make this thread wait, whose lease is renewed every cycle. So the copy is
    // published only when the lock is free, and tried again at the next pass otherwise.
    let mut mine = lock(snapshot).clone();
    let mut dirty = false;
    let result = sup.run(link, commands, stop, Duration::from_millis(1), |sup, event| {
        match event {
            ServeEvent::Online(OnlineEvent::Safe { .. }) => mine.safe_events += 1,
            ServeEvent::Online(OnlineEvent::Unsafe { diagnosis, .. }) => {
                mine.unsafe_events += 1;
                mine.diagnosis = Some(diagnosis.clone());
            }
            ServeEvent::RulesInstalled => {
                names = sup.supervisor().rules().axes().iter().map(|a| a.name.clone()).collect();
                mine.diagnosis = Some("new safety rules installed: the drives are held until reset".into());
            }
            ServeEvent::Reset => mine.resets += 1,
            ServeEvent::Integrity(_) | ServeEvent::Stopped => {}
            ServeEvent::Pass => {
                if dirty || last_publish.elapsed() >= Duration::from_millis(10) {
                    mine.safe_to_run = sup.safe_to_run();
                    mine.held = sup.held();
                    mine.integrity.clone_from(sup.integrity());
                    mine.frames = sup.frames();
                    mine.integrity_checks = sup.integrity_checks();
                    mine.stops = sup.stops();
                    mine.reaches =
                        names.iter().cloned().zip(sup.supervisor().reaches().iter().copied()).collect();
                    mine.samples = names.iter().cloned().zip(sup.samples().iter().copied()).collect();
                    let done = match snapshot.try_lock() {
                        Ok(mut s) => {
                            s.clone_from(&mine);
                            true
                        }
                        Err(TryLockError::Poisoned(p)) => {
                            p.into_inner().clone_from(&mine);
                            true
                        }
                        Err(TryLockError::WouldBlock) => false,
                    };
                    if done {
                        last_publish = Instant::now();
                        // Never waits: a waiter re-checks under the lock.
                        published.notify_all();
                    }
                    dirty = !done;
                }
                return ControlFlow::Continue(());
            }
        }
        dirty = true;
        ControlFlow::Continue(())
    });
    if let Err(e) = result {
        tracing::error!(error = %e, "juggler supervisor: link failed");
    }
    sup.stop_all();
}

/// A juggler drive as a read-only axis (see the module documentation).
pub struct EplAxis {
    config: AxisConfig,
    node: u8,
    handle: Arc<JugglerHandle>,
}

impl EplAxis {
    pub(crate) fn new(config: AxisConfig, node: u8, handle: Arc<JugglerHandle>) -> Self {
        Self { config, node, handle }
    }
}

impl Axis for EplAxis {
    fn name(&self) -> &str {
        &self.config.name
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities { stop: true, quick_stop: true, reports_velocity: true, ..Capabilities::default() }
    }

    fn scale(&self) -> &Scale {
        &self.config.scale
    }

    fn read_state(&mut self) -> Result<AxisState, AxisError> {
        let view = lock(&self.handle.views).get(&self.node).copied();
        let v = view.filter(|v| v.at.elapsed() < STALE).ok_or_else(|| AxisError::Communication {
            axis: self.config.name.clone(),
            reason: format!("no PRes from POWERLINK node {} for {STALE:?}", self.node),
        })?;
        let mut faults = Vec::new();
        if v.status & STATUS_LEASE_STOP != 0 {
            faults.push(Fault {
                kind: FaultKind::Other,
                reason: "stopped: the safety lease was revoked or expired".into(),
            });
        }
        Ok(AxisState {
            position: self.config.scale.position_to_si(f64::from(v.position)),
            position_raw: i64::from(v.position),
            velocity: Some(self.config.scale.rate_to_si(f64::from(v.speed))),
            current: None,
            following_error: None,
            flags: AxisFlags {
                enabled: v.status & STATUS_ENABLED != 0,
                homed: v.status & STATUS_HOMED != 0,
                moving: v.speed != 0,
                target_reached: v.speed == 0,
                ..AxisFlags::default()
            },
            faults,
        })
    }

    fn execute(&mut self, command: &AxisCommand) -> Result<(), AxisError> {
        match command {
            AxisCommand::Stop | AxisCommand::QuickStop => {
                self.handle.stop_all();
                Ok(())
            }
            other => Err(AxisError::Refused {
                axis: self.config.name.clone(),
                command: other.name().into(),
                reason: "juggler axes are read-only: the juggler runs its own program on the POWERLINK \
                         segment; only stop and quick-stop (which revoke the safety lease) are accepted"
                    .into(),
            }),
        }
    }
}

/// A juggler drive as a device: connected while its PRes are fresh.
pub(crate) struct EplDevice {
    pub(crate) name: String,
    pub(crate) axes: Vec<String>,
    pub(crate) node: u8,
    pub(crate) handle: Arc<JugglerHandle>,
}

impl EplDevice {
    fn fresh(&self) -> bool {
        lock(&self.handle.views).get(&self.node).is_some_and(|v| v.at.elapsed() < STALE)
    }
}

impl DeviceCtl for EplDevice {
    fn name(&self) -> &str {
        &self.name
    }

    fn axes(&self) -> Vec<String> {
        self.axes.clone()
    }

    fn connect(&self) -> Result<(), DeviceError> {
        let deadline = Instant::now() + Duration::from_millis(500);
        while Instant::now() < deadline {
            if self.fresh() {
                return Ok(());
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        Err(DeviceError::NoAnswer(format!("no PRes from POWERLINK node {}", self.node)))
    }

    fn is_connected(&self) -> bool {
        self.fresh()
    }
}
