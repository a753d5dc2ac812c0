//! Runs a [`CdcMn`] on an [`EthLink`] and a clock: one thread with absolute cycle deadlines
//! (like `sim::mn`), promoted to the cyclic real-time class
//! ([`motus_realtime::promote_current_thread`]), with the start lateness of every SoC
//! recorded (the SoC jitter).
//!
//! * Timing, on the clock ([`SharedClock`]): until [`RuntimeConfig::busy_wait`] before the
//!   deadline the thread receives (and hands the MN) stray frames, then
//!   [`motus_clock::Clock::sleep_until_precise`]. A cycle whose work overruns the next deadline
//!   skips it (counted). On a virtual clock every wait is a wait on the clock, so the cycle is
//!   exact.
//! * The thread publishes the MN's per-node reports and its events every
//!   [`RuntimeConfig::publish_every`] cycles to the [`MnHandle`].

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_clock::SharedClock;
use motus_epl_protocol::{EplFrame, Message, NmtState};

use super::{CdcMn, MnEvent, NodeReport};
use crate::sim::stats::{Percentiles, SampleWindow};
use crate::transport::{EthLink, MAX_FRAME};

/// Timing of the runtime.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RuntimeConfig {
    /// Stop receiving stray frames this long before each deadline and wait precisely.
    pub busy_wait: Duration,
    /// Poll the link without sleeping while waiting for a PRes or an ASnd (one busy core; on
    /// the system clock only).
    pub spin: bool,
    /// Publish reports and events to the handle every this many cycles.
    pub publish_every: u64,
}

impl Default for RuntimeConfig {
    fn default() -> Self {
        Self { busy_wait: Duration::from_micros(200), spin: false, publish_every: 10 }
    }
}

/// Counters of the runtime.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RuntimeStats {
    /// Cycles run (full and reduced).
    pub cycles: u64,
    /// Full cycles (with a SoC).
    pub full_cycles: u64,
    /// Deadlines skipped because a cycle's work overran them.
    pub overruns: u64,
    /// Frames that could not be sent.
    pub send_errors: u64,
    /// Frames received that did not decode.
    pub decode_errors: u64,
    /// Lateness of each SoC after its deadline, in ns: p50, p99, max.
    pub soc_late: Percentiles,
    /// PReq sent -> PRes received (in time), in ns, all CNs: p50, p99, max.
    pub pres_rtt: Percentiles,
    /// The MN's state.
    pub mn_state: Option<NmtState>,
}

#[derive(Debug, Default)]
struct Shared {
    /// SoC lateness samples (ns); the percentiles are computed by the handle, off the cycle
    /// thread (a sort of 64 Ki samples takes milliseconds).
    late: SampleWindow,
    /// PReq -> PRes round trips (ns).
    rtt: SampleWindow,
    nodes: Vec<NodeReport>,
    events: VecDeque<MnEvent>,
    stats: RuntimeStats,
    outputs: Vec<(u8, u16, u8, u64)>,
}

/// A running MN; stops and joins its thread on [`MnHandle::stop`] or drop.
pub struct MnHandle {
    clock: SharedClock,
    stop: Arc<AtomicBool>,
    shared: Arc<Mutex<Shared>>,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for MnHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MnHandle").finish_non_exhaustive()
    }
}

impl MnHandle {
    fn lock(&self) -> std::sync::MutexGuard<'_, Shared> {
        self.shared.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The latest per-node reports.
    pub fn nodes(&self) -> Vec<NodeReport> {
        self.lock().nodes.clone()
    }

    /// The events published since the last call, oldest first.
    pub fn take_events(&self) -> Vec<MnEvent> {
        self.lock().events.drain(..).collect()
    }

    /// The latest counters and SoC jitter.
    pub fn stats(&self) -> RuntimeStats {
        let (mut stats, late, rtt) = {
            let sh = self.lock();
            (sh.stats.clone(), sh.late.clone(), sh.rtt.clone())
        };
        stats.soc_late = late.percentiles();
        stats.pres_rtt = rtt.percentiles();
        stats
    }

