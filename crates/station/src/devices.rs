//! Device supervision: a device that disconnects is retried with exponential back-off;
//! meanwhile its axes are faulted and stopped (through an [`AxisGate`]) and an alarm is
//! active. Nothing else stops: other devices and task classes go on.
//!
//! [`Reconnector::poll`] takes the time as an argument (pure and testable); run it from
//! a slow task class (it implements [`CyclicTask`]) so a blocking `connect` never delays
//! a motion cycle.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::alarm::{Alarm, AlarmCode, AlarmSeverity, AlarmSink};
use crate::scheduler::{CyclicTask, TaskError};

/// Why a device could not be reached.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DeviceError {
    /// The link (port, bus, segment) could not be opened.
    #[error("link {link}: {reason}")]
    Link {
        /// Link name or URI.
        link: String,
        /// OS or protocol reason.
        reason: String,
    },
    /// The link is up but the device does not answer.
    #[error("no answer from the device: {0}")]
    NoAnswer(String),
    /// The device answered but is not the expected one or refused the set-up.
    #[error("device refused the set-up: {0}")]
    Refused(String),
}

/// A device the station keeps connected (a driver with its link).
pub trait DeviceHandle: Send {
    /// Name from the cell file.
    fn name(&self) -> &str;
    /// Opens the link and brings the device up. May block (runs on the devices task).
    fn connect(&mut self) -> Result<(), DeviceError>;
    /// Cheap health check: false once the link or the device was lost.
    fn is_connected(&mut self) -> bool;
    /// Names of the axes this device moves.
    fn axes(&self) -> Vec<String>;
    /// A condition of the connected device that only the operator can clear (a KV-01
    /// module's latched safety time-out needs a power cycle), as a sentence that says what
    /// to do; `None` when there is none (the default). Checked on every poll while the
    /// device is connected: the [`AlarmCode::DeviceLatched`] alarm is raised once when it
    /// appears (or its text changes) and cleared when it is gone.
    fn needs_operator(&mut self) -> Option<String> {
        None
    }
    /// How many failed health checks in a row make the device lost (default 1). A device whose
    /// check is one request with a short reply window (a PS1A module: 32.5 ms) says more, so
    /// that a reply a loaded host dropped does not take its axes away mid-move.
    fn lost_after_misses(&self) -> u32 {
        1
    }
}

/// Where the reconnector marks axes faulted (and asks for their stop) and clears them.
pub trait AxisGate: Send + Sync {
    /// The axis's device is gone: fault it and stop commanding it (motion layer).
    fn fault(&self, axis: &str, reason: &str);
    /// The axis's device is back: the fault is cleared (motion still needs the
    /// operator's or program's enable/fault reset).
    fn clear(&self, axis: &str);
}

/// An [`AxisGate`] that keeps the faulted axes in a table the motion tasks read.
#[derive(Debug, Default)]
pub struct FaultTable {
    faults: Mutex<BTreeMap<String, String>>,
}

impl FaultTable {
    /// An empty table.
    pub fn new() -> Self {
        Self::default()
    }

    /// The fault reason of an axis, if faulted.
    pub fn fault_of(&self, axis: &str) -> Option<String> {
        self.faults.lock().ok().and_then(|g| g.get(axis).cloned())
    }

    /// Every faulted axis with its reason, by name.
    pub fn faulted(&self) -> Vec<(String, String)> {
        self.faults
            .lock()
            .map(|g| g.iter().map(|(a, r)| (a.clone(), r.clone())).collect())
            .unwrap_or_default()
    }
}

impl AxisGate for FaultTable {
    fn fault(&self, axis: &str, reason: &str) {
        if let Ok(mut g) = self.faults.lock() {
            g.insert(axis.to_string(), reason.to_string());
        }
    }

    fn clear(&self, axis: &str) {
        if let Ok(mut g) = self.faults.lock() {
            g.remove(axis);
        }
    }
}

