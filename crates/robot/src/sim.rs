//! The simulated robot: three simulated IclA drives on a CAN bus, the true pose of the
//! base (with configurable wheel slip), and the optical-mouse sensor fed by the true
//! motion on a pty — so wheel odometry and the sensor disagree exactly when a real robot's
//! would.
//!
//! Two forms:
//! - [`SimRobot::start`]: the drives serve a real bus (the socketcand hub, a SocketCAN
//!   interface) and the sensor a pty, on the system clock (the `motus sim-can` process).
//! - [`SimRobot::in_process`]: everything on one clock shared with the host, in one
//!   process: the drives are the in-process peer of a threaded [`PairBus`], the world
//!   thread runs their control loop and the world every millisecond, and the sensor's
//!   packets reach the host through an in-process line ([`SimRobot::take_sensor_link`]).
//!   On a [`motus_clock::VirtualClock::threaded`] clock a test of minutes of motion takes
//!   seconds and its timing is exact.

use motus_can::{CanBus, CanError, PairBus};
use motus_clock::{Clock, SharedClock, SystemClock};
use motus_icla_sim::runtime::{lock, run_shared, SharedDrives};
use motus_icla_sim::{SimConfig, SimDrive};
use motus_mouse_sim::{MouseMotion, MouseSensor, SensorConfig};
use motus_omni::kinematics::{Geometry, Pose};
use motus_omni::world::RobotWorld;
use motus_serial::{LineSettings, Link, PtyLink};
use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::{JoinHandle, Thread};
use std::time::{Duration, Instant};

/// The in-process bus of [`SimRobot::in_process`].
pub type SimBus = PairBus<Vec<SimDrive>>;

/// What the simulated robot is made of.
#[derive(Debug, Clone)]
pub struct SimRobotConfig {
    /// The three wheel drives (wheel 1, 2, 3), e.g. nodes 2, 3, 4 or LSS-unconfigured.
    pub drives: [SimConfig; 3],
    /// Slip per wheel: 0 = none, 0.1 = the wheel's ground contact delivers 90 % of its travel.
    pub slip: [f64; 3],
    /// Base geometry.
    pub geometry: Geometry,
    /// Serve the optical-mouse converter on a pty with a symlink at this path
    /// ([`SimRobot::start`]; [`SimRobot::in_process`] serves it on an in-process line).
    pub mouse_link: Option<PathBuf>,
    /// Sensor settings.
    pub sensor: SensorConfig,
}

impl SimRobotConfig {
    /// The seed's robot: drives at nodes 2, 3, 4, no slip, no sensor link.
    pub fn seed() -> Self {
        Self {
            drives: [SimConfig::node(2), SimConfig::node(3), SimConfig::node(4)],
            slip: [0.0; 3],
            geometry: Geometry::default(),
            mouse_link: None,
            sensor: SensorConfig::default(),
        }
    }
}