    /// Sets an output value (see [`CdcMn::set_output`]); applied at the next publication.
    pub fn set_output(&self, node: u8, index: u16, subindex: u8, value: u64) {
        self.lock().outputs.push((node, index, subindex, value));
    }

    /// Whether the MN's thread ended (it ends only when stopped, or if it panicked).
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().map_or(true, JoinHandle::is_finished)
    }

    /// Stops the MN and returns its final counters.
    pub fn stop(mut self) -> RuntimeStats {
        self.halt();
        self.stats()
    }

    fn halt(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            // The thread runs on the clock: time must move for it meanwhile.
            if motus_clock::while_blocked(&*self.clock, || t.join()).is_err() {
                tracing::warn!("the MN thread panicked");
            }
        }
    }
}

impl Drop for MnHandle {
    fn drop(&mut self) {
        self.halt();
    }
}

/// Starts `mn` on `link` and `clock` in a thread named `epl-cdc-mn`.
///
/// # Errors
/// The thread could not be spawned.
pub fn spawn(
    link: Arc<dyn EthLink>,
    clock: SharedClock,
    mn: CdcMn,
    config: RuntimeConfig,
) -> std::io::Result<MnHandle> {
    let stop = Arc::new(AtomicBool::new(false));
    let shared = Arc::new(Mutex::new(Shared { nodes: mn.nodes(), ..Shared::default() }));
    let mut runtime = MnRuntime {
        link,
        clock: Arc::clone(&clock),
        mn,
        config,
        stats: RuntimeStats::default(),
        pending_late: Vec::with_capacity(MAX_PENDING),
        pending_rtt: Vec::with_capacity(MAX_PENDING),
        buf: vec![0; MAX_FRAME],
        out: Vec::with_capacity(MAX_FRAME),
        shared: Arc::clone(&shared),
    };
    let stop_thread = Arc::clone(&stop);
    let thread =
        motus_clock::spawn(&clock, std::thread::Builder::new().name("epl-cdc-mn".into()), move || {
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Cyclic);
            runtime.run(&stop_thread);
        })?;
    Ok(MnHandle { clock, stop, shared, thread: Some(thread) })
}

struct MnRuntime {
    link: Arc<dyn EthLink>,
    clock: SharedClock,
    mn: CdcMn,
    config: RuntimeConfig,
    stats: RuntimeStats,
    /// SoC lateness samples not yet handed to [`Shared::late`].
    pending_late: Vec<u64>,
    /// PReq -> PRes samples not yet handed to [`Shared::rtt`].
    pending_rtt: Vec<u64>,
    buf: Vec<u8>,
    out: Vec<u8>,
    shared: Arc<Mutex<Shared>>,
}

impl MnRuntime {
    fn send(&mut self, frame: &EplFrame) {
        self.out.clear();
        let ok = frame.encode_into(&mut self.out).is_ok() && self.link.send(&self.out).is_ok();
        if !ok {
            self.stats.send_errors += 1;
        }
    }

    /// Receives frames until `deadline`, handing each to the MN, and returns when one is the
    /// awaited answer (`true`) or the deadline passes (`false`).
    fn wait(&mut self, deadline: Instant, expect_pres: Option<u8>, answer_expected: bool) -> bool {
        loop {
            let now = self.clock.now();
            if now >= deadline {
                return false;
            }
            let received = if self.config.spin {
                self.link.recv(&mut self.buf, Duration::ZERO)
            } else {
                self.link.recv(&mut self.buf, deadline - now)
            };
            let n = match received {
                Ok(Some((n, _))) => n,
                Ok(None) => {
                    if self.config.spin {
                        std::hint::spin_loop();
                    }
                    continue;
                }
                Err(e) => {
                    tracing::debug!("receive: {e}");
                    self.clock.sleep_until(deadline.min(now + Duration::from_micros(100)));
                    continue;
                }
            };
            let frame = match EplFrame::decode(self.buf.get(..n).unwrap_or(&[])) {
                Ok(f) => f,
                Err(_) => {
                    self.stats.decode_errors += 1;
                    continue;
                }
            };
            if frame.src_node == motus_epl_protocol::MN_NODE_ID {
                continue;
            }
            let now = self.clock.now();
            let answered = self.mn.on_frame(now, &frame, expect_pres);
            if answered && (answer_expected || matches!(frame.message, Message::PRes(_))) {
                return true;
            }
        }
    }

