//! A simulated POWERLINK segment: one Managing Node ([`MnConfig`]) and Controlled Nodes that
//! behave like servo drives ([`DriveParams`]), each on its own [`EthLink`]. The MN has a
//! thread; a CN runs in the sending thread when its link can ([`EthLink::attach_receiver`]:
//! an in-process `mem://` segment, where a PReq is answered inside the MN's send), else on a
//! receiving thread of its own.
//!
//! The segment runs on a clock ([`SegmentBuilder::clock`], the system clock by default). On a
//! threaded [`motus_clock::VirtualClock`] shared with a [`crate::transport::MemHub`] made on
//! it ([`crate::transport::MemHub::with_clock`]), the MN's cycle thread and every other thread
//! of the test take part in the clock's time: the cycle, its time-outs and every figure of
//! [`MnStats`] are exact, and seconds of cycles run in a fraction of that in wall time.
//!
//! ```no_run
//! use std::sync::Arc;
//! use std::time::Duration;
//! use motus_epl::sim::{CamAxis, CamProgram, DriveParams, Segment};
//! use motus_epl::UdpHub;
//!
//! let hub = UdpHub::new();
//! let mut builder = Segment::builder().cycle(Duration::from_millis(1));
//! builder = builder.mn_link(Arc::new(hub.connect()?));
//! for node in 1..=5 {
//!     builder = builder.drive(node, Arc::new(hub.connect()?), DriveParams::default());
//! }
//! let axes = vec![CamAxis { center: 0.0, amplitude: 500.0, period: 1.0, phase: 0.0 }; 5];
//! let segment = builder.program(Box::new(CamProgram::new(axes))).start()?;
//! assert!(segment.wait_operational(Duration::from_secs(5)));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod axis;
mod cn;
mod mn;
pub mod pdo;
pub mod program;
pub mod stats;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use motus_clock::{SharedClock, SystemClock};
use motus_epl_protocol::{NmtState, BROADCAST_NODE_ID, MN_NODE_ID};
use thiserror::Error;

pub use axis::{AxisModel, DriveParams};
pub use mn::MnConfig;
pub use pdo::{Actual, SetPoint};
pub use program::{CamAxis, CamProgram, MotionProgram, SetpointList};
pub use stats::{CnChange, CnEvent, MnStats, Percentiles};

use crate::transport::EthLink;

