//! The threaded master: one receive thread dispatches frames; API calls block the
//! calling thread only. SDO transfers to different nodes run in parallel (one channel
//! per node), transfers to the same node are serialised.

mod failure_log;
mod heartbeat_producer;
mod lss_ops;
mod sdo_ops;
mod spin_wait;
mod sync_producer;
mod wake;

pub use heartbeat_producer::{consumer_entry, HeartbeatProducer};
pub use sdo_ops::{DumpRow, NodeInfo};
pub use sync_producer::SyncProducer;
pub use wake::ClockReceiver;

use std::collections::HashMap;
use std::ops::RangeInclusive;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{channel, Receiver};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::{JoinHandle, Thread};
use std::time::{Duration, Instant};

use motus_can::{CanBus, CanError, CanFrame, Received};
use motus_canopen_protocol::message::LSS_SLAVE_TO_MASTER;
use motus_canopen_protocol::{LssResponse, NmtCommand, NmtState, SdoResponse};
use motus_clock::{SharedClock, SystemClock};

use crate::eds::ObjectDictionary;
use crate::emcy::{EmcyParse, Emergency};
use crate::error::MasterError;
use crate::heartbeat::{HeartbeatConsumer, HeartbeatEvent};
use crate::nmt::{command_frame, parse_heartbeat, NodeChange, NodeTable};
use crate::sdo_client::SDO_RESPONSE_BASE;

use wake::{Waiter, WakeSlot};

/// Something the master observed on the bus.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum MasterEvent {
    /// A node sent its boot-up message.
    Booted {
        /// Node.
        node: u8,
    },
    /// A node's heartbeat reports a new state.
    StateChanged {
        /// Node.
        node: u8,
        /// Previous state (None = first heartbeat seen).
        from: Option<NmtState>,
        /// New state.
        to: NmtState,
    },
    /// A monitored node's heartbeat stopped (reported once).
    HeartbeatLost {
        /// Node.
        node: u8,
        /// Last heartbeat (or start of monitoring).
        last_seen: Instant,
    },
    /// A lost node's heartbeat came back.
    HeartbeatRecovered {
        /// Node.
        node: u8,
        /// State it reports.
        state: NmtState,
    },
    /// An emergency message.
    Emergency(Emergency),
}

/// COB-ID filter of a subscription.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CobFilter {
    /// One COB-ID.
    Id(u32),
    /// An inclusive range.
    Range(RangeInclusive<u32>),
}

impl CobFilter {
    fn matches(&self, id: u32) -> bool {
        match self {
            Self::Id(x) => *x == id,
            Self::Range(r) => r.contains(&id),
        }
    }
}

impl From<u32> for CobFilter {
    fn from(id: u32) -> Self {
        Self::Id(id)
    }
}

impl From<RangeInclusive<u32>> for CobFilter {
    fn from(r: RangeInclusive<u32>) -> Self {
        Self::Range(r)
    }
}

/// Counters of the receive path.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MasterStats {
    /// Frames received.
    pub frames_received: u64,
    /// Frames in a service's COB-ID range that do not fit its layout (an SDO response
    /// that decodes to nothing, a heartbeat with DLC != 1, an EMCY with DLC != 8, an
    /// unknown LSS reply); counted, never acted on.
    pub frames_malformed: u64,
    /// SDO responses nobody was waiting for.
    pub sdo_unsolicited: u64,
    /// Frames sent.
    pub frames_sent: u64,
    /// Receive errors of the transport.
    pub transport_errors: u64,
}

