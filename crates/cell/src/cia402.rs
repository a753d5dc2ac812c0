//! CiA 402 drives on CANopen: the virtual CAN bus (a socketcand hub started in-process when
//! nothing listens at the link's address), the simulated IclA drives on it (`motus sim
//! icla`; the three wheels of an `omni` group as a [`SimRobot`]), and one [`Cia402Axis`] per
//! drive through one CANopen master per link (as `motus axis cia402://...` opens it).
//!
//! Recovery: every bus connection here is a [`ReconnectingBus`], so after the hub (or the
//! socketcand daemon) restarts, the master and the simulated drives are back on the bus
//! within the link's back-off (100 ms doubling to 2 s) without being rebuilt. A drive's
//! bring-up ([`Cia402Device`]: heartbeat producer and consumer, the PDO set, NMT start;
//! enabling is left to a request) is run again by the station's reconnection whenever the
//! drive restarted (its boot-up message), left OPERATIONAL, or its heartbeat was lost.

use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_axis::{Axis, Scale};
use motus_can::socketcand::{Hub, HubConfig};
use motus_can::{BusUri, CanBus, ReconnectPolicy, ReconnectingBus, WhileDown};
use motus_canopen::{consumer_entry, HeartbeatProducer, Master, MasterError, NmtState, SdoError};
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
            let bus = sim_bus(&self.uri).map_err(|e| err(e.to_string()))?;
            let robot =
                SimRobot::start(bus, SimRobotConfig { drives: drives.clone(), ..SimRobotConfig::seed() })
                    .map_err(|e| err(e.to_string()))?;
            *self.running_robot.lock().unwrap_or_else(PoisonError::into_inner) = Some(robot);
        }
        if !self.others.is_empty() {
            let bus = sim_bus(&self.uri).map_err(|e| err(e.to_string()))?;
            let drives: motus_icla_sim::SharedDrives =
                Arc::new(Mutex::new(self.others.iter().cloned().map(SimDrive::new).collect()));
            self.stop = Arc::new(AtomicBool::new(false));
            let (stop, name) = (Arc::clone(&self.stop), self.name.clone());
            let t = std::thread::Builder::new()
                .name(format!("sim-{}", self.name))
                .spawn(move || {
                    motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Simulator);
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

/// The simulated drives' connection: like drives on a real bus whose wiring is cut, they
/// stay powered (and fault when the master's heartbeat stops) while the hub is away, and
/// are on the bus again when it is back.
fn sim_bus(uri: &str) -> Result<Arc<dyn CanBus>, motus_can::CanError> {
    let policy = ReconnectPolicy { while_down: WhileDown::Discard, ..ReconnectPolicy::default() };
    Ok(Arc::new(ReconnectingBus::open(uri, policy)?))
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

/// Each drive sends its heartbeat (0x1017) this often once brought up...
pub const DRIVE_HEARTBEAT_PERIOD: Duration = Duration::from_millis(100);

/// ...and the master counts it lost (the drive is brought up again) after this long
/// without one: generous, so a loaded host never takes a late frame for a dead drive.
pub const DRIVE_HEARTBEAT_SUPERVISION: Duration = Duration::from_secs(1);

/// The host side of one CAN link: one master (with its heartbeat) on a reconnecting bus,
/// opened on first use (a hub absent at start is retried by the station's reconnection).
pub(crate) struct CanLink {
    uri: String,
    master: Mutex<Option<(Arc<Master>, HeartbeatProducer)>>,
}

impl CanLink {
    pub(crate) fn new(link: &Link) -> Arc<Self> {
        Arc::new(Self { uri: link.uri.clone(), master: Mutex::new(None) })
    }

    /// The master, if it was opened.
    fn current(&self) -> Option<Arc<Master>> {
        self.master.lock().unwrap_or_else(PoisonError::into_inner).as_ref().map(|(m, _)| Arc::clone(m))
    }

    /// The link's master (opened once; the drives share it; its bus reconnects by itself).
    fn master(&self) -> Result<Arc<Master>, DeviceError> {
        let mut g = self.master.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some((m, _)) = g.as_ref() {
            return Ok(Arc::clone(m));
        }
        let link_err = |reason: String| DeviceError::Link { link: self.uri.clone(), reason };
        let bus = ReconnectingBus::open(&self.uri, ReconnectPolicy::default())
            .map_err(|e| link_err(e.to_string()))?;
        let m = Arc::new(Master::new(Arc::new(bus)));
        m.set_sdo_timeout(SDO_TIMEOUT);
        let heartbeat =
            m.start_heartbeat(MASTER_NODE_ID, MASTER_HEARTBEAT).map_err(|e| link_err(e.to_string()))?;
        *g = Some((Arc::clone(&m), heartbeat));
        Ok(m)
    }
}

/// What the last bring-up of a drive established.
#[derive(Debug, Clone, Copy)]
struct BringUp {
    /// The master's count of the drive's boot-up messages before the bring-up began: a
    /// higher count means the drive restarted since and lost what the bring-up set.
    boots: u64,
    /// The drive produces a heartbeat the master supervises (0x1017 was accepted).
    supervised: bool,
}

/// One CiA 402 drive of the cell.
pub(crate) struct Cia402Device {
    name: String,
    axis: String,
    node: u8,
    scale: Scale,
    link: Arc<CanLink>,
    slot: Slot,
    brought_up: Mutex<Option<BringUp>>,
    /// A bring-up was tried before.
    tried: AtomicBool,
}

/// How long the first bring-up of a drive waits for it to be heard.
const FIRST_BOOT_WAIT: Duration = Duration::from_secs(3);

/// An SDO write of the bring-up: a time-out means the drive is not there (retried by the
/// reconnection); an abort is the drive's refusal (`Ok(false)`: the caller decides).
fn bring_up_write(master: &Master, node: u8, index: u16, sub: u8, data: &[u8]) -> Result<bool, DeviceError> {
    match master.sdo_download(node, index, sub, data) {
        Ok(()) => Ok(true),
        Err(MasterError::Sdo(SdoError::Aborted { .. })) => Ok(false),
        Err(e @ MasterError::Transport { .. }) => {
            Err(DeviceError::Link { link: master.describe(), reason: e.to_string() })
        }
        Err(e) => Err(DeviceError::NoAnswer(format!("node {node}: writing 0x{index:04X}:{sub}: {e}"))),
    }
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
        Ok(Self {
            name: device.name.clone(),
            axis: a.name.clone(),
            node,
            scale: a.scale,
            link,
            slot,
            brought_up: Mutex::new(None),
            tried: AtomicBool::new(false),
        })
    }

    /// The drive's full bring-up: heartbeat producer (0x1017) supervised by the master,
    /// heartbeat consumer of the master's heartbeat (0x1016), the PDO set, NMT start. The
    /// same at start, after the drive restarted and after the bus came back.
    fn open(&self, master: Arc<Master>) -> Result<(Box<dyn Axis + Send>, BringUp), DeviceError> {
        let node = self.node;
        let boots = master.boot_count(node);
        // The first time, a drive simulated by the cell may still be booting: wait for it.
        // Later, one SDO probe says whether it is there (an absent drive must not hold the
        // station's reconnection of the other devices for long).
        let wait = if self.tried.swap(true, Ordering::Relaxed) { Duration::ZERO } else { FIRST_BOOT_WAIT };
        let deadline = Instant::now() + wait;
        while master.node_state(node).is_none() {
            if master.sdo_upload(node, 0x1000, 0).is_ok() {
                break;
            }
            if Instant::now() > deadline {
                return Err(DeviceError::NoAnswer(format!(
                    "node {node}: no boot-up, heartbeat or SDO answer{}",
                    if wait.is_zero() { String::new() } else { format!(" within {wait:?}") }
                )));
            }
        }
        // The drive's heartbeat, so the master sees it restart, stop or leave OPERATIONAL.
        let period = u16::try_from(DRIVE_HEARTBEAT_PERIOD.as_millis()).unwrap_or(u16::MAX);
        let supervised = bring_up_write(&master, node, 0x1017, 0, &period.to_le_bytes())?;
        if supervised {
            master.monitor_heartbeat(node, DRIVE_HEARTBEAT_SUPERVISION);
        } else {
            tracing::warn!(
                node,
                "the drive refused a heartbeat period (0x1017): its restarts are seen by its boot-up only"
            );
        }
        // The drive's own watchdog on the station: it stops when our heartbeat stops.
        let entry = consumer_entry(MASTER_NODE_ID, DRIVE_HEARTBEAT_TIMEOUT);
        if !bring_up_write(&master, node, 0x1016, 1, &entry.to_le_bytes())? {
            tracing::warn!(
                node,
                "the drive refused the heartbeat consumer (0x1016): it will NOT stop by itself if the station dies"
            );
        }
        let mut io = CanopenDrive::new(Arc::clone(&master), node);
        io.use_pdos().map_err(|e| DeviceError::NoAnswer(e.to_string()))?;
        if supervised {
            // A heartbeat sent after the NMT start says OPERATIONAL (an older one, still on
            // its way, may say PRE-OPERATIONAL: it must not count against this bring-up).
            let started = Instant::now();
            loop {
                let fresh = master.last_heartbeat(node).is_some_and(|t| t > started);
                if fresh && master.node_state(node) == Some(NmtState::Operational) {
                    break;
                }
                if started.elapsed() > DRIVE_HEARTBEAT_SUPERVISION {
                    return Err(DeviceError::NoAnswer(format!(
                        "node {node}: no OPERATIONAL heartbeat within {DRIVE_HEARTBEAT_SUPERVISION:?} of its NMT start"
                    )));
                }
                std::thread::sleep(Duration::from_millis(5));
            }
        }
        let drive = Drive::new(io, DriveSettings::default());
        let mut axis = Cia402Axis::new(
            drive,
            format!("cia402:{}#{}", self.link.uri, node),
            self.scale,
            Profile::ICLA_SEED,
        );
        axis.read_state().map_err(|e| DeviceError::NoAnswer(e.to_string()))?;
        Ok((Box::new(axis), BringUp { boots, supervised }))
    }

    /// Why the last bring-up no longer holds (`None`: it holds).
    fn bring_up_lost(&self, master: &Master, b: BringUp) -> Option<String> {
        let node = self.node;
        if master.boot_count(node) != b.boots {
            return Some(format!("node {node} restarted (boot-up message)"));
        }
        if b.supervised {
            if master.heartbeat_lost(node) {
                return Some(format!("node {node}: heartbeat lost"));
            }
            match master.node_state(node) {
                Some(NmtState::Operational) => {}
                other => {
                    return Some(format!(
                        "node {node} left OPERATIONAL (now {})",
                        other.map_or_else(|| "unknown".to_owned(), |s| s.to_string())
                    ))
                }
            }
        }
        None
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
        *self.brought_up.lock().unwrap_or_else(PoisonError::into_inner) = None;
        let (axis, bring_up) = self.open(self.link.master()?)?;
        put(&self.slot, axis);
        *self.brought_up.lock().unwrap_or_else(PoisonError::into_inner) = Some(bring_up);
        Ok(())
    }

    /// Connected while the drive answers and its bring-up holds; a restart (boot-up), a
    /// lost heartbeat or a drive out of OPERATIONAL ends it (logged once), so the station's
    /// reconnection brings the drive up again.
    fn is_connected(&self) -> bool {
        let mut g = self.brought_up.lock().unwrap_or_else(PoisonError::into_inner);
        let (Some(b), Some(master)) = (*g, self.link.current()) else { return false };
        if let Some(why) = self.bring_up_lost(&master, b) {
            tracing::warn!(device = %self.name, "{why}: the drive will be brought up again");
            *g = None;
            return false;
        }
        drop(g);
        slot_healthy(&self.slot)
    }
}