/// Errors starting the simulated robot.
#[derive(Debug, thiserror::Error)]
pub enum SimRobotError {
    /// The CAN bus failed.
    #[error("simulated robot: {0}")]
    Bus(#[from] CanError),
    /// The sensor's pty or configuration failed.
    #[error("simulated robot sensor: {0}")]
    Sensor(String),
}

/// A running simulated robot; stops on drop.
pub struct SimRobot {
    drives: SharedDrives,
    world: Arc<Mutex<RobotWorld>>,
    motion: Arc<MouseMotion>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
    mouse_path: Option<PathBuf>,
    /// Why the drives stopped serving their bus (set when the bus failed).
    bus_failure: Arc<Mutex<Option<String>>>,
    /// The clock of the simulation.
    clock: SharedClock,
    /// The in-process bus ([`SimRobot::in_process`]).
    pair_bus: Option<Arc<SimBus>>,
    /// The host's end of the in-process sensor line, until taken.
    sensor_link: Mutex<Option<SensorLink>>,
}

impl SimRobot {
    /// Starts the drives on `bus`, the world model (1 ms steps) and, if configured, the
    /// sensor on its pty.
    pub fn start(bus: Arc<dyn CanBus>, config: SimRobotConfig) -> Result<SimRobot, SimRobotError> {
        let drives: SharedDrives =
            Arc::new(Mutex::new(config.drives.iter().cloned().map(SimDrive::new).collect()));
        let mut world = RobotWorld::new(config.geometry, Pose::default());
        world.set_slip(config.slip);
        let world = Arc::new(Mutex::new(world));
        let stop = Arc::new(AtomicBool::new(false));
        let mut sensor =
            MouseSensor::new(config.sensor.clone()).map_err(|e| SimRobotError::Sensor(e.to_string()))?;
        let motion = sensor.motion();
        let mut threads = Vec::new();

        let (d, s) = (Arc::clone(&drives), Arc::clone(&stop));
        let bus_failure = Arc::new(Mutex::new(None));
        let failure = Arc::clone(&bus_failure);
        threads.push(spawn("icla-sim", move || {
            if let Err(e) = run_shared(bus, d, s) {
                tracing::error!(error = %e, "simulated drives stopped");
                *failure.lock().unwrap_or_else(PoisonError::into_inner) = Some(e.to_string());
            }
        })?);

        let (d, w, m, s) = (Arc::clone(&drives), Arc::clone(&world), Arc::clone(&motion), Arc::clone(&stop));
        threads.push(spawn("robot-world", move || world_loop(&d, &w, &m, &s))?);

        let mut mouse_path = None;
        if let Some(path) = &config.mouse_link {
            let mut link = PtyLink::create(Some(path), LineSettings::n81(9600))
                .map_err(|e| SimRobotError::Sensor(format!("pty at {}: {e}", path.display())))?;
            mouse_path = Some(path.clone());
            let s = Arc::clone(&stop);
            threads.push(spawn("mouse-sim", move || {
                if let Err(e) = motus_mouse_sim::serve(&mut link as &mut dyn Link, &mut sensor, &s) {
                    tracing::error!(error = %e, "simulated mouse stopped");
                }
            })?);
        }
        Ok(SimRobot {
            drives,
            world,
            motion,
            stop,
            threads,
            mouse_path,
            bus_failure,
            clock: SystemClock::shared(),
            pair_bus: None,
            sensor_link: Mutex::new(None),
        })
    }

    /// The simulated robot in this process, on `clock` (see the module documentation): the
    /// drives answer on [`SimRobot::pair_bus`] (give it to a master made with
    /// [`motus_canopen::Master::with_threaded_clock`] on the same clock) and the sensor on
    /// [`SimRobot::take_sensor_link`] (for [`crate::sensor::SensorReader::start_on`]).
    ///
    /// One thread, taking part in the clock, runs every millisecond (half a millisecond off
    /// the clock's whole milliseconds, so that it never shares an instant with a host that
    /// sleeps whole milliseconds): the drives' timers and motion, then the true pose from
    /// the wheels' travel, then, every sensor period, the sensor's next packet, whose bytes
    /// reach the host together once the last one is on the 9600 Bd line (as a USB-serial
    /// adapter hands them over). `mouse_link` is not used.
    pub fn in_process(config: SimRobotConfig, clock: SharedClock) -> Result<SimRobot, SimRobotError> {
        let drives_now: Vec<SimDrive> = config.drives.iter().cloned().map(SimDrive::new).collect();
        let (bus, drives) = motus_icla_sim::pair_threaded(drives_now, Arc::clone(&clock));
        let mut world = RobotWorld::new(config.geometry, Pose::default());
        world.set_slip(config.slip);
        let world = Arc::new(Mutex::new(world));
        let stop = Arc::new(AtomicBool::new(false));
        let mut sensor =
            MouseSensor::new(config.sensor.clone()).map_err(|e| SimRobotError::Sensor(e.to_string()))?;
        let motion = sensor.motion();
        let period = config.sensor.period;
        let line = Arc::new(Mutex::new(SensorLine::default()));
        let link = SensorLink { line: Arc::clone(&line), clock: Arc::clone(&clock) };

        let (b, d, w, m, s) = (
            Arc::clone(&bus),
            Arc::clone(&drives),
            Arc::clone(&world),
            Arc::clone(&motion),
            Arc::clone(&stop),
        );
        let thread_clock = Arc::clone(&clock);
        let builder = std::thread::Builder::new().name("robot-world".into());
        let world_thread = motus_clock::spawn(&clock, builder, move || {
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Simulator);
            let clock = thread_clock;
            clock.sleep(Duration::from_micros(500));
            let mut step = WorldStep::new(&d);
            let mut next_packet = clock.now() + period;
            motus_icla_sim::run_pair(&b, Duration::from_millis(1), &s, |now| {
                step.run(&d, &w, &m);
                if now >= next_packet {
                    next_packet += period;
                    let bytes = sensor.next_bytes();
                    lock_line(&line).send(now, &bytes, &*clock);
                }
            });
        })
        .map_err(|e| SimRobotError::Sensor(format!("spawn robot-world: {e}")))?;
        Ok(SimRobot {
            drives,
            world,
            motion,
            stop,
            threads: vec![world_thread],
            mouse_path: None,
            bus_failure: Arc::new(Mutex::new(None)),
            clock,
            pair_bus: Some(bus),
            sensor_link: Mutex::new(Some(link)),
        })
    }