#[derive(Default)]
struct Stats {
    received: AtomicU64,
    malformed: AtomicU64,
    unsolicited: AtomicU64,
    sent: AtomicU64,
    transport_errors: AtomicU64,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

pub(crate) struct Inner {
    bus: Arc<dyn CanBus>,
    /// The time of SDO deadlines and heartbeat monitoring (see [`Master::with_clock`]).
    clock: SharedClock,
    /// The master's threads take part in the clock and its waits park on it (see
    /// [`Master::with_threaded_clock`]).
    threaded: bool,
    running: AtomicBool,
    /// The receive thread (woken when what it waits for changes).
    rx_thread: Mutex<Option<Thread>>,
    sdo_timeout: Mutex<Duration>,
    lss_timeout: Mutex<Duration>,
    sdo_waiters: Mutex<HashMap<u8, Waiter<Received>>>,
    sdo_locks: Mutex<HashMap<u8, Arc<Mutex<()>>>>,
    nodes: Mutex<NodeTable>,
    nodes_changed: Condvar,
    /// Threads parked in `wait_boots`/`wait_state` (threaded only).
    node_waiters: Mutex<Vec<Thread>>,
    heartbeat: Mutex<HeartbeatConsumer>,
    event_subs: Mutex<Vec<Waiter<MasterEvent>>>,
    pdo_subs: Mutex<Vec<(CobFilter, Waiter<Received>)>>,
    lss_waiter: Mutex<Option<Waiter<LssResponse>>>,
    lss_lock: Mutex<()>,
    eds: Mutex<Option<Arc<ObjectDictionary>>>,
    stats: Stats,
    /// How fast batches of SDO answers come back (decides whether to spin for them).
    sdo_latency: spin_wait::AnswerLatency,
}

impl Inner {
    pub(crate) fn send(&self, frame: &CanFrame, context: impl FnOnce() -> String) -> Result<(), MasterError> {
        self.bus.send(frame).map_err(|e| MasterError::transport(context(), e))?;
        self.stats.sent.fetch_add(1, Ordering::Relaxed);
        Ok(())
    }

    /// Sends `frames` in one batch ([`CanBus::send_batch`]).
    pub(crate) fn send_batch(&self, frames: &[CanFrame]) -> Result<(), CanError> {
        self.bus.send_batch(frames)?;
        self.stats.sent.fetch_add(frames.len() as u64, Ordering::Relaxed);
        Ok(())
    }

    fn emit(&self, event: MasterEvent) {
        tracing::debug!(?event, "master event");
        lock(&self.event_subs).retain(|w| w.send(event.clone(), &*self.clock));
    }

    /// Where a thread waiting for a delivery is woken: itself on a threaded master, nobody
    /// otherwise (it blocks on its channel).
    pub(crate) fn wake_slot(&self) -> Option<Arc<WakeSlot>> {
        self.threaded.then(WakeSlot::current)
    }

    /// Receives from `rx` (filled by the receive thread for the calling thread, woken
    /// through [`Self::wake_slot`]) until `deadline` on the clock; see [`wake::recv_until`].
    /// The caller is the thread of control, so on a one-thread virtual clock a time-out
    /// moves the clock to the deadline.
    pub(crate) fn recv_until<T>(
        &self,
        rx: &Receiver<T>,
        deadline: Instant,
    ) -> Result<T, std::sync::mpsc::RecvTimeoutError> {
        wake::recv_until(rx, &*self.clock, deadline, self.threaded, true)
    }

    /// Wakes the receive thread (threaded: it recomputes how long it may park).
    fn wake_receiver(&self) {
        if self.threaded {
            if let Some(t) = lock(&self.rx_thread).as_ref() {
                self.clock.unpark(t);
            }
        }
    }