/// Exponential back-off between reconnection attempts (no random jitter, so tests and
/// operators can predict it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Backoff {
    /// Delay after the first failure.
    pub initial: Duration,
    /// Longest delay.
    pub max: Duration,
}

impl Default for Backoff {
    /// 100 ms doubling up to 5 s.
    fn default() -> Self {
        Backoff { initial: Duration::from_millis(100), max: Duration::from_secs(5) }
    }
}

impl Backoff {
    /// Delay after `failures` consecutive failed attempts (>= 1): `initial * 2^(failures-1)`,
    /// capped at `max`.
    pub fn delay(&self, failures: u32) -> Duration {
        let shift = failures.saturating_sub(1).min(31);
        self.initial.saturating_mul(1u32 << shift).min(self.max)
    }
}

/// Connection state of one device.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ConnState {
    /// Not tried yet.
    Pending,
    /// Up.
    Connected,
    /// Down; retried at `next_attempt`.
    Disconnected {
        /// Consecutive failed attempts.
        failures: u32,
        /// When the next attempt is due.
        next_attempt: Instant,
        /// The last reason.
        last_error: String,
    },
}

/// What changed during a poll.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DeviceEvent {
    /// The device came up (first time or again); its axes' faults were cleared.
    Connected {
        /// Device name.
        device: String,
        /// Failed attempts before this success.
        after_failures: u32,
    },
    /// The device was lost: its axes are faulted and stopped.
    Lost {
        /// Device name.
        device: String,
        /// Its axes.
        axes: Vec<String>,
    },
    /// An attempt failed; the next one is due after `retry_in`.
    AttemptFailed {
        /// Device name.
        device: String,
        /// Consecutive failures so far.
        failures: u32,
        /// Why.
        error: DeviceError,
        /// Back-off until the next attempt.
        retry_in: Duration,
    },
}

/// A snapshot for the HMI.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeviceStatus {
    /// Device name.
    pub name: String,
    /// State.
    pub state: ConnState,
    /// Its axes.
    pub axes: Vec<String>,
    /// Times it was lost since the start.
    pub losses: u64,
}

struct Entry {
    handle: Box<dyn DeviceHandle>,
    axes: Vec<String>,
    state: ConnState,
    losses: u64,
    /// Failed health checks in a row while connected.
    misses: u32,
    /// The operator condition the active [`AlarmCode::DeviceLatched`] alarm reports.
    latched: Option<String>,
}

/// Raises the device's [`AlarmCode::DeviceLatched`] alarm once when its operator condition
/// appears (or changes), and clears it when it is gone.
fn update_latched(e: &mut Entry, name: &str, alarms: &dyn AlarmSink) {
    let now = e.handle.needs_operator();
    if now == e.latched {
        return;
    }
    match &now {
        Some(message) => {
            tracing::error!(device = %name, "{message}");
            alarms.raise(Alarm {
                code: AlarmCode::DeviceLatched,
                severity: AlarmSeverity::Error,
                source: device_source(name),
                message: message.clone(),
            });
        }
        None => {
            tracing::info!(device = %name, "the device's latched condition is cleared");
            alarms.clear(&device_source(name), AlarmCode::DeviceLatched);
        }
    }
    e.latched = now;
}

/// Keeps devices connected.
pub struct Reconnector {
    entries: Vec<Entry>,
    backoff: Backoff,
    alarms: Arc<dyn AlarmSink>,
    gate: Arc<dyn AxisGate>,
}

impl std::fmt::Debug for Reconnector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Reconnector")
            .field("devices", &self.status())
            .field("backoff", &self.backoff)
            .finish()
    }
}

/// The alarm source name of a device.
pub fn device_source(device: &str) -> String {
    format!("device:{device}")
}

impl Reconnector {
    /// A reconnector with no devices.
    pub fn new(backoff: Backoff, alarms: Arc<dyn AlarmSink>, gate: Arc<dyn AxisGate>) -> Self {
        Reconnector { entries: Vec::new(), backoff, alarms, gate }
    }

