//! The NFv2 bus scheduler: one thread sends every slave **one frame per cycle** carrying
//! everything due for it — set-points not yet acknowledged, the active set-point (re-sent
//! every cycle for the 1209A's 2 s command watchdog), and the queries (the position every
//! cycle, the drive status in two frames of three and the device status in the third, in
//! rotating orders, current and digital inputs every few cycles) — built with the codec
//! and exchanged through [`motus_serial::BusMaster::transact`], accepting only an answer
//! of the expected shape from the addressed slave. NFv2 answers carry no sequence number;
//! the rotation makes a late answer to one of the two previous frames of a slave
//! unacceptable as the answer to the current one.
//!
//! Before the first cycle it computes the [`CyclePlan`] of its steady frames at the line's
//! baud rate and **warns** (`tracing::warn!`, and [`CyclePlan::feasible`] /
//! [`CycleStats::feasible`]) if the requested cycle is shorter than the wire allows; it
//! then runs at the minimum instead. A zero cycle means "as fast as the line allows".
//!
//! A missing, corrupt or misshapen answer is a **missed sample** for that slave and cycle
//! (counted), never a wrong value; its set-points stay due and go out again next cycle.
//! Cyclic frames are not retried (the next cycle carries fresher values). Cycles start on
//! a fixed grid; a cycle whose exchanges outlast the period (a missed answer costs its
//! time-out margin) is an overrun: the next one starts at once and the following ones
//! catch up, so the mean cycle stays the requested one while the line has slack. [`Packing::Unpacked`] sends one command or query per frame instead, for
//! comparison (every query frame of a slave then has the same shape, so a late answer
//! can pass for the next one; the plausibility gate is the only guard).
//!
//! Raw frames from other threads ([`Scheduler::transact`]) interleave between cycle
//! exchanges on the same bus master.
//!
//! # Time
//! The scheduler reads time and waits through a [`motus_clock::Clock`]: the cycle grid,
//! the timestamps of requests and answers, the statistics' window, and every wait of its
//! [`Drive`] handles and of the axes and head built on them. [`Scheduler::start`] takes the
//! clock of the bus master ([`motus_serial::BusMaster::clock`]: the system clock unless the
//! master was made with [`motus_serial::BusMaster::with_clock`]), so the line's time-outs and
//! the cycle run on one clock; [`Scheduler::start_with_clock`] names it. On a threaded
//! [`motus_clock::VirtualClock`] the cycle thread takes part in the clock's time (it is
//! started with [`motus_clock::spawn`]), so a driver and an in-process simulator
//! ([`motus_serial::SimLink`]) run on virtual time.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use motus_clock::SharedClock;
use motus_nfv2_protocol::{Command, CommandCode as C, Frame};

use crate::bus::{Exchanged, Nfv2Bus};
use crate::drive::runtime::{DriveRuntime, Outcome, Timing};
use crate::drive::{Drive, DriveConfig};
use crate::error::Nfv2Error;
use crate::plan::{unpack, CyclePlan, Packing};
use crate::stats::{CycleStats, Recorder};

/// Scheduler settings.
#[derive(Debug, Clone, PartialEq)]
pub struct SchedulerConfig {
    /// Requested cycle (default 15 ms; zero: back to back, as fast as the line allows,
    /// without the impossibility warning).
    pub cycle: Duration,
    /// One frame per slave per cycle, or one command per frame.
    pub packing: Packing,
    /// Slave processing plus line turnaround before an answer (default 0.2 ms, the
    /// 1209A answering from its receive interrupt).
    pub turnaround: Duration,
    /// Read the motor current every this many cycles (0: never; default 10).
    pub current_every: u32,
    /// Read the digital inputs every this many cycles (0: only when a fault needs its
    /// cause; default 50).
    pub inputs_every: u32,
    /// Query the position twice per frame and accept only equal values (guards against
    /// the corruptions the NFv2 CRC-8 misses, at 8 bytes per slave and cycle).
    pub verify_position: bool,
    /// Mean age of the values in an answer when the request arrives (half the 1209A's
    /// 1 ms regulator period; see [`crate::samples::latch_correction`]).
    pub latch_age: Duration,
    /// Position samples kept per slave (default 8192: about two minutes at 15 ms).
    pub history: usize,
    /// Extrapolation allowed after the newest sample for "position at t" (default 10 ms).
    pub where_margin: Duration,
    /// Longest gap between samples interpolated across (default 40 ms, one missed sample
    /// at 15 ms: linear interpolation across 40 ms of a 120 deg/s² motion is off by at
    /// most 0.025 deg).
    pub max_gap: Duration,
    /// A position sample whose exchange was held up (by the host or the line) by more
    /// than this, beyond an unhindered one, is not used for "position at t" (default
    /// 2 ms; see [`crate::samples::SampleHistory::max_delay`]).
    pub where_max_delay: Duration,
    /// A held-up sample is used all the same when it and its neighbours agree within this
    /// many counts: the axis stood still (default 2; see
    /// [`crate::samples::SampleHistory::still_band`]).
    pub where_still_band: i64,
    /// Position gain of streaming, 1/s (default 8).
    pub stream_gain: f64,
    /// How long a command may wait for its acknowledgement (default 1 s).
    pub confirm_timeout: Duration,
    /// No valid answer for this long is a communication fault (default 500 ms).
    pub silence: Duration,
}