    fn dispatch(&self, r: Received) {
        self.stats.received.fetch_add(1, Ordering::Relaxed);
        let frame = &r.frame;
        let id = frame.id();
        {
            let mut subs = lock(&self.pdo_subs);
            if !subs.is_empty() && !frame.is_extended() {
                subs.retain(|(f, w)| !f.matches(id) || w.send(r.clone(), &*self.clock));
            }
        }
        if frame.is_extended() {
            return;
        }
        match id {
            0x581..=0x5FF => {
                if frame.is_remote() || SdoResponse::decode(frame.data()).is_none() {
                    self.malformed(frame);
                    return;
                }
                let node = u8::try_from(id - SDO_RESPONSE_BASE).unwrap_or(0);
                let waiter = lock(&self.sdo_waiters).get(&node).cloned();
                match waiter {
                    Some(w) if w.send(r.clone(), &*self.clock) => {}
                    _ => {
                        self.stats.unsolicited.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
            0x701..=0x77F => match parse_heartbeat(frame) {
                Some(Ok((node, state))) => self.on_heartbeat(node, state, r.at),
                _ => self.malformed(frame),
            },
            0x081..=0x0FF => match Emergency::parse(frame) {
                EmcyParse::Emergency(e) => self.emit(MasterEvent::Emergency(e)),
                EmcyParse::Malformed => self.malformed(frame),
                EmcyParse::NotEmcy => {}
            },
            LSS_SLAVE_TO_MASTER => match (frame.is_remote(), LssResponse::decode(frame.data())) {
                (false, Some(resp)) => {
                    if let Some(w) = lock(&self.lss_waiter).as_ref() {
                        let _ = w.send(resp, &*self.clock);
                    }
                }
                _ => self.malformed(frame),
            },
            _ => {}
        }
    }

    fn malformed(&self, frame: &CanFrame) {
        tracing::debug!(%frame, "malformed frame ignored");
        self.stats.malformed.fetch_add(1, Ordering::Relaxed);
    }

    fn on_heartbeat(&self, node: u8, state: NmtState, at: Instant) {
        let change = lock(&self.nodes).on_heartbeat(node, state, at);
        self.nodes_changed.notify_all();
        if self.threaded {
            for t in lock(&self.node_waiters).iter() {
                self.clock.unpark(t);
            }
        }
        let hb_events = lock(&self.heartbeat).on_heartbeat(node, state, at);
        for e in hb_events {
            self.emit_heartbeat(e);
        }
        if let Some(NodeChange::StateChanged { node, from, to }) = change {
            self.emit(MasterEvent::StateChanged { node, from, to });
        }
    }

    fn emit_heartbeat(&self, e: HeartbeatEvent) {
        self.emit(match e {
            HeartbeatEvent::NodeLost { node, last_seen } => MasterEvent::HeartbeatLost { node, last_seen },
            HeartbeatEvent::NodeRecovered { node, state } => MasterEvent::HeartbeatRecovered { node, state },
            HeartbeatEvent::NodeBooted { node } => MasterEvent::Booted { node },
        });
    }

    /// How long the receive thread waits for a frame: 5 ms of wall time; on a threaded
    /// clock until the next heartbeat deadline (just past it: a loss is a silence *longer*
    /// than the consumer time), at most [`THREADED_IDLE`], so a loss is reported at the
    /// instant it happens and an idle bus costs few wake-ups.
    fn receive_timeout(&self) -> Duration {
        if !self.threaded {
            return Duration::from_millis(5);
        }
        let now = self.clock.now();
        match lock(&self.heartbeat).next_deadline() {
            Some(d) => (d.saturating_duration_since(now) + Duration::from_micros(1)).min(THREADED_IDLE),
            None => THREADED_IDLE,
        }
    }

    fn receive_loop(self: Arc<Self>) {
        // A closed transport fails every receive: one line when it starts, a summary every
        // few seconds, one line when it works again.
        let mut failures = failure_log::FailureLog::new("CAN receive", Duration::from_secs(5));
        let bus = self.bus.describe();
        while self.running.load(Ordering::Acquire) {
            match self.bus.recv(self.receive_timeout()) {
                Ok(r) => {
                    failures.succeed(self.clock.now(), &bus);
                    if let Some(r) = r {
                        self.dispatch(r);
                    }
                }
                Err(e) => {
                    self.stats.transport_errors.fetch_add(1, Ordering::Relaxed);
                    failures.fail(self.clock.now(), &e, &bus);
                    if self.threaded {
                        self.clock.sleep(Duration::from_millis(20));
                    } else {
                        std::thread::sleep(Duration::from_millis(20));
                    }
                }
            }
            let lost = lock(&self.heartbeat).poll(self.clock.now());
            for e in lost {
                self.emit_heartbeat(e);
            }
        }
    }
}

/// Longest park of the receive thread on a threaded clock.
const THREADED_IDLE: Duration = Duration::from_millis(100);

/// A CANopen master on one CAN bus. All methods take `&self` and are thread-safe.
pub struct Master {
    inner: Arc<Inner>,
    rx_thread: Option<JoinHandle<()>>,
}

impl Master {
    /// Starts a master on `bus` (spawns its receive thread), on the system clock.
    pub fn new(bus: Arc<dyn CanBus>) -> Master {
        Self::with_clock(bus, SystemClock::shared())
    }

    /// Starts a master on `bus` whose SDO and LSS time-outs, `wait_boot`/`wait_state` and
    /// heartbeat monitoring run on `clock`, for one thread of control.
    ///
    /// On a [`motus_clock::VirtualClock`] the bus must be an in-process pair
    /// ([`motus_can::PairBus`]) whose peer answers inside `send`: a transfer waits for an
    /// answer at most its remaining time-out of *wall* time (a liveness bound; the answer is
    /// normally already queued), then jumps the clock to the deadline and fails on virtual
    /// time. The receive thread only reads the clock. Frames' [`Received::at`] must be in
    /// the clock's time (the pair stamps them so). The heartbeat and SYNC producers sleep on
    /// the clock, so on a virtual clock they need [`Self::with_threaded_clock`].
    pub fn with_clock(bus: Arc<dyn CanBus>, clock: SharedClock) -> Master {
        Self::make(bus, clock, false)
    }

    /// Starts a master on `bus` whose threads take part in `clock`: a
    /// [`motus_clock::VirtualClock::threaded`] clock shared with a test, a driver, a
    /// watchdog and a simulator thread (or the system clock).
    ///
    /// Its threads (the receive thread, [`Self::start_heartbeat`], [`Self::start_sync`])
    /// start with [`motus_clock::spawn`] and wait on the clock; every wait for something
    /// another thread delivers (an SDO or LSS answer, a boot-up or state in
    /// [`Self::wait_state`], a [`ClockReceiver`]) *parks* on the clock until its deadline
    /// and is woken at the instant of the delivery, so time moves on while all wait and
    /// stands still while a delivery is under way. A lost heartbeat is reported at the
    /// instant the consumer time runs out. The bus must wake the receive thread the same
    /// way ([`motus_can::PairBus::threaded`]), or be a real one on the system clock.
    pub fn with_threaded_clock(bus: Arc<dyn CanBus>, clock: SharedClock) -> Master {
        Self::make(bus, clock, true)
    }

    fn make(bus: Arc<dyn CanBus>, clock: SharedClock, threaded: bool) -> Master {
        let inner = Arc::new(Inner {
            bus,
            clock,
            threaded,
            running: AtomicBool::new(true),
            rx_thread: Mutex::default(),
            sdo_timeout: Mutex::new(Duration::from_millis(500)),
            lss_timeout: Mutex::new(Duration::from_millis(500)),
            sdo_waiters: Mutex::default(),
            sdo_locks: Mutex::default(),
            nodes: Mutex::default(),
            nodes_changed: Condvar::new(),
            node_waiters: Mutex::default(),
            heartbeat: Mutex::default(),
            event_subs: Mutex::default(),
            pdo_subs: Mutex::default(),
            lss_waiter: Mutex::default(),
            lss_lock: Mutex::default(),
            eds: Mutex::default(),
            stats: Stats::default(),
            sdo_latency: spin_wait::AnswerLatency::new(),
        });
        let rx = Arc::clone(&inner);
        let builder = std::thread::Builder::new().name("canopen-master-rx".into());
        let rx_thread = motus_clock::spawn(&inner.clock, builder, move || {
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Device);
            rx.receive_loop()
        })
        .map_err(|e| tracing::error!(error = %e, "cannot spawn the receive thread"))
        .ok();
        *lock(&inner.rx_thread) = rx_thread.as_ref().map(|h| h.thread().clone());
        Master { inner, rx_thread }
    }

    /// Whether this master's threads take part in its clock ([`Self::with_threaded_clock`]).
    pub fn is_threaded(&self) -> bool {
        self.inner.threaded
    }

    /// Sends an NMT command to `node` (0 = all nodes).
    pub fn nmt(&self, node: u8, command: NmtCommand) -> Result<(), MasterError> {
        if node > 127 {
            return Err(MasterError::InvalidArgument(format!("NMT node {node} outside 0..=127")));
        }
        let frame = command_frame(node, command).map_err(|e| MasterError::InvalidArgument(e.to_string()))?;
        self.inner.send(&frame, || format!("sending NMT {command} to node {node}"))
    }

    /// Sends a PDO (or any raw frame with a standard id).
    pub fn send_pdo(&self, cob_id: u32, data: &[u8]) -> Result<(), MasterError> {
        let frame = CanFrame::new(cob_id, data).map_err(|e| MasterError::InvalidArgument(e.to_string()))?;
        self.inner.send(&frame, || format!("sending PDO 0x{cob_id:03X}"))
    }

    /// Sends one frame as is.
    pub fn send_frame(&self, frame: &CanFrame) -> Result<(), MasterError> {
        self.inner.send(frame, || format!("sending {frame}"))
    }

    /// Receives every frame whose COB-ID matches `filter` (from now on).
    pub fn subscribe(&self, filter: impl Into<CobFilter>) -> Receiver<Received> {
        let (tx, rx) = channel();
        lock(&self.inner.pdo_subs).push((filter.into(), Waiter::new(tx, None)));
        rx
    }

    /// Receives every [`MasterEvent`] from now on.
    pub fn events(&self) -> Receiver<MasterEvent> {
        let (tx, rx) = channel();
        lock(&self.inner.event_subs).push(Waiter::new(tx, None));
        rx
    }

    /// [`Self::subscribe`] with time-outs on the master's clock (a thread taking part in a
    /// threaded clock is woken at the instant a frame is delivered; see [`ClockReceiver`]).
    pub fn subscribe_on_clock(&self, filter: impl Into<CobFilter>) -> ClockReceiver<Received> {
        let (tx, rx) = channel();
        let slot = Arc::new(WakeSlot::default());
        lock(&self.inner.pdo_subs).push((filter.into(), Waiter::new(tx, Some(Arc::clone(&slot)))));
        ClockReceiver::new(rx, slot, Arc::clone(&self.inner.clock), self.inner.threaded)
    }

    /// [`Self::events`] with time-outs on the master's clock (see [`ClockReceiver`]).
    pub fn events_on_clock(&self) -> ClockReceiver<MasterEvent> {
        let (tx, rx) = channel();
        let slot = Arc::new(WakeSlot::default());
        lock(&self.inner.event_subs).push(Waiter::new(tx, Some(Arc::clone(&slot))));
        ClockReceiver::new(rx, slot, Arc::clone(&self.inner.clock), self.inner.threaded)
    }

    /// Monitors `node`'s heartbeat: [`MasterEvent::HeartbeatLost`] once when none arrived
    /// for longer than `consumer_time` (counted from now), then
    /// [`MasterEvent::HeartbeatRecovered`]. A zero time stops monitoring.
    pub fn monitor_heartbeat(&self, node: u8, consumer_time: Duration) {
        lock(&self.inner.heartbeat).monitor(node, consumer_time, self.inner.clock.now());
        self.inner.wake_receiver();
    }

    /// The NMT state `node` last reported (boot-up or heartbeat).
    pub fn node_state(&self, node: u8) -> Option<NmtState> {
        lock(&self.inner.nodes).state(node)
    }

    /// When `node` was last heard (boot-up or heartbeat).
    pub fn last_heartbeat(&self, node: u8) -> Option<Instant> {
        lock(&self.inner.nodes).get(node).map(|e| e.last_seen)
    }

    /// How many boot-up messages (COB-ID 0x700 + node, data 0x00) of `node` this master
    /// has received: a change means the node restarted and lost its configuration (PDO
    /// set, heartbeat consumer and producer, NMT state), so whoever brought it up must do
    /// it again.
    pub fn boot_count(&self, node: u8) -> u64 {
        lock(&self.inner.nodes).get(node).map_or(0, |e| e.boots)
    }

    /// Whether `node` is monitored ([`Self::monitor_heartbeat`]) and its heartbeat is lost now.
    pub fn heartbeat_lost(&self, node: u8) -> bool {
        lock(&self.inner.heartbeat).is_lost(node)
    }

    /// Waits until `done` holds for the node table, at most `timeout` on the master's clock
    /// (threaded: parked on it, woken by every heartbeat and boot-up; otherwise blocked for
    /// the time-out of wall time, and a time-out moves the clock to the deadline, as an
    /// SDO time-out does). True if it holds.
    fn wait_nodes(&self, timeout: Duration, done: impl Fn(&NodeTable) -> bool) -> bool {
        let inner = &self.inner;
        let clock = &*inner.clock;
        let now = clock.now();
        let deadline = now.checked_add(timeout).unwrap_or(now + Duration::from_secs(86_400));
        if inner.threaded {
            let me = std::thread::current();
            lock(&inner.node_waiters).push(me.clone());
            let held = loop {
                if done(&lock(&inner.nodes)) {
                    break true;
                }
                if clock.now() >= deadline {
                    break false;
                }
                clock.park_until(deadline);
            };
            lock(&inner.node_waiters).retain(|t| t.id() != me.id());
            return held;
        }
        let guard = lock(&inner.nodes);
        let (_g, res) = inner
            .nodes_changed
            .wait_timeout_while(guard, timeout, |t| !done(t))
            .unwrap_or_else(|p| p.into_inner());
        if res.timed_out() {
            clock.sleep_until(deadline);
            return false;
        }
        true
    }

    /// Waits for a boot-up message of `node` received after this call.
    pub fn wait_boot(&self, node: u8, timeout: Duration) -> Result<(), MasterError> {
        let before = self.boot_count(node);
        self.wait_boots(node, before + 1, timeout)
    }

    /// Waits until `node` has sent at least `count` boot-up messages since this master
    /// started ([`Self::boot_count`]); returns at once if it has.
    pub fn wait_boots(&self, node: u8, count: u64, timeout: Duration) -> Result<(), MasterError> {
        let boots = |t: &NodeTable| t.get(node).map_or(0, |e| e.boots);
        if !self.wait_nodes(timeout, |t| boots(t) >= count) {
            return Err(MasterError::NodeTimeout { node, what: "boot-up".into(), timeout });
        }
        Ok(())
    }

    /// Waits until `node` reports `state` in a heartbeat (returns at once if it already did).
    pub fn wait_state(&self, node: u8, state: NmtState, timeout: Duration) -> Result<(), MasterError> {
        if !self.wait_nodes(timeout, |t| t.state(node) == Some(state)) {
            return Err(MasterError::NodeTimeout {
                node,
                what: format!("heartbeat in state {state}"),
                timeout,
            });
        }
        Ok(())
    }

    /// Counters of the receive path.
    pub fn stats(&self) -> MasterStats {
        let s = &self.inner.stats;
        MasterStats {
            frames_received: s.received.load(Ordering::Relaxed),
            frames_malformed: s.malformed.load(Ordering::Relaxed),
            sdo_unsolicited: s.unsolicited.load(Ordering::Relaxed),
            frames_sent: s.sent.load(Ordering::Relaxed),
            transport_errors: s.transport_errors.load(Ordering::Relaxed),
        }
    }

    /// The clock of SDO time-outs and heartbeat monitoring.
    pub fn clock(&self) -> &SharedClock {
        &self.inner.clock
    }

    /// The bus description.
    pub fn describe(&self) -> String {
        self.inner.bus.describe()
    }
}

impl Drop for Master {
    fn drop(&mut self) {
        self.inner.running.store(false, Ordering::Release);
        if let Some(h) = self.rx_thread.take() {
            self.inner.wake_receiver();
            let _ = motus_clock::while_blocked(&*self.inner.clock, || h.join());
        }
    }
}