    /// Adds a device; its axes stay faulted ("not connected yet") until the first
    /// successful connect.
    pub fn add(&mut self, handle: Box<dyn DeviceHandle>) {
        let axes = handle.axes();
        for a in &axes {
            self.gate.fault(a, &format!("device {} not connected yet", handle.name()));
        }
        self.entries.push(Entry {
            handle,
            axes,
            state: ConnState::Pending,
            losses: 0,
            misses: 0,
            latched: None,
        });
    }

    /// Every device's state.
    pub fn status(&self) -> Vec<DeviceStatus> {
        self.entries
            .iter()
            .map(|e| DeviceStatus {
                name: e.handle.name().to_string(),
                state: e.state.clone(),
                axes: e.axes.clone(),
                losses: e.losses,
            })
            .collect()
    }

    /// Makes the next poll try `device` at once (operator's "retry now"); false if unknown.
    pub fn retry_now(&mut self, device: &str, now: Instant) -> bool {
        match self.entries.iter_mut().find(|e| e.handle.name() == device) {
            Some(e) => {
                if let ConnState::Disconnected { next_attempt, .. } = &mut e.state {
                    *next_attempt = now;
                }
                true
            }
            None => false,
        }
    }

    /// Checks every device and retries the due ones.
    pub fn poll(&mut self, now: Instant) -> Vec<DeviceEvent> {
        let mut events = Vec::new();
        for e in &mut self.entries {
            let name = e.handle.name().to_string();
            let due = match &e.state {
                ConnState::Connected => {
                    if e.handle.is_connected() {
                        e.misses = 0;
                        update_latched(e, &name, &*self.alarms);
                        continue;
                    }
                    e.misses += 1;
                    if e.misses < e.handle.lost_after_misses() {
                        tracing::debug!(device = %name, misses = e.misses, "health check failed");
                        continue;
                    }
                    e.misses = 0;
                    e.losses += 1;
                    tracing::warn!(device = %name, "device lost; its axes are faulted and stopped");
                    let reason = format!("device {name} disconnected");
                    for a in &e.axes {
                        self.gate.fault(a, &reason);
                    }
                    self.alarms.raise(Alarm {
                        code: AlarmCode::DeviceDisconnected,
                        severity: AlarmSeverity::Error,
                        source: device_source(&name),
                        message: format!(
                            "device {name} disconnected: axes {} faulted and stopped; reconnecting",
                            e.axes.join(", ")
                        ),
                    });
                    events.push(DeviceEvent::Lost { device: name.clone(), axes: e.axes.clone() });
                    e.state = ConnState::Disconnected {
                        failures: 0,
                        next_attempt: now + self.backoff.initial,
                        last_error: reason,
                    };
                    false
                }
                ConnState::Pending => true,
                ConnState::Disconnected { next_attempt, .. } => now >= *next_attempt,
            };
            if !due {
                continue;
            }
            let failures = match &e.state {
                ConnState::Disconnected { failures, .. } => *failures,
                _ => 0,
            };
            match e.handle.connect() {
                Ok(()) => {
                    for a in &e.axes {
                        self.gate.clear(a);
                    }
                    self.alarms.clear(&device_source(&name), AlarmCode::DeviceDisconnected);
                    tracing::info!(device = %name, after_failures = failures, "device connected");
                    e.state = ConnState::Connected;
                    update_latched(e, &name, &*self.alarms);
                    events.push(DeviceEvent::Connected { device: name, after_failures: failures });
                }
                Err(err) => {
                    let failures = failures + 1;
                    let retry_in = self.backoff.delay(failures);
                    if failures == 1 && matches!(e.state, ConnState::Pending) {
                        self.alarms.raise(Alarm {
                            code: AlarmCode::DeviceDisconnected,
                            severity: AlarmSeverity::Error,
                            source: device_source(&name),
                            message: format!("device {name} cannot be reached ({err}); retrying"),
                        });
                    }
                    tracing::debug!(device = %name, failures, error = %err, ?retry_in, "connect failed");
                    e.state = ConnState::Disconnected {
                        failures,
                        next_attempt: now + retry_in,
                        last_error: err.to_string(),
                    };
                    events.push(DeviceEvent::AttemptFailed { device: name, failures, error: err, retry_in });
                }
            }
        }
        events
    }
}