impl Default for SchedulerConfig {
    fn default() -> Self {
        SchedulerConfig {
            cycle: Duration::from_millis(15),
            packing: Packing::Packed,
            turnaround: Duration::from_micros(200),
            current_every: 10,
            inputs_every: 50,
            verify_position: false,
            latch_age: Duration::from_micros(500),
            history: 8192,
            where_margin: Duration::from_millis(10),
            max_gap: Duration::from_millis(40),
            where_max_delay: crate::samples::DEFAULT_MAX_DELAY,
            where_still_band: crate::samples::DEFAULT_STILL_BAND,
            stream_gain: 8.0,
            confirm_timeout: Duration::from_secs(1),
            silence: Duration::from_millis(500),
        }
    }
}

/// The state the cycle thread and the handles share.
pub(crate) struct State {
    pub(crate) drives: Vec<DriveRuntime>,
    pub(crate) recorder: Recorder,
    seq: u64,
}

/// Shared by the scheduler, its thread and the drive handles.
pub(crate) struct Inner {
    pub(crate) bus: Nfv2Bus,
    pub(crate) config: SchedulerConfig,
    pub(crate) plan: CyclePlan,
    /// What the cycle thread and the handles read time from and wait on.
    pub(crate) clock: SharedClock,
    state: Mutex<State>,
    stop: AtomicBool,
    running: AtomicBool,
}

impl Inner {
    pub(crate) fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    pub(crate) fn running(&self) -> bool {
        self.running.load(Ordering::Relaxed)
    }
}

/// The bus scheduler (see the module documentation). Dropping it stops the thread.
pub struct Scheduler {
    inner: Arc<Inner>,
    thread: Mutex<Option<JoinHandle<()>>>,
}

/// The frame a slave gets every cycle in steady state: the active set-point and the
/// per-cycle queries.
fn steady_frame(address: u8, config: &SchedulerConfig) -> Frame {
    let mut commands =
        vec![Command::values(C::SetDrivesPosition, [0]), Command::query(C::ReadDrivesPosition)];
    if config.verify_position {
        commands.push(Command::query(C::ReadDrivesPosition));
    }
    commands.push(Command::query(C::ReadDrivesStatus));
    if config.current_every == 1 {
        commands.push(Command::query(C::ReadDrivesCurrent));
    }
    Frame { address, commands }
}

impl Scheduler {
    /// Starts cycling the 1209A drives `drives` on `bus`, on the clock of its bus master.
    ///
    /// # Errors
    /// [`Nfv2Error::InvalidArgument`] for no drive or a duplicate address,
    /// [`Nfv2Error::Encode`] if a steady frame cannot be built for a drive's revision,
    /// [`Nfv2Error::Open`] if the thread cannot start.
    pub fn start(
        bus: Nfv2Bus,
        drives: Vec<DriveConfig>,
        config: SchedulerConfig,
    ) -> Result<Scheduler, Nfv2Error> {
        let clock = Arc::clone(bus.master().clock());
        Self::start_with_clock(bus, drives, config, clock)
    }

