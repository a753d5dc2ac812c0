//! Smoke tests on a real pseudo-terminal, in real time: two simulated 1209A served by the
//! simulator's thread (`SimLine::run`), the host opening the pty's symlink like a serial
//! port. They check function only, with generous liveness time-outs; the figures (cycle
//! statistics) are printed, not asserted: the behaviours and their figures are tested on
//! virtual time (`drive.rs`, `scheduler.rs`, `pantilt.rs`).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_nfv2::{DriveConfig, Nfv2Bus, PanTilt, PanTiltConfig, Scheduler, SchedulerConfig};
use motus_nfv2_protocol::{Command, CommandCode as C, DriveMode, Frame};
use motus_nfv2_sim::{lock, LineOptions, SharedController, SimClock, SimLine};
use motus_serial::{BusConfig, BusMaster, LineSettings, PtyLink, SerialLink, ServeThread};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

const BAUD: u32 = 57_600;
/// A liveness bound: far beyond what any of these waits takes on a loaded host.
const LIVENESS: Duration = Duration::from_secs(30);

/// Stops serving (first field: dropped first) before the folder of its pty goes.
struct Sim {
    _line: ServeThread<SimLine>,
    _dir: tempfile::TempDir,
    path: PathBuf,
    clock: SimClock,
    controllers: Vec<(u8, SharedController)>,
}

impl Sim {
    fn start(options: LineOptions) -> Sim {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("nfv2");
        let pty = PtyLink::create(Some(&path), LineSettings::n81(BAUD)).unwrap();
        let line = SimLine::new(Box::new(pty), options).unwrap();
        let (controllers, clock) = (line.controllers(), line.clock());
        Sim {
            _line: ServeThread::spawn("nfv2-sim", line, SimLine::run).unwrap(),
            _dir: dir,
            path,
            clock,
            controllers,
        }
    }

    /// The host side: the pty's symlink opened as a serial port.
    fn bus(&self) -> Nfv2Bus {
        let link = SerialLink::open(self.path.to_str().unwrap(), BAUD).unwrap();
        // Liveness margins: a loaded host may hold a reply up well beyond the line's own
        // time-out (the time-outs themselves are tested on virtual time).
        let config = BusConfig { margin: Duration::from_millis(200), retries: 3 };
        Nfv2Bus::new(Arc::new(BusMaster::new(Box::new(link), config)))
    }

    /// Runs `f` on the controller at `address`, brought up to the line's time first.
    fn with<T>(&self, address: u8, f: impl FnOnce(&mut motus_nfv2_sim::Controller) -> T) -> T {
        let c = self.controllers.iter().find(|(a, _)| *a == address).map(|(_, c)| c.clone()).unwrap();
        let mut g = lock(&c);
        g.advance_to(self.clock.now());
        f(&mut g)
    }
}

fn eventually(mut f: impl FnMut() -> bool) -> bool {
    let t0 = Instant::now();
    while t0.elapsed() < LIVENESS {
        if f() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    f()
}

#[test]
fn the_scheduler_cycles_and_raw_frames_go_between_cycles_over_a_pty() {
    let sim = Sim::start(LineOptions { addresses: vec![1, 2], ..LineOptions::default() });
    let config = SchedulerConfig {
        cycle: Duration::from_millis(15),
        confirm_timeout: LIVENESS,
        silence: LIVENESS,
        ..SchedulerConfig::default()
    };
    let sched = Scheduler::start(sim.bus(), vec![DriveConfig::new(1), DriveConfig::new(2)], config).unwrap();
    assert!(eventually(|| sched.drives().iter().all(|d| d.samples().len() > 10)), "{}", sched.stats());
    let query = Frame { address: 2, commands: vec![Command::query(C::ReadDeviceVitals)] };
    let vitals = sched.transact(&query).unwrap().unwrap();
    assert_eq!(vitals.int_values(C::ReadDeviceVitals).map(<[i64]>::len), Some(4));
    eprintln!("scheduler over a pty: {}", sched.stats());
}

#[test]
fn a_drive_enables_and_moves_over_a_pty() {
    let sim = Sim::start(LineOptions { addresses: vec![1, 2], ..LineOptions::default() });
    let config = SchedulerConfig {
        cycle: Duration::from_millis(15),
        confirm_timeout: LIVENESS,
        silence: LIVENESS,
        ..SchedulerConfig::default()
    };
    let sched = Scheduler::start(sim.bus(), vec![DriveConfig::new(1), DriveConfig::new(2)], config).unwrap();
    let drive = sched.drive(1).unwrap();
    drive.enable().unwrap();
    drive.move_to(3_000, Some(2_000), None).unwrap();
    let s = drive.wait_idle(LIVENESS).unwrap();
    assert!((s.position.unwrap().counts - 3_000).abs() <= 5, "{s:?}");
    assert!((sim.with(1, |c| c.true_state().counter) - 3_000).abs() <= 5);
    assert_eq!(sim.with(1, |c| c.true_state().mode), DriveMode::Position);
    eprintln!("drive over a pty: {}", sched.stats());
}

#[test]
fn the_head_homes_and_goes_to_a_target_over_a_paced_pty() {
    let sim = Sim::start(LineOptions { addresses: vec![1, 2], baud_pacing: true, ..LineOptions::default() });
    // Near the HOME edges, to keep it short.
    sim.with(1, |c| c.place_axis(-18_000.0).unwrap());
    sim.with(2, |c| c.place_axis(-19_000.0).unwrap());
    let scheduler = SchedulerConfig {
        confirm_timeout: LIVENESS,
        silence: LIVENESS,
        ..PanTiltConfig::default().scheduler
    };
    let config = PanTiltConfig { home_timeout: LIVENESS, scheduler, ..PanTiltConfig::default() };
    let pt = PanTilt::start(sim.bus(), config).unwrap();
    pt.home().unwrap();
    let t0 = Instant::now();
    let planned = pt.goto(10.0, -5.0).unwrap();
    let (pan, tilt) = pt.wait_idle(planned + LIVENESS).unwrap();
    assert!((pan - 10.0).abs() <= 0.02 && (tilt + 5.0).abs() <= 0.02, "ended at ({pan}, {tilt})");
    // "Where at t" may refuse a time reached only through samples the host held up: a
    // figure of the host's load, printed (it is tested on virtual time).
    let where_now = pt.where_at(pt.pan().snapshot().position.unwrap().at());
    eprintln!("where at the newest pan sample: {where_now:?}");
    eprintln!(
        "head over a pty: goto planned {planned:.3?}, done after {:.3?}; {}",
        t0.elapsed(),
        pt.scheduler().stats()
    );
}
