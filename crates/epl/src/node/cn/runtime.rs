//! [`ControlledNodeRuntime`]: a [`ControlledNode`] on an [`EthLink`], in a thread of its own.
//!
//! The thread is promoted as a cyclic real-time thread
//! ([`motus_realtime::promote_current_thread`] with [`ThreadClass::Cyclic`]: `SCHED_FIFO`
//! when the process obtained it, else nice levels) with a 1 ns timer slack. For every frame
//! received, a PReq for the node is answered first with the PRes the node has prepared
//! ([`ControlledNode::pres_for`], no decoding), then the frame is handled and whatever the
//! node answers (ASnd in the async slot) is sent. The time from the frame's reception
//! (the link's receive time stamp) to the return of the PRes `send` is the turnaround,
//! kept for the last [`SampleWindow::CAPACITY`] PReq.
//!
//! Waiting for frames ([`CnWait`]): with [`CnWait::Sleep`] the thread sleeps in the link's
//! `recv` (on a raw socket a `ppoll` with a nanosecond time-out: the PReq wakes the thread,
//! which costs the kernel's wake-up latency, and on a virtual machine such a wake-up across
//! CPUs was sometimes late by milliseconds). With [`CnWait::Anticipate`] it sleeps until
//! shortly before the next PReq is due and polls the link from then until the PReq is there
//! ([`Anticipation`]): no wake-up by the frame, at the cost of the polling window each
//! cycle. With [`CnWait::Spin`] it polls the link without sleeping (`recv` with a zero
//! time-out in a loop: one busy core). Polling is bounded by the system clock, so a virtual
//! clock never makes it hang.
//!
//! Time comes from the [`SharedClock`] given to [`ControlledNodeRuntime::start`] (the node's
//! `now`, time-outs, sleeps after a receive error).

use std::io;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_clock::{Clock, SharedClock};
use motus_epl_protocol::NmtState;
use motus_realtime::ThreadClass;

use super::anticipation::{Anticipation, WaitStep};
use super::machine::{CnCounters, CnEvent, ControlledNode};
use crate::sim::stats::{Percentiles, SampleWindow};
use crate::transport::{EthLink, MAX_FRAME};

/// The longest the thread waits for a frame before it looks at its stop flag and deadlines.
const MAX_WAIT: Duration = Duration::from_millis(5);
/// Events kept for [`ControlledNodeRuntime::take_events`] at most; later ones are dropped
/// (and counted) until they are taken.
pub const EVENT_QUEUE: usize = 4096;

/// How the node's thread waits for frames (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CnWait {
    /// Sleep in `recv` until a frame wakes the thread (the default: no CPU while idle).
    #[default]
    Sleep,
    /// Sleep until shortly before the next PReq is due, then poll the link until it is
    /// there ([`Anticipation::host_default`]'s window in every cycle with PReqs).
    Anticipate,
    /// Poll the link without ever sleeping (one busy core).
    Spin,
}

/// How a [`ControlledNodeRuntime`] runs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CnRuntimeConfig {
    /// How the thread waits for frames.
    pub wait: CnWait,
    /// The class the thread is promoted to (default [`ThreadClass::Cyclic`]).
    pub class: ThreadClass,
    /// The CPU the thread is pinned to (`None`: wherever the scheduler puts it). Best the
    /// CPU where the segment's frames arrive (the NIC's interrupt, or on a veth segment the
    /// MN's CPU): the PReq then wakes the thread without crossing CPUs.
    pub cpu: Option<usize>,
}

impl Default for CnRuntimeConfig {
    fn default() -> Self {
        Self { wait: CnWait::Sleep, class: ThreadClass::Cyclic, cpu: None }
    }
}

/// What a [`ControlledNodeRuntime`] measured and counted.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CnRuntimeStats {
    /// PReq received -> PRes sent, in ns, over the last [`SampleWindow::CAPACITY`] PReq.
    pub turnaround: Percentiles,
    /// PRes sent.
    pub pres_sent: u64,
    /// Frames the link refused to send.
    pub send_errors: u64,
    /// Receive errors of the link.
    pub recv_errors: u64,
    /// Events dropped because nobody took them.
    pub events_dropped: u64,
    /// The node's counters.
    pub counters: CnCounters,
    /// The node's state.
    pub state: NmtState,
}

#[derive(Debug)]
struct Shared {
    state: AtomicU8,
    turnaround: Mutex<SampleWindow>,
    pres_sent: AtomicU64,
    send_errors: AtomicU64,
    recv_errors: AtomicU64,
    events_dropped: AtomicU64,
}