    /// As [`Scheduler::start`], reading time from and waiting on `clock` (see the module
    /// documentation; the bus master's own waits stay on its clock, which should be the
    /// same): the cycle thread is started with [`motus_clock::spawn`].
    ///
    /// # Errors
    /// As [`Scheduler::start`].
    pub fn start_with_clock(
        bus: Nfv2Bus,
        drives: Vec<DriveConfig>,
        config: SchedulerConfig,
        clock: SharedClock,
    ) -> Result<Scheduler, Nfv2Error> {
        if drives.is_empty() {
            return Err(Nfv2Error::InvalidArgument("the scheduler needs at least one drive".into()));
        }
        let mut addresses: Vec<u8> = drives.iter().map(|d| d.address).collect();
        addresses.sort_unstable();
        if let Some(w) = addresses.windows(2).find(|w| w.first() == w.get(1)) {
            return Err(Nfv2Error::InvalidArgument(format!("address {:?} is given twice", w.first())));
        }
        let baud = bus.master().line().baud;
        let frames: Vec<(Frame, _)> =
            drives.iter().map(|d| (steady_frame(d.address, &config), bus.revision(d.address))).collect();
        let plan =
            CyclePlan::new(config.cycle, baud, config.turnaround, config.packing, &frames, bus.profile())?;
        if !config.cycle.is_zero() {
            if let Some(w) = plan.warning() {
                tracing::warn!("{w}");
            }
        }
        tracing::info!("{plan}");
        let order: Vec<u8> = drives.iter().map(|d| d.address).collect();
        let now = clock.now();
        let runtimes = drives.into_iter().map(|d| {
            let rev = bus.revision(d.address);
            DriveRuntime::new(d, rev, &config, now)
        });
        let state = State { drives: runtimes.collect(), recorder: Recorder::new(&order, now), seq: 0 };
        let inner = Arc::new(Inner {
            bus,
            config,
            plan,
            clock,
            state: Mutex::new(state),
            stop: AtomicBool::new(false),
            running: AtomicBool::new(true),
        });
        let worker = inner.clone();
        let builder = std::thread::Builder::new().name("nfv2-scheduler".into());
        let thread = motus_clock::spawn(&inner.clock, builder, move || {
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Cyclic);
            run(&worker)
        })
        .map_err(|e| Nfv2Error::Open { path: "scheduler thread".into(), reason: e.to_string() })?;
        Ok(Scheduler { inner, thread: Mutex::new(Some(thread)) })
    }

    /// The drive at `address`.
    ///
    /// # Errors
    /// [`Nfv2Error::UnknownSlave`].
    pub fn drive(&self, address: u8) -> Result<Drive, Nfv2Error> {
        let index = self.inner.lock().drives.iter().position(|d| d.address() == address);
        index.map(|i| Drive::new(self.inner.clone(), i, address)).ok_or(Nfv2Error::UnknownSlave(address))
    }

    /// Every drive, in cycle order.
    #[must_use]
    pub fn drives(&self) -> Vec<Drive> {
        let addresses: Vec<u8> = self.inner.lock().drives.iter().map(DriveRuntime::address).collect();
        addresses.into_iter().enumerate().map(|(i, a)| Drive::new(self.inner.clone(), i, a)).collect()
    }

    /// The wire budget computed at start.
    #[must_use]
    pub fn plan(&self) -> &CyclePlan {
        &self.inner.plan
    }

    /// The settings.
    #[must_use]
    pub fn config(&self) -> &SchedulerConfig {
        &self.inner.config
    }

    /// The bus.
    #[must_use]
    pub fn bus(&self) -> &Nfv2Bus {
        &self.inner.bus
    }

    /// The clock the scheduler and its drives read time from and wait on.
    #[must_use]
    pub fn clock(&self) -> &SharedClock {
        &self.inner.clock
    }

    /// Statistics since the start or the last [`Scheduler::reset_stats`].
    #[must_use]
    pub fn stats(&self) -> CycleStats {
        let p = &self.inner.plan;
        let now = self.inner.clock.now();
        self.inner.lock().recorder.snapshot(p.requested, p.min_cycle, p.baud, now)
    }

    /// Restarts the statistics window.
    pub fn reset_stats(&self) {
        let now = self.inner.clock.now();
        self.inner.lock().recorder.reset(now);
    }

    /// Sends a raw frame between two cycle exchanges and returns the answer, if any.
    ///
    /// # Errors
    /// As [`Nfv2Bus::transact`].
    pub fn transact(&self, frame: &Frame) -> Result<Option<Frame>, Nfv2Error> {
        self.inner.bus.transact(frame)
    }

    /// True while the cycle thread runs.
    #[must_use]
    pub fn is_running(&self) -> bool {
        self.inner.running()
    }

    /// Stops the cycle thread (the drives keep their last set-points; a SPEED or
    /// POS_INCREMENT set-point is zeroed by the drive's watchdog after 2 s).
    pub fn shutdown(&self) {
        self.inner.stop.store(true, Ordering::Relaxed);
        let thread = self.thread.lock().unwrap_or_else(PoisonError::into_inner).take();
        if let Some(t) = thread {
            // The cycle thread may be asleep on the clock: a threaded virtual clock moves
            // it to its next deadline while this thread waits.
            let _ = motus_clock::while_blocked(&*self.inner.clock, || t.join());
        }
    }
}