impl CyclicTask for Reconnector {
    fn name(&self) -> &str {
        "devices"
    }

    fn cycle(&mut self, now: Instant, _cycle: u64) -> Result<(), TaskError> {
        self.poll(now);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};

    use super::*;
    use crate::alarm::MemoryAlarms;

    /// A device whose connects fail `fail_next` times, and that can be unplugged.
    struct FakeDevice {
        name: String,
        axes: Vec<String>,
        fail_next: Arc<AtomicU32>,
        plugged: Arc<AtomicBool>,
        up: bool,
        attempts: Arc<AtomicU32>,
    }

    impl DeviceHandle for FakeDevice {
        fn name(&self) -> &str {
            &self.name
        }
        fn connect(&mut self) -> Result<(), DeviceError> {
            self.attempts.fetch_add(1, Ordering::SeqCst);
            if self.fail_next.load(Ordering::SeqCst) > 0 {
                self.fail_next.fetch_sub(1, Ordering::SeqCst);
                return Err(DeviceError::NoAnswer("node 2 silent".into()));
            }
            self.up = true;
            self.plugged.store(true, Ordering::SeqCst);
            Ok(())
        }
        fn is_connected(&mut self) -> bool {
            self.up = self.up && self.plugged.load(Ordering::SeqCst);
            self.up
        }
        fn axes(&self) -> Vec<String> {
            self.axes.clone()
        }
    }

    struct Rig {
        rec: Reconnector,
        alarms: Arc<MemoryAlarms>,
        faults: Arc<FaultTable>,
        fail_next: Arc<AtomicU32>,
        plugged: Arc<AtomicBool>,
        attempts: Arc<AtomicU32>,
    }

    fn rig(fails: u32) -> Rig {
        let alarms = Arc::new(MemoryAlarms::new());
        let faults = Arc::new(FaultTable::new());
        let mut rec = Reconnector::new(Backoff::default(), alarms.clone(), faults.clone());
        let fail_next = Arc::new(AtomicU32::new(fails));
        let plugged = Arc::new(AtomicBool::new(true));
        let attempts = Arc::new(AtomicU32::new(0));
        rec.add(Box::new(FakeDevice {
            name: "wheels".into(),
            axes: vec!["wheel1".into(), "wheel2".into()],
            fail_next: fail_next.clone(),
            plugged: plugged.clone(),
            up: false,
            attempts: attempts.clone(),
        }));
        let other = Arc::new(AtomicU32::new(0));
        rec.add(Box::new(FakeDevice {
            name: "head".into(),
            axes: vec!["pan".into()],
            fail_next: other,
            plugged: Arc::new(AtomicBool::new(true)),
            up: false,
            attempts: Arc::new(AtomicU32::new(0)),
        }));
        Rig { rec, alarms, faults, fail_next, plugged, attempts }
    }

    #[test]
    fn backoff_doubles_from_100ms_to_5s() {
        let b = Backoff::default();
        let ms: Vec<u128> = (1..=9).map(|n| b.delay(n).as_millis()).collect();
        // 100 * 2^(n-1): 100, 200, 400, 800, 1600, 3200, then capped at 5000.
        assert_eq!(ms, vec![100, 200, 400, 800, 1600, 3200, 5000, 5000, 5000]);
        assert_eq!(b.delay(1000), Duration::from_secs(5));
    }