/// A [`ControlledNode`] running on a link (see the module documentation). Stop it with
/// [`ControlledNodeRuntime::stop`]; dropping it stops it too.
#[derive(Debug)]
pub struct ControlledNodeRuntime {
    node: Arc<Mutex<ControlledNode>>,
    shared: Arc<Shared>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    events: Receiver<CnEvent>,
    clock: SharedClock,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Whether the MN polls a CN in `state` with PReqs (PRE_OPERATIONAL_2, READY_TO_OPERATE,
/// OPERATIONAL).
fn polled_by_preq(state: NmtState) -> bool {
    matches!(state, NmtState::PreOperational2 | NmtState::ReadyToOperate | NmtState::Operational)
}

/// Receives a frame, spinning on the link until `timeout` has passed on the system clock.
fn spin_recv(link: &dyn EthLink, buf: &mut [u8], timeout: Duration) -> io::Result<Option<(usize, Instant)>> {
    let until = Instant::now() + timeout;
    loop {
        if let Some(got) = link.recv(buf, Duration::ZERO)? {
            return Ok(Some(got));
        }
        if Instant::now() >= until {
            return Ok(None);
        }
        std::hint::spin_loop();
    }
}

/// What [`serve_frame`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Served {
    /// The frame was a PReq for the node, answered with a PRes (sent or not).
    pub preq: bool,
    /// The frame was a PReq for the node, answered with a PRes whose `send` returned then.
    pub pres_sent_at: Option<Instant>,
    /// Frames that could not be sent.
    pub send_errors: u64,
}

/// Serves one received frame `raw` with `node` on `link`, as every Motus CN does: a PReq for
/// the node is answered first with the PRes it has prepared ([`ControlledNode::pres_for`], no
/// decoding), then the frame is handled at `clock`'s time and whatever the node answers (ASnd
/// in the async slot) is sent.
pub fn serve_frame(node: &mut ControlledNode, link: &dyn EthLink, clock: &dyn Clock, raw: &[u8]) -> Served {
    let mut served = Served::default();
    let answered = match node.pres_for(raw) {
        Some(pres) => {
            match link.send(pres) {
                Ok(()) => served.pres_sent_at = Some(clock.now()),
                Err(e) => {
                    served.send_errors += 1;
                    tracing::debug!("PRes not sent: {e}");
                }
            }
            true
        }
        None => false,
    };
    let now = clock.now();
    let out = if answered { node.on_answered_preq(now, raw) } else { node.on_frame(now, raw) };
    for frame in out {
        if let Err(e) = link.send(&frame) {
            served.send_errors += 1;
            tracing::debug!("frame not sent: {e}");
        }
    }
    served.preq = answered;
    served
}

/// The node's thread: everything the runtime shares with it.
struct Worker {
    node: Arc<Mutex<ControlledNode>>,
    link: Arc<dyn EthLink>,
    clock: SharedClock,
    shared: Arc<Shared>,
    stop: Arc<AtomicBool>,
    events: SyncSender<CnEvent>,
    config: CnRuntimeConfig,
}

impl Worker {
    fn run(self) {
        motus_realtime::promote_current_thread(self.config.class);
        if let Some(cpu) = self.config.cpu {
            if let Err(e) = motus_realtime::pin_current_thread(cpu) {
                tracing::warn!("{e}");
            }
        }
        if let Err(e) = nix::sys::prctl::set_timerslack(1) {
            tracing::debug!("timer slack: {e}");
        }
        let mut buf = vec![0u8; MAX_FRAME];
        let mut anticipation = Anticipation::host_default();
        while !self.stop.load(Ordering::Relaxed) {
            let now = self.clock.now();
            let (deadline, cycle) = {
                let node = lock(&self.node);
                (node.next_deadline(), node.cycle_len())
            };
            let wait = deadline.map_or(MAX_WAIT, |d| d.saturating_duration_since(now)).min(MAX_WAIT);
            let step = match self.config.wait {
                CnWait::Sleep => WaitStep::Sleep(wait),
                CnWait::Spin => WaitStep::Poll(wait),
                CnWait::Anticipate => anticipation.plan(now, cycle, wait),
            };
            let got = match step {
                WaitStep::Poll(d) => spin_recv(&*self.link, &mut buf, d),
                WaitStep::Sleep(d) => self.link.recv(&mut buf, d),
            };
            let mut node = lock(&self.node);
            match got {
                Ok(Some((n, at))) => {
                    if self.on_frame(&mut node, buf.get(..n).unwrap_or_default(), at) {
                        anticipation.on_preq(at);
                    }
                    if !polled_by_preq(node.state()) {
                        anticipation.forget();
                    }
                }
                Ok(None) => {}
                Err(e) => {
                    self.shared.recv_errors.fetch_add(1, Ordering::Relaxed);
                    tracing::warn!(link = %self.link.describe(), "recv: {e}");
                    drop(node);
                    self.clock.sleep(Duration::from_millis(5));
                    node = lock(&self.node);
                }
            }
            node.poll(self.clock.now());
            self.publish(&mut node);
        }
    }

