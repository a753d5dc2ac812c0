//! Simulated 1209A controllers on a real pseudo-terminal, served by a thread, a host bus
//! opened on the pty's symlink like on a real serial port, and a recorder of the
//! simulator's true trajectory in the drives' counter coordinates.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use motus_nfv2::{Nfv2Bus, SchedulerConfig};
use motus_nfv2_sim::{lock, LineOptions, SharedController, SimClock, SimLine};
use motus_serial::{BusConfig, BusMaster, LineSettings, PtyLink, SerialLink, ServeThread};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

pub const BAUD: u32 = 57_600;

/// Tests of one binary run one at a time: each has a simulator and a scheduler spinning
/// on two cores, and they measure timing.
pub fn serial() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(|p| p.into_inner())
}

pub fn two_controllers() -> LineOptions {
    LineOptions { addresses: vec![1, 2], ..LineOptions::default() }
}

/// Stops serving (first field: dropped first) before the folder of its pty goes.
pub struct Sim {
    _line: ServeThread<SimLine>,
    pub dir: tempfile::TempDir,
    pub path: PathBuf,
    pub clock: SimClock,
    controllers: Vec<(u8, SharedController)>,
}

impl Sim {
    pub fn start(options: LineOptions) -> Sim {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("nfv2");
        let pty = PtyLink::create(Some(&path), LineSettings::n81(BAUD)).unwrap();
        let line = SimLine::new(Box::new(pty), options).unwrap();
        let (controllers, clock) = (line.controllers(), line.clock());
        Sim {
            _line: ServeThread::spawn("nfv2-sim", line, SimLine::run).unwrap(),
            dir,
            path,
            clock,
            controllers,
        }
    }

    pub fn controller(&self, address: u8) -> SharedController {
        self.controllers.iter().find(|(a, _)| *a == address).map(|(_, c)| c.clone()).unwrap()
    }

    /// The host side: the pty's symlink opened as a serial port.
    pub fn bus(&self, margin: Duration) -> Nfv2Bus {
        let link = SerialLink::open(self.path.to_str().unwrap(), BAUD).unwrap();
        Nfv2Bus::new(Arc::new(BusMaster::new(Box::new(link), BusConfig { margin, retries: 2 })))
    }

    /// Runs `f` on the controller at `address`, brought up to the line's time first.
    pub fn with<T>(&self, address: u8, f: impl FnOnce(&mut motus_nfv2_sim::Controller) -> T) -> T {
        let c = self.controller(address);
        let mut g = lock(&c);
        g.advance_to(self.clock.now());
        f(&mut g)
    }
}

pub fn fast_scheduler() -> SchedulerConfig {
    SchedulerConfig { cycle: Duration::from_millis(15), ..SchedulerConfig::default() }
}

/// One true state, in the drive's counter coordinates.
#[derive(Debug, Clone, Copy)]
pub struct Truth {
    /// Simulated time.
    pub t: Duration,
    /// True position, counts, in counter coordinates (counter = floor(true) + offset).
    pub counts: f64,
    /// True speed, counts/s.
    pub speed: f64,
    /// The bridge is switching.
    pub bridge_on: bool,
}

/// Records every regulator cycle's true state of some controllers from a thread.
pub struct TruthRecorder {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Vec<Vec<Truth>>>>,
}

impl TruthRecorder {
    pub fn start(sim: &Sim, addresses: &[u8]) -> TruthRecorder {
        let controllers: Vec<SharedController> = addresses.iter().map(|&a| sim.controller(a)).collect();
        let clock = sim.clock;
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let thread = std::thread::spawn(move || {
            let mut out: Vec<Vec<Truth>> = vec![Vec::new(); controllers.len()];
            while !flag.load(Ordering::Relaxed) {
                for (c, rec) in controllers.iter().zip(out.iter_mut()) {
                    let mut g = lock(c);
                    g.advance_to(clock.now());
                    let s = g.true_state();
                    drop(g);
                    if rec.last().is_some_and(|l: &Truth| l.t >= s.time) {
                        continue;
                    }
                    let offset = s.counter as f64 - s.position_counts.floor();
                    rec.push(Truth {
                        t: s.time,
                        counts: s.position_counts + offset,
                        speed: s.speed_counts_per_s,
                        bridge_on: s.bridge_on,
                    });
                }
                std::thread::sleep(Duration::from_micros(700));
            }
            out
        });
        TruthRecorder { stop, thread: Some(thread) }
    }

    pub fn finish(mut self) -> Vec<Vec<Truth>> {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.take().unwrap().join().unwrap()
    }
}

/// The true position (counts) at simulated time `t`, interpolated.
pub fn truth_at(rec: &[Truth], t: Duration) -> Option<f64> {
    let i = rec.partition_point(|r| r.t <= t);
    let (a, b) = (rec.get(i.checked_sub(1)?)?, rec.get(i)?);
    if b.t - a.t > Duration::from_millis(5) {
        return None;
    }
    let f = (t - a.t).as_secs_f64() / (b.t - a.t).as_secs_f64();
    Some(a.counts + f * (b.counts - a.counts))
}

/// The first time after which the position stays within `tol` counts of `target`.
pub fn arrival(rec: &[Truth], target: f64, tol: f64) -> Option<Duration> {
    let last_out = rec.iter().rposition(|r| (r.counts - target).abs() > tol)?;
    rec.get(last_out + 1).map(|r| r.t)
}

/// Polls `f` every 5 ms until it is true or `timeout` elapses.
pub fn eventually(timeout: Duration, mut f: impl FnMut() -> bool) -> bool {
    let t0 = Instant::now();
    while t0.elapsed() < timeout {
        if f() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    f()
}

/// Seconds of a long run: `MOTUS_NFV2_TRACK_SECONDS` (default `default`).
pub fn seconds(var: &str, default: u64) -> u64 {
    std::env::var(var).ok().and_then(|s| s.parse().ok()).unwrap_or(default)
}