/// Why a segment could not start.
#[derive(Debug, Error)]
pub enum SegmentError {
    /// No link was given for the Managing Node.
    #[error("segment: no link for the managing node")]
    NoMnLink,
    /// A CN node ID outside 1..=239.
    #[error("segment: node ID {0} is not a controlled node (1..=239)")]
    InvalidNode(u8),
    /// A node ID given twice.
    #[error("segment: node {0} added twice")]
    DuplicateNode(u8),
    /// A zero cycle time or PRes time-out.
    #[error("segment: {0} must not be zero")]
    ZeroTime(&'static str),
    /// A thread could not be spawned.
    #[error("segment: spawning a thread: {0}")]
    Spawn(#[from] std::io::Error),
    /// A thread cannot be pinned to the CPU asked for ([`SegmentBuilder::pin_mn`],
    /// [`SegmentBuilder::pin_spinning_cns`]).
    #[error("segment: {0}")]
    Affinity(#[from] motus_realtime::affinity::AffinityError),
}

/// Builds a [`Segment`].
#[derive(Default)]
pub struct SegmentBuilder {
    mn: Option<Arc<dyn EthLink>>,
    drives: Vec<(u8, Arc<dyn EthLink>, DriveParams)>,
    polled: Vec<u8>,
    config: MnConfig,
    program: Option<Box<dyn MotionProgram>>,
    spin_cns: bool,
    mn_cpu: Option<usize>,
    spinning_cns_cpu: Option<usize>,
    clock: Option<SharedClock>,
}

impl SegmentBuilder {
    /// The Managing Node's link.
    pub fn mn_link(mut self, link: Arc<dyn EthLink>) -> Self {
        self.mn = Some(link);
        self
    }

    /// Adds a drive CN with node ID `node` on `link`.
    pub fn drive(mut self, node: u8, link: Arc<dyn EthLink>, params: DriveParams) -> Self {
        self.drives.push((node, link, params));
        self
    }

    /// Adds a CN that the MN boots and polls (after the drives, with an empty PReq) but that
    /// the segment does not simulate: a node served elsewhere, such as the supervisor as a
    /// safety node (`motus safety run --node`), whose PRes the drives read
    /// ([`DriveParams::safety_node`]). The MN waits for it to be OPERATIONAL before the
    /// program starts.
    pub fn polled_node(mut self, node: u8) -> Self {
        self.polled.push(node);
        self
    }

    /// The whole MN timing configuration.
    pub fn config(mut self, config: MnConfig) -> Self {
        self.config = config;
        self
    }

    /// The cycle period.
    pub fn cycle(mut self, cycle: Duration) -> Self {
        self.config.cycle = cycle;
        self
    }

    /// The PRes time-out.
    pub fn pres_timeout(mut self, timeout: Duration) -> Self {
        self.config.pres_timeout = timeout;
        self
    }

    /// Serve every CN from one thread that polls their links without sleeping (one busy
    /// core; a PReq is answered within microseconds instead of a thread wake-up, which is
    /// what lets five drives fit in a 400 us cycle between user-space threads).
    pub fn spin_cns(mut self, on: bool) -> Self {
        self.spin_cns = on;
        self
    }

    /// Pins the MN's thread to `cpu`. With [`MnConfig::spin_for_pres`] and
    /// [`SegmentBuilder::spin_cns`] two threads poll without sleeping; left to the scheduler
    /// they now and then share one core for milliseconds (every PRes of those cycles late):
    /// pinned to two CPUs they do not (`docs/decisions.md`). Checked at
    /// [`SegmentBuilder::start`].
    pub fn pin_mn(mut self, cpu: usize) -> Self {
        self.mn_cpu = Some(cpu);
        self
    }

    /// Pins the thread that serves the CNs by polling ([`SegmentBuilder::spin_cns`]) to
    /// `cpu` (ignored when the CNs do not spin). Checked at [`SegmentBuilder::start`].
    pub fn pin_spinning_cns(mut self, cpu: usize) -> Self {
        self.spinning_cns_cpu = Some(cpu);
        self
    }

    /// Runs the segment on `clock` instead of the system clock: the MN's cycle, its time-outs
    /// and its statistics, and the CNs' threads if any (an in-process segment on the same
    /// clock: [`crate::transport::MemHub::with_clock`]). The segment never busy-waits on a
    /// clock given here ([`MnConfig::busy_wait`], [`MnConfig::spin_for_pres`] and
    /// [`SegmentBuilder::spin_cns`] are ignored): only the system clock, the default, moves
    /// while a thread spins.
    pub fn clock(mut self, clock: SharedClock) -> Self {
        self.clock = Some(clock);
        self
    }

    /// The motion program run once OPERATIONAL (without one, drives hold their start position).
    pub fn program(mut self, program: Box<dyn MotionProgram>) -> Self {
        self.program = Some(program);
        self
    }

    /// Starts the CN threads and the MN thread.
    pub fn start(self) -> Result<Segment, SegmentError> {
        let mn_link = self.mn.ok_or(SegmentError::NoMnLink)?;
        if self.config.cycle.is_zero() {
            return Err(SegmentError::ZeroTime("cycle"));
        }
        if self.config.pres_timeout.is_zero() {
            return Err(SegmentError::ZeroTime("PRes time-out"));
        }
        let mut seen = Vec::new();
        for node in self.drives.iter().map(|(n, _, _)| n).chain(&self.polled) {
            if *node == 0 || *node >= MN_NODE_ID || *node == BROADCAST_NODE_ID {
                return Err(SegmentError::InvalidNode(*node));
            }
            if seen.contains(node) {
                return Err(SegmentError::DuplicateNode(*node));
            }
            seen.push(*node);
        }
        // Busy waiting only on the system clock (a virtual clock does not move while a thread
        // spins).
        let spinning_allowed = self.clock.is_none();
        let clock = self.clock.unwrap_or_else(SystemClock::shared);
        let mut config = self.config;
        if !spinning_allowed {
            config.busy_wait = Duration::ZERO;
            config.spin_for_pres = false;
        }
        let spin_cns = self.spin_cns && spinning_allowed;
        let spinning_cns_cpu = self.spinning_cns_cpu.filter(|_| spin_cns);
        for cpu in self.mn_cpu.iter().chain(&spinning_cns_cpu) {
            motus_realtime::affinity::check_cpu(*cpu)?;
        }
        let stop = Arc::new(AtomicBool::new(false));
        let mut threads = Vec::new();
        let mut cns = Vec::new();
        let mut nodes = Vec::new();
        let mut spinning = Vec::new();
        let mut attached = Vec::new();
        for (node, link, params) in self.drives {
            let shared = Arc::new(cn::CnShared::new());
            let cn = cn::Cn::new(node, link, params, Arc::clone(&shared));
            let link = cn.link();
            if spin_cns {
                spinning.push((link, cn.into_handler()));
            } else {
                match link.attach_receiver(cn.into_handler()) {
                    Ok(()) => attached.push(link),
                    Err(handler) => threads.push(crate::transport::serve_on_thread(
                        format!("epl-cn{node}"),
                        link,
                        handler,
                        Arc::clone(&stop),
                        motus_realtime::ThreadClass::Simulator,
                        &clock,
                    )?),
                }
            }
            cns.push((node, shared));
            nodes.push((node, params.initial_position.round() as i32));
        }
        if !spinning.is_empty() {
            let stop = Arc::clone(&stop);
            threads.push(
                std::thread::Builder::new()
                    .name("epl-cns".into())
                    // Not promoted: a thread that polls without sleeping under SCHED_FIFO would
                    // take its CPU from every normal thread (motus_realtime).
                    .spawn(move || {
                        pin_or_warn(spinning_cns_cpu, "epl-cns");
                        cn::run_spinning(spinning, &stop)
                    })?,
            );
        }
        let mn_shared = Arc::new(mn::MnShared::default());
        let mn = mn::Mn::new(
            mn_link,
            Arc::clone(&clock),
            config,
            &nodes,
            &self.polled,
            self.program,
            Arc::clone(&mn_shared),
        );
        let stop_mn = Arc::clone(&stop);
        let mn_cpu = self.mn_cpu;
        let started =
            motus_clock::spawn(&clock, std::thread::Builder::new().name("epl-mn".into()), move || {
                motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Cyclic);
                pin_or_warn(mn_cpu, "epl-mn");
                mn.run(&stop_mn)
            });
        match started {
            Ok(t) => threads.push(t),
            Err(e) => {
                stop.store(true, Ordering::Relaxed);
                for link in &attached {
                    link.detach_receiver();
                }
                return Err(e.into());
            }
        }
        Ok(Segment { stop, threads, attached, mn: mn_shared, cns, clock })
    }
}

/// Pins the calling thread to `cpu` if given (checked before the thread started: a failure
/// here is the kernel's, logged, and the thread runs unpinned).
fn pin_or_warn(cpu: Option<usize>, thread: &str) {
    if let Some(cpu) = cpu {
        if let Err(e) = motus_realtime::affinity::pin_current_thread(cpu) {
            tracing::warn!(thread, error = %e, "segment: thread not pinned");
        }
    }
}

/// A running simulated segment; stops (and joins its threads) on [`Segment::stop`] or drop.
pub struct Segment {
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
    /// Links whose CN runs in the sending thread (detached on stop).
    attached: Vec<Arc<dyn EthLink>>,
    mn: Arc<mn::MnShared>,
    cns: Vec<(u8, Arc<cn::CnShared>)>,
    clock: SharedClock,
}

impl Segment {
    /// A builder with the default [`MnConfig`].
    pub fn builder() -> SegmentBuilder {
        SegmentBuilder::default()
    }

    /// The MN's NMT state.
    pub fn mn_state(&self) -> NmtState {
        NmtState::from_raw(self.mn.state.load(Ordering::Relaxed))
    }

    /// The NMT state of CN `node` as the CN itself holds it.
    pub fn cn_state(&self, node: u8) -> Option<NmtState> {
        self.cns
            .iter()
            .find(|(n, _)| *n == node)
            .map(|(_, s)| NmtState::from_raw(s.state.load(Ordering::Relaxed)))
    }

    /// Pulls (`true`) or plugs back (`false`) the cable of CN `node`: while unplugged it
    /// receives and sends nothing (a CN gone silent; see [`MnConfig::lost_after`] and
    /// [`DriveParams::soc_loss_tolerance`] for what follows). False when there is no such CN.
    pub fn unplug(&self, node: u8, unplugged: bool) -> bool {
        let Some((_, cn)) = self.cns.iter().find(|(n, _)| *n == node) else { return false };
        cn.unplugged.store(unplugged, Ordering::Relaxed);
        true
    }

    /// The segment's clock.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }

    /// Waits until the MN is OPERATIONAL, looking every 5 ms of the segment's clock; false on
    /// time-out.
    pub fn wait_operational(&self, timeout: Duration) -> bool {
        let end = self.clock.now() + timeout;
        while self.clock.now() < end {
            if self.mn_state() == NmtState::Operational {
                return true;
            }
            self.clock.sleep(Duration::from_millis(5));
        }
        self.mn_state() == NmtState::Operational
    }

    /// Sets or clears the quick-stop bit the MN sends to every drive.
    pub fn quick_stop(&self, on: bool) {
        self.mn.quick_stop.store(on, Ordering::Relaxed);
    }

    /// A copy of the MN statistics.
    pub fn stats(&self) -> MnStats {
        self.mn.stats.lock().unwrap_or_else(PoisonError::into_inner).clone()
    }

    /// Clears the MN statistics (e.g. after boot-up).
    pub fn reset_stats(&self) {
        *self.mn.stats.lock().unwrap_or_else(PoisonError::into_inner) = MnStats::default();
    }

    /// Stops every thread and returns the final statistics.
    pub fn stop(mut self) -> MnStats {
        self.shutdown();
        self.stats()
    }

    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            // The thread runs on the segment's clock: time must move for it meanwhile.
            if motus_clock::while_blocked(&*self.clock, || t.join()).is_err() {
                tracing::warn!("a segment thread panicked");
            }
        }
        // The MN is stopped: no more frames reach these CNs from it.
        for link in self.attached.drain(..) {
            link.detach_receiver();
        }
    }
}

impl Drop for Segment {
    fn drop(&mut self) {
        self.shutdown();
    }
}