impl Drop for Scheduler {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// The cycle thread.
fn run(inner: &Inner) {
    let clock = &*inner.clock;
    let period = inner.plan.effective_cycle();
    let mut next = clock.now();
    let mut cycle: u64 = 0;
    while !inner.stop.load(Ordering::Relaxed) {
        let start = clock.now();
        let n = {
            let mut st = inner.lock();
            st.recorder.cycle_started(start);
            st.drives.len()
        };
        let mut missed = false;
        for i in 0..n {
            missed |= exchange_drive(inner, i, cycle, period);
        }
        cycle += 1;
        let end = clock.now();
        if inner.config.cycle.is_zero() {
            // As fast as the line allows: back to back, no deadline to miss.
            inner.lock().recorder.cycle_ended(false, missed);
            next = end;
            continue;
        }
        let deadline = next + period;
        let overran = end > deadline;
        inner.lock().recorder.cycle_ended(overran, missed);
        // Cycles stay on their grid: a late cycle starts at once and the following ones
        // catch up; only when a whole period is lost does the grid move.
        next = if end > deadline + period { end } else { deadline };
        clock.sleep_until_precise(next);
    }
    inner.running.store(false, Ordering::Relaxed);
}

/// One slave's frame(s) of one cycle; true if an expected answer was missed.
fn exchange_drive(inner: &Inner, i: usize, cycle: u64, period: Duration) -> bool {
    let baud = inner.plan.baud;
    let (frame, seq) = {
        let mut st = inner.lock();
        st.seq += 1;
        let seq = st.seq;
        // Stagger the occasional queries across drives.
        let Some(d) = st.drives.get_mut(i) else { return false };
        (d.build(seq, inner.clock.now(), cycle + i as u64, period, baud, &inner.config), seq)
    };
    let address = frame.address;
    let rev = inner.bus.revision(address);
    let parts = match inner.config.packing {
        Packing::Packed => vec![frame],
        Packing::Unpacked => unpack(&frame),
    };
    let mut missed = false;
    for part in parts {
        let request_at = inner.clock.now();
        let result = inner.bus.exchange(&part, false);
        let reply_at = inner.clock.now();
        let (outcome, bytes) = match result {
            Ok(Exchanged { answer: Some(a), sent, received }) => (Outcome::Answer(a), sent + received),
            Ok(Exchanged { answer: None, sent, .. }) => (Outcome::Unanswered, sent),
            Err(e) => {
                match &e {
                    Nfv2Error::Bus(motus_serial::BusError::Io { .. }) => {
                        tracing::warn!(address, error = %e, "exchange failed")
                    }
                    _ => tracing::debug!(address, error = %e, "missed answer"),
                }
                (Outcome::Missed, part.encoded_len(rev).unwrap_or(0))
            }
        };
        let mut st = inner.lock();
        st.recorder.bytes(bytes);
        let timing = Timing { request_at, reply_at, request_len: part.encoded_len(rev).unwrap_or(0), baud };
        let config = &inner.config;
        let absorbed =
            st.drives.get_mut(i).map(|d| d.absorb(seq, outcome, timing, config)).unwrap_or_default();
        if let Some(s) = st.recorder.slave(address) {
            s.exchanges += 1;
            s.answers += u64::from(absorbed.answered);
            s.missed += u64::from(absorbed.missed);
            s.rejected += u64::from(absorbed.rejected);
        }
        missed |= absorbed.missed;
    }
    missed
}
