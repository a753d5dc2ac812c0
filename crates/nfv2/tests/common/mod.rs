//! Simulated 1209A controllers served in process on virtual time: the driver's bus master
//! and the simulator's serve step share one threaded [`VirtualClock`] through a
//! [`SimLink`] (the scheduler's cycle thread and the test thread take part in its time),
//! and a recorder of the simulator's true trajectory (every regulator cycle) in the
//! drives' counter coordinates.
//! A minute of motion takes a second or so of wall time, and no figure depends on the
//! host's load.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use motus_clock::{Clock, SharedClock, VirtualClock};
use motus_nfv2::{Nfv2Bus, SchedulerConfig};
use motus_nfv2_protocol::FrameScanner;
use motus_nfv2_sim::{lock, Controllers, LineOptions, SharedController, SimClock, SimLine};
use motus_serial::{BusConfig, BusMaster, LineSettings, NullLink, SimLink};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

pub const BAUD: u32 = 57_600;

pub fn two_controllers() -> LineOptions {
    LineOptions { addresses: vec![1, 2], ..LineOptions::default() }
}

/// Two controllers with baud pacing (the line takes its wire time).
pub fn paced() -> LineOptions {
    LineOptions { addresses: vec![1, 2], baud_pacing: true, ..LineOptions::default() }
}

/// The simulated line in process, on a threaded virtual clock the calling (test) thread
/// takes part in.
pub struct Sim {
    pub clock: VirtualClock,
    pub shared: SharedClock,
    /// The line's simulated time (zero when the line started).
    pub sim_clock: SimClock,
    controllers: Vec<(u8, SharedController)>,
    link: Mutex<Option<SimLink<FrameScanner, Controllers>>>,
}

impl Sim {
    pub fn start(options: LineOptions) -> Sim {
        let clock = VirtualClock::threaded();
        let shared = clock.shared();
        let null = NullLink::new(LineSettings::n81(BAUD));
        let line = SimLine::with_clock(Box::new(null), options, shared.clone()).unwrap();
        let (controllers, sim_clock) = (line.controllers(), line.clock());
        let link = Mutex::new(Some(line.into_sim_link()));
        Sim { clock, shared, sim_clock, controllers, link }
    }

    pub fn controller(&self, address: u8) -> SharedController {
        self.controllers.iter().find(|(a, _)| *a == address).map(|(_, c)| c.clone()).unwrap()
    }

    /// The host side (once): a bus master on the in-process link and the same clock.
    pub fn bus(&self, margin: Duration) -> Nfv2Bus {
        let link = self.link.lock().unwrap().take().expect("one bus per simulated line");
        let master =
            BusMaster::with_clock(Box::new(link), BusConfig { margin, retries: 2 }, self.shared.clone());
        Nfv2Bus::new(Arc::new(master))
    }

    /// Runs `f` on the controller at `address`, brought up to the line's time first.
    pub fn with<T>(&self, address: u8, f: impl FnOnce(&mut motus_nfv2_sim::Controller) -> T) -> T {
        let c = self.controller(address);
        let mut g = lock(&c);
        g.advance_to(self.sim_clock.now());
        f(&mut g)
    }

    /// Virtual time now.
    pub fn now(&self) -> Instant {
        self.clock.now()
    }

    /// Waits `d` of virtual time (the scheduler cycles meanwhile).
    pub fn sleep(&self, d: Duration) {
        self.clock.sleep(d);
    }

    /// Polls `f` every 5 ms of virtual time until it is true or `timeout` has passed.
    pub fn eventually(&self, timeout: Duration, mut f: impl FnMut() -> bool) -> bool {
        let t0 = self.now();
        while self.clock.elapsed(t0) < timeout {
            if f() {
                return true;
            }
            self.sleep(Duration::from_millis(5));
        }
        f()
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

/// Records every regulator cycle's true state of some controllers (the controllers keep
/// them: [`motus_nfv2_sim::Controller::trace_truth`]).
pub struct TruthRecorder {
    controllers: Vec<SharedController>,
    sim_clock: SimClock,
}

impl TruthRecorder {
    pub fn start(sim: &Sim, addresses: &[u8]) -> TruthRecorder {
        let controllers: Vec<SharedController> = addresses.iter().map(|&a| sim.controller(a)).collect();
        for c in &controllers {
            let mut g = lock(c);
            g.advance_to(sim.sim_clock.now());
            g.trace_truth(Some(1 << 20));
        }
        TruthRecorder { controllers, sim_clock: sim.sim_clock.clone() }
    }

    pub fn finish(self) -> Vec<Vec<Truth>> {
        let mut out = Vec::new();
        for c in &self.controllers {
            let mut g = lock(c);
            g.advance_to(self.sim_clock.now());
            let trace = g.take_truth_trace();
            g.trace_truth(None);
            drop(g);
            let rec = trace
                .into_iter()
                .map(|s| {
                    let offset = s.counter as f64 - s.position_counts.floor();
                    Truth {
                        t: s.time,
                        counts: s.position_counts + offset,
                        speed: s.speed_counts_per_s,
                        bridge_on: s.bridge_on,
                    }
                })
                .collect();
            out.push(rec);
        }
        out
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

/// Seconds of a long run: `var` (default `default`).
pub fn seconds(var: &str, default: u64) -> u64 {
    std::env::var(var).ok().and_then(|s| s.parse().ok()).unwrap_or(default)
}