    #[test]
    fn fails_n_times_with_backoff_then_connects_and_clears_faults() {
        let mut r = rig(4);
        let t0 = Instant::now();
        assert!(r.faults.fault_of("wheel1").unwrap().contains("not connected yet"));
        // Poll every 10 ms of simulated time for 3 s; record when attempts happen.
        let mut attempt_times = Vec::new();
        let mut connected_at = None;
        for step in 0..300u64 {
            let now = t0 + Duration::from_millis(step * 10);
            for ev in r.rec.poll(now) {
                match ev {
                    DeviceEvent::AttemptFailed { device, failures, retry_in, .. } if device == "wheels" => {
                        attempt_times.push((step * 10, failures, retry_in.as_millis()));
                    }
                    DeviceEvent::Connected { device, after_failures } if device == "wheels" => {
                        connected_at = Some((step * 10, after_failures));
                    }
                    _ => {}
                }
            }
        }
        // Failures at 0, 100 (0+100), 300 (100+200), 700 (300+400); success at 1500 (700+800).
        assert_eq!(attempt_times, vec![(0, 1, 100), (100, 2, 200), (300, 3, 400), (700, 4, 800)]);
        assert_eq!(connected_at, Some((1500, 4)));
        assert_eq!(r.attempts.load(Ordering::SeqCst), 5);
        assert!(r.faults.faulted().is_empty());
        assert!(r.alarms.active().is_empty());
        // The other device connected on the first poll and was never disturbed.
        assert_eq!(r.rec.status()[1].state, ConnState::Connected);
        assert_eq!(r.alarms.raised().len(), 1);
        assert_eq!(r.alarms.raised()[0].source, "device:wheels");
    }

    /// A connected device whose latched operator condition the test sets.
    struct LatchingDevice {
        latched: Arc<Mutex<Option<String>>>,
        up: Arc<AtomicBool>,
    }

    impl DeviceHandle for LatchingDevice {
        fn name(&self) -> &str {
            "arm"
        }
        fn connect(&mut self) -> Result<(), DeviceError> {
            self.up.store(true, Ordering::SeqCst);
            Ok(())
        }
        fn is_connected(&mut self) -> bool {
            self.up.load(Ordering::SeqCst)
        }
        fn axes(&self) -> Vec<String> {
            vec!["joint1".into()]
        }
        fn needs_operator(&mut self) -> Option<String> {
            self.latched.lock().unwrap().clone()
        }
    }

    #[test]
    fn a_latched_condition_is_one_alarm_until_it_is_gone() {
        let alarms = Arc::new(MemoryAlarms::new());
        let faults = Arc::new(FaultTable::new());
        let mut rec = Reconnector::new(Backoff::default(), alarms.clone(), faults.clone());
        let latched = Arc::new(Mutex::new(None));
        let up = Arc::new(AtomicBool::new(false));
        rec.add(Box::new(LatchingDevice { latched: latched.clone(), up: up.clone() }));
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        rec.poll(t0);
        assert!(alarms.raised().is_empty());
        let text = "KV-01 module 3 latched its 700 ms communication time-out: power-cycle the arm";
        *latched.lock().unwrap() = Some(text.to_string());
        // Polled every 100 ms for 10 s: raised once, with the operator's sentence.
        for step in 1..=100u64 {
            rec.poll(t0 + ms(step * 100));
        }
        let raised = alarms.raised();
        assert_eq!(raised.len(), 1, "{raised:?}");
        assert_eq!(raised[0].code, AlarmCode::DeviceLatched);
        assert_eq!(raised[0].source, "device:arm");
        assert_eq!(raised[0].message, text);
        assert!(alarms.is_active("device:arm", AlarmCode::DeviceLatched));
        assert!(faults.faulted().is_empty(), "the device is connected: its axes are not gated");
        // Power-cycled: the device is lost and comes back without the condition.
        up.store(false, Ordering::SeqCst);
        *latched.lock().unwrap() = None;
        rec.poll(t0 + ms(10_100));
        assert!(alarms.is_active("device:arm", AlarmCode::DeviceLatched), "still latched while away");
        rec.poll(t0 + ms(10_200));
        assert!(alarms.active().is_empty(), "{:?}", alarms.active());
        assert_eq!(alarms.raised().len(), 2, "plus the disconnection");
    }