    /// The in-process bus of the drives ([`SimRobot::in_process`]; `None` for
    /// [`SimRobot::start`]).
    pub fn pair_bus(&self) -> Option<Arc<SimBus>> {
        self.pair_bus.clone()
    }

    /// The host's end of the in-process sensor line ([`SimRobot::in_process`]; once).
    pub fn take_sensor_link(&self) -> Option<Box<dyn Link>> {
        let link = self.sensor_link.lock().unwrap_or_else(PoisonError::into_inner).take()?;
        lock_line(&link.line).open = true;
        Some(Box::new(link))
    }

    /// The clock of the simulation.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }

    /// Why the drives no longer serve their bus (its transport closed: the hub stopped),
    /// `None` while they do. A simulator process exits on it, as a drive cut off its bus
    /// would be restarted.
    pub fn bus_failure(&self) -> Option<String> {
        self.bus_failure.lock().unwrap_or_else(PoisonError::into_inner).clone()
    }

    /// The true pose (the ground truth odometry tries to estimate).
    pub fn true_pose(&self) -> Pose {
        self.world.lock().unwrap_or_else(PoisonError::into_inner).pose()
    }

    /// Changes the wheel slip.
    pub fn set_slip(&self, slip: [f64; 3]) {
        self.world.lock().unwrap_or_else(PoisonError::into_inner).set_slip(slip);
    }

    /// The simulated drives (lock with `motus_icla_sim::runtime::lock` for fault injection).
    pub fn drives(&self) -> &SharedDrives {
        &self.drives
    }

    /// The true motion fed to the sensor (metres, robot frame).
    pub fn sensor_motion(&self) -> &Arc<MouseMotion> {
        &self.motion
    }

    /// The sensor's pty path, when served.
    pub fn mouse_path(&self) -> Option<&PathBuf> {
        self.mouse_path.as_ref()
    }

    /// Stops every thread.
    pub fn stop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        let clock = Arc::clone(&self.clock);
        for t in self.threads.drain(..) {
            let _ = motus_clock::while_blocked(&*clock, || t.join());
        }
    }
}

impl Drop for SimRobot {
    fn drop(&mut self) {
        self.stop();
    }
}

fn spawn(name: &str, f: impl FnOnce() + Send + 'static) -> Result<JoinHandle<()>, SimRobotError> {
    std::thread::Builder::new()
        .name(name.into())
        .spawn(move || {
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Simulator);
            f()
        })
        .map_err(|e| SimRobotError::Sensor(format!("spawn {name}: {e}")))
}

/// One step of the world: the wheels' physical travel since the last step moves the true
/// pose (minus slip), and the resulting translation goes to the sensor.
struct WorldStep {
    last: [f64; 3],
}

impl WorldStep {
    fn new(drives: &SharedDrives) -> Self {
        Self { last: Self::read(drives) }
    }

    fn read(drives: &SharedDrives) -> [f64; 3] {
        let g = lock(drives);
        let p = |i: usize| g.get(i).map_or(0.0, SimDrive::world_position);
        [p(0), p(1), p(2)]
    }