    /// Serves one frame; whether it was a PReq for the node.
    fn on_frame(&self, node: &mut ControlledNode, raw: &[u8], at: Instant) -> bool {
        let served = serve_frame(node, &*self.link, &*self.clock, raw);
        if let Some(sent) = served.pres_sent_at {
            let ns = sent.saturating_duration_since(at).as_nanos();
            lock(&self.shared.turnaround).push(u64::try_from(ns).unwrap_or(u64::MAX));
            self.shared.pres_sent.fetch_add(1, Ordering::Relaxed);
        }
        self.shared.send_errors.fetch_add(served.send_errors, Ordering::Relaxed);
        served.preq
    }

    fn publish(&self, node: &mut ControlledNode) {
        self.shared.state.store(node.state().raw(), Ordering::Relaxed);
        for e in node.take_events() {
            if self.events.try_send(e).is_err() {
                self.shared.events_dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}

impl ControlledNodeRuntime {
    /// Starts `node` on `link` in a thread of its own (`epl-cn-<node>`), on `clock`.
    ///
    /// # Errors
    /// The thread could not be spawned.
    pub fn start(
        node: ControlledNode,
        link: Arc<dyn EthLink>,
        clock: SharedClock,
        config: CnRuntimeConfig,
    ) -> io::Result<Self> {
        let name = format!("epl-cn-{}", node.node_id());
        let shared = Arc::new(Shared {
            state: AtomicU8::new(node.state().raw()),
            turnaround: Mutex::new(SampleWindow::default()),
            pres_sent: AtomicU64::new(0),
            send_errors: AtomicU64::new(0),
            recv_errors: AtomicU64::new(0),
            events_dropped: AtomicU64::new(0),
        });
        let node = Arc::new(Mutex::new(node));
        let stop = Arc::new(AtomicBool::new(false));
        let (tx, events) = sync_channel(EVENT_QUEUE);
        let worker = Worker {
            node: Arc::clone(&node),
            link,
            clock: Arc::clone(&clock),
            shared: Arc::clone(&shared),
            stop: Arc::clone(&stop),
            events: tx,
            config,
        };
        let thread =
            motus_clock::spawn(&clock, std::thread::Builder::new().name(name), move || worker.run())?;
        Ok(Self { node, shared, stop, thread: Some(thread), events, clock })
    }

    /// The node's NMT state (as of its thread's last pass).
    pub fn state(&self) -> NmtState {
        NmtState::from_raw(self.shared.state.load(Ordering::Relaxed))
    }

    /// The events since the last call, oldest first.
    pub fn take_events(&self) -> Vec<CnEvent> {
        self.events.try_iter().collect()
    }

    /// Waits up to `timeout` for the next event.
    pub fn next_event(&self, timeout: Duration) -> Option<CnEvent> {
        self.events.recv_timeout(timeout).ok()
    }

    /// Runs `f` on the node (to read or change its dictionary: inputs, parameters), between
    /// two frames.
    pub fn with_node<R>(&self, f: impl FnOnce(&mut ControlledNode) -> R) -> R {
        f(&mut lock(&self.node))
    }

    /// The statistics so far.
    pub fn stats(&self) -> CnRuntimeStats {
        let turnaround = lock(&self.shared.turnaround).percentiles();
        let (counters, state) = {
            let node = lock(&self.node);
            (node.counters(), node.state())
        };
        CnRuntimeStats {
            turnaround,
            pres_sent: self.shared.pres_sent.load(Ordering::Relaxed),
            send_errors: self.shared.send_errors.load(Ordering::Relaxed),
            recv_errors: self.shared.recv_errors.load(Ordering::Relaxed),
            events_dropped: self.shared.events_dropped.load(Ordering::Relaxed),
            counters,
            state,
        }
    }

    /// Stops the thread and returns the final statistics.
    pub fn stop(mut self) -> CnRuntimeStats {
        self.halt();
        self.stats()
    }

    fn halt(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = motus_clock::while_blocked(&*self.clock, || t.join());
        }
    }
}

impl Drop for ControlledNodeRuntime {
    fn drop(&mut self) {
        self.halt();
    }
}