    #[test]
    fn a_lost_device_faults_only_its_axes_until_it_is_back() {
        let mut r = rig(0);
        let t0 = Instant::now();
        r.rec.poll(t0);
        assert!(r.faults.faulted().is_empty());
        // Unplug the wheels; it will take 2 failed attempts to get them back.
        r.plugged.store(false, Ordering::SeqCst);
        r.fail_next.store(2, Ordering::SeqCst);
        let ev = r.rec.poll(t0 + Duration::from_millis(100));
        assert_eq!(
            ev,
            vec![DeviceEvent::Lost { device: "wheels".into(), axes: vec!["wheel1".into(), "wheel2".into()] }]
        );
        assert_eq!(r.faults.fault_of("wheel2").as_deref(), Some("device wheels disconnected"));
        assert_eq!(r.faults.fault_of("pan"), None, "nothing else stops");
        assert!(r.alarms.is_active("device:wheels", AlarmCode::DeviceDisconnected));
        // First retry 100 ms after the loss (at 200), then 100 ms later (300), then 200 (500).
        assert!(r.rec.poll(t0 + Duration::from_millis(199)).is_empty());
        assert!(matches!(
            r.rec.poll(t0 + Duration::from_millis(200))[..],
            [DeviceEvent::AttemptFailed { failures: 1, .. }]
        ));
        assert!(matches!(
            r.rec.poll(t0 + Duration::from_millis(300))[..],
            [DeviceEvent::AttemptFailed { failures: 2, .. }]
        ));
        assert!(r.rec.poll(t0 + Duration::from_millis(499)).is_empty());
        // The operator asks for an immediate retry.
        assert!(r.rec.retry_now("wheels", t0 + Duration::from_millis(450)));
        assert!(!r.rec.retry_now("nope", t0));
        let ev = r.rec.poll(t0 + Duration::from_millis(450));
        assert_eq!(ev, vec![DeviceEvent::Connected { device: "wheels".into(), after_failures: 2 }]);
        assert!(r.faults.faulted().is_empty());
        assert!(r.alarms.active().is_empty());
        assert_eq!(r.rec.status()[0].losses, 1);
    }

    /// A device whose health checks fail while `failing` is set; lost after `after` misses.
    struct FlakyDevice {
        failing: Arc<AtomicBool>,
        after: u32,
    }

    impl DeviceHandle for FlakyDevice {
        fn name(&self) -> &str {
            "ps1a-1"
        }
        fn connect(&mut self) -> Result<(), DeviceError> {
            if self.failing.load(Ordering::SeqCst) {
                return Err(DeviceError::NoAnswer("no reply".into()));
            }
            Ok(())
        }
        fn is_connected(&mut self) -> bool {
            !self.failing.load(Ordering::SeqCst)
        }
        fn axes(&self) -> Vec<String> {
            vec!["linear1".into()]
        }
        fn lost_after_misses(&self) -> u32 {
            self.after
        }
    }

    #[test]
    fn a_device_is_lost_only_after_its_number_of_failed_checks_in_a_row() {
        let alarms = Arc::new(MemoryAlarms::new());
        let faults = Arc::new(FaultTable::new());
        let mut rec = Reconnector::new(Backoff::default(), alarms.clone(), faults.clone());
        let failing = Arc::new(AtomicBool::new(false));
        rec.add(Box::new(FlakyDevice { failing: failing.clone(), after: 3 }));
        let t0 = Instant::now();
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        rec.poll(at(0));
        assert_eq!(rec.status()[0].state, ConnState::Connected);
        // Two misses, then a good check: still connected, nothing raised.
        for (k, fail) in [true, true, false, true, true].into_iter().enumerate() {
            failing.store(fail, Ordering::SeqCst);
            rec.poll(at(100 * (k as u64 + 1)));
            assert_eq!(rec.status()[0].state, ConnState::Connected, "check {k}");
        }
        assert!(faults.faulted().is_empty());
        // The third miss in a row: lost, faulted, alarmed.
        rec.poll(at(600));
        assert_ne!(rec.status()[0].state, ConnState::Connected);
        assert!(faults.fault_of("linear1").is_some());
        assert_eq!(alarms.active().len(), 1);
    }
}