    fn run(&mut self, drives: &SharedDrives, world: &Mutex<RobotWorld>, motion: &MouseMotion) {
        let now = Self::read(drives);
        let delta = [now[0] - self.last[0], now[1] - self.last[1], now[2] - self.last[2]];
        self.last = now;
        if delta.iter().all(|d| *d == 0.0) {
            return;
        }
        let m = world.lock().unwrap_or_else(PoisonError::into_inner).apply_wheel_inc(delta);
        motion.add_displacement(m.x, m.y);
    }
}

/// Every millisecond of wall time, a world step (the drives run on their own serving thread).
fn world_loop(drives: &SharedDrives, world: &Mutex<RobotWorld>, motion: &MouseMotion, stop: &AtomicBool) {
    let mut step = WorldStep::new(drives);
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(1));
        step.run(drives, world, motion);
    }
}

/// The sensor's line at 9600 Bd 8N1.
const SENSOR_LINE: LineSettings = LineSettings { baud: 9600, bits_per_char: 10 };

/// The in-process sensor line: packets on their way to the host, each with the instant
/// its last byte is on the host's side.
#[derive(Default)]
struct SensorLine {
    packets: VecDeque<(Instant, Vec<u8>)>,
    /// When the line is free for the next packet.
    free_at: Option<Instant>,
    /// The host's thread parked in a read.
    reader: Option<Thread>,
    /// Whether the host end was taken (packets nobody reads are not kept).
    open: bool,
}

impl SensorLine {
    /// Sends `bytes` from `now` (or once the previous packet has left) and wakes the host.
    fn send(&mut self, now: Instant, bytes: &[u8], clock: &dyn Clock) {
        if !self.open || bytes.is_empty() {
            return;
        }
        let start = self.free_at.map_or(now, |f| f.max(now));
        let done = start + SENSOR_LINE.wire_time(bytes.len());
        self.free_at = Some(done);
        self.packets.push_back((done, bytes.to_vec()));
        if let Some(t) = &self.reader {
            clock.unpark(t);
        }
    }
}

fn lock_line(line: &Mutex<SensorLine>) -> MutexGuard<'_, SensorLine> {
    line.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The host's end of the in-process sensor line ([`SimRobot::take_sensor_link`]): a read
/// parks on the clock until a packet is complete or the time-out has passed.
struct SensorLink {
    line: Arc<Mutex<SensorLine>>,
    clock: SharedClock,
}

impl SensorLink {
    /// Moves the bytes of the packets complete by `now` into `buf` (a packet that does not
    /// fit stays, with its rest, for the next read).
    fn take_due(line: &mut SensorLine, now: Instant, buf: &mut [u8]) -> usize {
        let mut n = 0;
        while let Some((at, bytes)) = line.packets.front_mut() {
            if *at > now || n == buf.len() {
                break;
            }
            let k = bytes.len().min(buf.len() - n);
            if let (Some(dst), Some(src)) = (buf.get_mut(n..n + k), bytes.get(..k)) {
                dst.copy_from_slice(src);
            }
            n += k;
            bytes.drain(..k);
            if bytes.is_empty() {
                line.packets.pop_front();
            }
        }
        n
    }
}

impl Link for SensorLink {
    /// The converter only transmits: what the host writes is dropped.
    fn write_all(&mut self, _: &[u8]) -> std::io::Result<()> {
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> std::io::Result<usize> {
        let clock = &*self.clock;
        let now = clock.now();
        let deadline = now.checked_add(timeout).unwrap_or(now + Duration::from_secs(86_400));
        loop {
            let now = clock.now();
            let next = {
                let mut line = lock_line(&self.line);
                let n = Self::take_due(&mut line, now, buf);
                if n > 0 || now >= deadline || buf.is_empty() {
                    line.reader = None;
                    return Ok(n);
                }
                line.reader = Some(std::thread::current());
                line.packets.front().map_or(deadline, |(at, _)| (*at).min(deadline))
            };
            clock.park_until(next);
        }
    }

    fn discard_input(&mut self) -> std::io::Result<()> {
        let now = self.clock.now();
        lock_line(&self.line).packets.retain(|(at, _)| *at > now);
        Ok(())
    }

    fn line(&self) -> LineSettings {
        SENSOR_LINE
    }

    fn describe(&self) -> String {
        "in-process mouse line".into()
    }
}