    /// Hands reports, events and samples to the handle; skipped (`false`) when the handle
    /// holds the lock and `wait` is not set (the cycle thread never waits for it).
    fn publish(&mut self, wait: bool) -> bool {
        self.stats.mn_state = Some(self.mn.state());
        let nodes = self.mn.nodes();
        let outputs = {
            let mut sh = if wait {
                self.shared.lock().unwrap_or_else(PoisonError::into_inner)
            } else {
                match self.shared.try_lock() {
                    Ok(g) => g,
                    Err(std::sync::TryLockError::Poisoned(p)) => p.into_inner(),
                    Err(std::sync::TryLockError::WouldBlock) => return false,
                }
            };
            let mut events = Vec::new();
            while let Some(e) = self.mn.pop_event() {
                events.push(e);
            }
            for x in self.pending_late.drain(..) {
                sh.late.push(x);
            }
            for x in self.pending_rtt.drain(..) {
                sh.rtt.push(x);
            }
            sh.nodes = nodes;
            sh.events.extend(events);
            while sh.events.len() > 4096 {
                sh.events.pop_front();
            }
            sh.stats = self.stats.clone();
            std::mem::take(&mut sh.outputs)
        };
        for (node, index, sub, value) in outputs {
            if !self.mn.set_output(node, index, sub, value) {
                tracing::warn!(node, index, sub, "output not mapped");
            }
        }
        true
    }

    fn run(&mut self, stop: &AtomicBool) {
        if let Err(e) = nix::sys::prctl::set_timerslack(1) {
            tracing::debug!("timer slack: {e}");
        }
        let cycle = self.mn.cycle();
        let mut deadline = self.clock.now() + cycle;
        while !stop.load(Ordering::Relaxed) {
            // Stray frames until shortly before the deadline, then a precise wait.
            let wake = deadline.checked_sub(self.config.busy_wait).unwrap_or(deadline);
            self.wait(wake, None, false);
            self.clock.sleep_until_precise(deadline);
            let start = self.clock.now();
            self.stats.cycles += 1;
            let next = deadline + cycle;
            if self.mn.start_cycle(start) {
                self.stats.full_cycles += 1;
                if self.pending_late.len() < MAX_PENDING {
                    let late = start.saturating_duration_since(deadline).as_nanos();
                    self.pending_late.push(u64::try_from(late).unwrap_or(u64::MAX));
                }
                let soc = self.mn.soc(deadline);
                self.send(&soc);
                for node in self.mn.poll_list() {
                    let Some(preq) = self.mn.preq(node) else { continue };
                    let timeout = self.mn.pres_timeout(node);
                    let sent = self.clock.now();
                    self.send(&preq);
                    let until = (sent + timeout).min(next);
                    if self.wait(until, Some(node), false) {
                        if self.pending_rtt.len() < MAX_PENDING {
                            let rtt = self.clock.now().saturating_duration_since(sent).as_nanos();
                            self.pending_rtt.push(u64::try_from(rtt).unwrap_or(u64::MAX));
                        }
                    } else {
                        self.mn.pres_missed(node);
                    }
                }
            }
            let now = self.clock.now();
            for f in self.mn.async_slot(now) {
                self.send(&f);
            }
            if self.mn.awaited().is_some() {
                let cap = next.checked_sub(self.config.busy_wait).unwrap_or(next);
                let until = (self.clock.now() + self.mn.async_timeout()).min(cap);
                self.wait(until, None, true);
            }
            self.mn.end_cycle(self.clock.now());
            if self.stats.cycles % self.config.publish_every.max(1) == 0 {
                self.publish(false);
            }
            deadline = next;
            let now = self.clock.now();
            if now > deadline {
                self.stats.overruns += 1;
                while deadline < now {
                    deadline += cycle;
                }
            }
        }
        self.publish(true);
    }
}

/// SoC lateness samples kept on the cycle thread between two publications at most.
const MAX_PENDING: usize = 4096;
