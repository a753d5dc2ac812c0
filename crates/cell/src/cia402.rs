//! CiA 402 drives on CANopen: the virtual CAN bus (a socketcand hub started in-process when
//! nothing listens at the link's address), the simulated IclA drives on it (`motus sim
//! icla`; the three wheels of an `omni` group as a [`SimRobot`]), and one [`Cia402Axis`] per
//! drive through one CANopen master per link (as `motus axis cia402://...` opens it).

use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_axis::{Axis, Scale};
use motus_can::socketcand::{Hub, HubConfig};
use motus_can::BusUri;
use motus_canopen::{consumer_entry, HeartbeatProducer, Master};
use motus_cia402::{CanopenDrive, Cia402Axis, Drive, DriveSettings, Profile};
use motus_icla_sim::{SimConfig, SimDrive};
use motus_omni::kinematics::Pose;
use motus_robot::sim::{SimRobot, SimRobotConfig};
use motus_station::config::{Cell, Device, DeviceKind, GroupKind, Link};
use motus_station::devices::DeviceError;

use crate::axis::{put, slot_healthy, Slot};
use crate::sim::SimControl;
use crate::{CellError, DeviceCtl};

/// SDO time-out of the cell's masters (keeps health checks short).
const SDO_TIMEOUT: Duration = Duration::from_millis(300);

/// Starts a hub at the link's socketcand address if nothing listens there.
pub(crate) fn ensure_hub(link: &Link) -> Result<Option<Hub>, CellError> {
    let err = |reason: String| CellError::Simulator { name: link.name.clone(), reason };
    let BusUri::Socketcand { host, port, channel } =
        BusUri::parse(&link.uri).map_err(|e| err(e.to_string()))?
    else {
        return Ok(None);
    };
    let addr: SocketAddr = (host.trim_start_matches('[').trim_end_matches(']'), port)
        .to_socket_addrs()
        .map_err(|e| err(format!("cannot resolve {host}: {e}")))?
        .next()
        .ok_or_else(|| err(format!("{host} has no address")))?;
    if TcpStream::connect_timeout(&addr, Duration::from_millis(200)).is_ok() {
        tracing::info!(link = %link.name, %addr, "a CAN bus already listens there: joining it");
        return Ok(None);
    }
    let hub =
        Hub::start(HubConfig { listen: addr, bitrate: None, channel }).map_err(|e| err(e.to_string()))?;
    tracing::info!(link = %link.name, uri = %hub.uri(), "virtual CAN bus started");
    Ok(Some(hub))
}

/// The simulated drives of one CAN link.
pub(crate) struct CanSim {
    name: String,
    uri: String,
    robot: Option<[SimConfig; 3]>,
    others: Vec<SimConfig>,
    running_robot: Arc<Mutex<Option<SimRobot>>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl CanSim {
    /// The link's simulated drives; `None` when it has none.
    pub(crate) fn start(cell: &Cell, link: &Link) -> Result<Option<CanSim>, CellError> {
        let nodes: Vec<(String, u8)> = cell
            .devices_on_link(&link.name)
            .iter()
            .filter(|d| d.simulate && d.kind == DeviceKind::Cia402)
            .filter_map(|d| d.address.and_then(|a| u8::try_from(a).ok()).map(|n| (d.name.clone(), n)))
            .collect();
        if nodes.is_empty() {
            return Ok(None);
        }
        let wheel_nodes: Option<[u8; 3]> =
            cell.groups.iter().filter(|g| g.kind == GroupKind::Omni).find_map(|g| {
                let n: Vec<u8> = g
                    .axes
                    .iter()
                    .filter_map(|a| cell.axis(a))
                    .filter_map(|a| nodes.iter().find(|(d, _)| *d == a.device).map(|(_, n)| *n))
                    .collect();
                n.try_into().ok()
            });
        let others = nodes
            .iter()
            .filter(|(_, n)| wheel_nodes.is_none_or(|w| !w.contains(n)))
            .map(|(_, n)| SimConfig::node(*n))
            .collect();
        let mut sim = CanSim {
            name: link.name.clone(),
            uri: link.uri.clone(),
            robot: wheel_nodes.map(|w| w.map(SimConfig::node)),
            others,
            running_robot: Arc::new(Mutex::new(None)),
            stop: Arc::new(AtomicBool::new(false)),
            thread: None,
        };
        sim.spawn()?;
        Ok(Some(sim))
    }

    /// The simulated robot (true pose), while it runs.
    pub(crate) fn robot(&self) -> Arc<Mutex<Option<SimRobot>>> {
        Arc::clone(&self.running_robot)
    }

    fn spawn(&mut self) -> Result<(), CellError> {
        let err = |reason: String| CellError::Simulator { name: self.name.clone(), reason };
        if let Some(drives) = &self.robot {
            let bus = motus_can::open_bus(&self.uri).map_err(|e| err(e.to_string()))?;
            let robot =
                SimRobot::start(bus, SimRobotConfig { drives: drives.clone(), ..SimRobotConfig::seed() })
                    .map_err(|e| err(e.to_string()))?;
            *self.running_robot.lock().unwrap_or_else(PoisonError::into_inner) = Some(robot);
        }
        if !self.others.is_empty() {
            let bus = motus_can::open_bus(&self.uri).map_err(|e| err(e.to_string()))?;
            let drives: motus_icla_sim::SharedDrives =
                Arc::new(Mutex::new(self.others.iter().cloned().map(SimDrive::new).collect()));
            self.stop = Arc::new(AtomicBool::new(false));
            let (stop, name) = (Arc::clone(&self.stop), self.name.clone());
            let t = std::thread::Builder::new()
                .name(format!("sim-{}", self.name))
                .spawn(move || {
                    if let Err(e) = motus_icla_sim::run_shared(bus, drives, stop) {
                        tracing::warn!(simulator = %name, error = %e, "simulated drives stopped");
                    }
                })
                .map_err(|e| err(e.to_string()))?;
            self.thread = Some(t);
        }
        Ok(())
    }
}

impl SimControl for CanSim {
    fn kill(&mut self) {
        if let Some(mut r) = self.running_robot.lock().unwrap_or_else(PoisonError::into_inner).take() {
            r.stop();
        }
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }

    fn restart(&mut self) -> Result<(), CellError> {
        self.kill();
        self.spawn()
    }

    fn is_running(&self) -> bool {
        self.running_robot.lock().unwrap_or_else(PoisonError::into_inner).is_some()
            || self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }
}

impl Drop for CanSim {
    fn drop(&mut self) {
        self.kill();
    }
}

/// The true pose of a simulated robot, while it runs.
pub(crate) fn true_pose(robot: &Mutex<Option<SimRobot>>) -> Option<Pose> {
    robot.lock().unwrap_or_else(PoisonError::into_inner).as_ref().map(SimRobot::true_pose)
}

/// The node id the station's master sends its heartbeat as (126: the IclA's factory id is
/// 127, and a cell's drives use low ids).
pub const MASTER_NODE_ID: u8 = 126;

/// Period of the master's heartbeat.
pub const MASTER_HEARTBEAT: Duration = Duration::from_millis(100);

/// Every drive of the cell is told to watch the master's heartbeat with this time-out
/// (0x1016): when the station dies, each drive stops by itself (EMCY 0x8130 and its fault
/// reaction) within this time plus its quick-stop ramp.
pub const DRIVE_HEARTBEAT_TIMEOUT: Duration = Duration::from_millis(300);

/// The host side of one CAN link: one master (with its heartbeat), opened on first use.
pub(crate) struct CanLink {
    uri: String,
    master: Mutex<Option<(Arc<Master>, HeartbeatProducer)>>,
}

impl CanLink {
    pub(crate) fn new(link: &Link) -> Arc<Self> {
        Arc::new(Self { uri: link.uri.clone(), master: Mutex::new(None) })
    }

    /// The link's master (opened once; the drives share it).
    fn master(&self) -> Result<Arc<Master>, DeviceError> {
        let mut g = self.master.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some((m, _)) = g.as_ref() {
            return Ok(Arc::clone(m));
        }
        let link_err = |reason: String| DeviceError::Link { link: self.uri.clone(), reason };
        let bus = motus_can::open_bus(&self.uri).map_err(|e| link_err(e.to_string()))?;
        let m = Arc::new(Master::new(bus));
        m.set_sdo_timeout(SDO_TIMEOUT);
        let heartbeat =
            m.start_heartbeat(MASTER_NODE_ID, MASTER_HEARTBEAT).map_err(|e| link_err(e.to_string()))?;
        *g = Some((Arc::clone(&m), heartbeat));
        Ok(m)
    }
}

/// One CiA 402 drive of the cell.
pub(crate) struct Cia402Device {
    name: String,
    axis: String,
    node: u8,
    scale: Scale,
    link: Arc<CanLink>,
    slot: Slot,
}

impl Cia402Device {
    pub(crate) fn new(
        cell: &Cell,
        device: &Device,
        link: Arc<CanLink>,
        slot: Slot,
    ) -> Result<Self, CellError> {
        let a = cell
            .axes_of_device(&device.name)
            .into_iter()
            .next()
            .ok_or_else(|| CellError::Config(format!("device {}: no [[axis]] uses it", device.name)))?;
        let node = device.address.and_then(|a| u8::try_from(a).ok()).ok_or_else(|| {
            CellError::Config(format!("device {}: a CiA 402 drive needs a node id", device.name))
        })?;
        Ok(Self { name: device.name.clone(), axis: a.name.clone(), node, scale: a.scale, link, slot })
    }

    fn open(&self, master: Arc<Master>) -> Result<Box<dyn Axis + Send>, DeviceError> {
        let deadline = Instant::now() + Duration::from_secs(3);
        while master.node_state(self.node).is_none() {
            if Instant::now() > deadline {
                return Err(DeviceError::NoAnswer(format!(
                    "node {}: no boot-up or heartbeat within 3 s",
                    self.node
                )));
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        // The drive's own watchdog on the station: it stops when our heartbeat stops.
        let entry = consumer_entry(MASTER_NODE_ID, DRIVE_HEARTBEAT_TIMEOUT);
        if let Err(e) = master.sdo_download(self.node, 0x1016, 1, &entry.to_le_bytes()) {
            tracing::warn!(
                node = self.node,
                error = %e,
                "the drive refused the heartbeat consumer (0x1016): it will NOT stop by itself if the station dies"
            );
        }
        let mut io = CanopenDrive::new(master, self.node);
        io.use_pdos().map_err(|e| DeviceError::NoAnswer(e.to_string()))?;
        let drive = Drive::new(io, DriveSettings::default());
        let mut axis = Cia402Axis::new(
            drive,
            format!("cia402:{}#{}", self.link.uri, self.node),
            self.scale,
            Profile::ICLA_SEED,
        );
        axis.read_state().map_err(|e| DeviceError::NoAnswer(e.to_string()))?;
        Ok(Box::new(axis))
    }
}

impl DeviceCtl for Cia402Device {
    fn name(&self) -> &str {
        &self.name
    }

    fn axes(&self) -> Vec<String> {
        vec![self.axis.clone()]
    }

    fn connect(&self) -> Result<(), DeviceError> {
        let axis = self.open(self.link.master()?)?;
        put(&self.slot, axis);
        Ok(())
    }

    fn is_connected(&self) -> bool {
        slot_healthy(&self.slot)
    }
}
