//! The simulated robot: three simulated IclA drives on a CAN bus, the true pose of the
//! base (with configurable wheel slip), and the optical-mouse sensor fed by the true
//! motion on a pty — so wheel odometry and the sensor disagree exactly when a real robot's
//! would.

use motus_can::{CanBus, CanError};
use motus_icla_sim::runtime::{lock, run_shared, SharedDrives};
use motus_icla_sim::{SimConfig, SimDrive};
use motus_mouse_sim::{MouseMotion, MouseSensor, SensorConfig};
use motus_omni::kinematics::{Geometry, Pose};
use motus_omni::world::RobotWorld;
use motus_serial::{LineSettings, Link, PtyLink};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

/// What the simulated robot is made of.
#[derive(Debug, Clone)]
pub struct SimRobotConfig {
    /// The three wheel drives (wheel 1, 2, 3), e.g. nodes 2, 3, 4 or LSS-unconfigured.
    pub drives: [SimConfig; 3],
    /// Slip per wheel: 0 = none, 0.1 = the wheel's ground contact delivers 90 % of its travel.
    pub slip: [f64; 3],
    /// Base geometry.
    pub geometry: Geometry,
    /// Serve the optical-mouse converter on a pty with a symlink at this path.
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
        Ok(SimRobot { drives, world, motion, stop, threads, mouse_path, bus_failure })
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
        for t in self.threads.drain(..) {
            let _ = t.join();
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

/// Every millisecond: the wheels' physical travel since the last step moves the true pose
/// (minus slip), and the resulting translation goes to the sensor.
fn world_loop(drives: &SharedDrives, world: &Mutex<RobotWorld>, motion: &MouseMotion, stop: &AtomicBool) {
    let read = || -> [f64; 3] {
        let g = lock(drives);
        let p = |i: usize| g.get(i).map_or(0.0, SimDrive::world_position);
        [p(0), p(1), p(2)]
    };
    let mut last = read();
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(1));
        let now = read();
        let delta = [now[0] - last[0], now[1] - last[1], now[2] - last[2]];
        last = now;
        if delta.iter().all(|d| *d == 0.0) {
            continue;
        }
        let m = world.lock().unwrap_or_else(PoisonError::into_inner).apply_wheel_inc(delta);
        motion.add_displacement(m.x, m.y);
    }
}
