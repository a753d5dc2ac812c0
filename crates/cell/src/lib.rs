//! # motus-cell — a cell configuration turned into running devices and axes
//!
//! [`open_cell`] takes a validated [`Cell`] (see `motus_station::config`) and:
//!
//! 1. starts every simulator the cell asks for, in-process but on its real transport, as the
//!    CLI's `motus sim ...` does: PS1A, KV-01 and NFv2 lines on a pty whose symlink is the
//!    link's path (modules `ps1a`, `kv01`, `nfv2`); IclA CiA 402 drives on the virtual CAN bus,
//!    with a socketcand hub started when nothing listens at the link's address, and the
//!    wheels of an `omni` group as a simulated robot (module `cia402`); the juggler's POWERLINK
//!    segment over UDP with the safety lease ([`juggler`]); `sim-axis` devices ([`sim_axis`]);
//! 2. opens the drivers as the CLI does and gives one [`CellAxis`] per `[[axis]]` (name,
//!    scale and machine limits from the file), grouped per device ([`RunningCell::axes`]);
//! 3. runs the juggler's online supervisor on its own thread with a shared
//!    [`SupervisorSnapshot`]; its axes are read-only ([`juggler::EplAxis`]);
//! 4. offers a [`DeviceHandle`] per device for the station's `Reconnector`
//!    ([`RunningCell::device_handles`]), and a kill / restart switch per simulator
//!    ([`RunningCell::kill_simulator`], [`RunningCell::restart_simulator`]).
//!
//! [`RunningCell::stop`] (also on drop) stops every simulator, driver thread and hub.

#![forbid(unsafe_code)]

mod axis;
mod cia402;
mod group;
pub mod juggler;
pub mod juggler_program;
mod kv01;
mod nfv2;
mod ps1a;
mod sim;
pub mod sim_axis;

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use motus_axis::Axis;
use motus_can::socketcand::Hub;
use motus_safety::Restart;
pub use motus_safety_epl::juggler::Pattern;
use motus_station::config::{Cell, DeviceKind, GroupKind, LinkKind};
use motus_station::devices::{DeviceError, DeviceHandle};

pub use axis::CellAxis;
pub use group::{ArmGroup, CellGroup, GroupHandle, OmniGroup, PanTiltGroup};
pub use juggler::{JugglerHandle, SupervisorSnapshot};
pub use juggler_program::ProgramSelector;

use axis::{new_slot, put, Slot};
use sim::SimControl;

/// How the cell runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellOptions {
    /// Program of the simulated juggler (default: the safe juggling cam).
    pub juggler_pattern: Pattern,
    /// POWERLINK cycle of the simulated segment (default 1 ms, as `motus sim epl`).
    pub juggler_cycle: Duration,
    /// The simulated juggler drives stop this long after the last lease renewal (20 ms).
    pub drive_lease: Duration,
    /// Validity of each lease renewal on the wire (20 ms, as `motus safety run`).
    pub wire_lease: Duration,
    /// After a safety stop: wait for the operator's reset (default) or resume when safe.
    pub supervisor_restart: Restart,
    /// Fail [`open_cell`] when a device cannot be reached at start (default); when false it
    /// is left to the station's reconnection.
    pub require_devices: bool,
}

impl Default for CellOptions {
    fn default() -> Self {
        Self {
            juggler_pattern: Pattern::Juggle,
            juggler_cycle: Duration::from_millis(1),
            drive_lease: Duration::from_millis(20),
            wire_lease: Duration::from_millis(20),
            supervisor_restart: Restart::Manual,
            require_devices: true,
        }
    }
}

/// Why the cell could not be opened or a simulator not be switched.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CellError {
    /// The cell asks for something this library cannot build.
    #[error("cell: {0}")]
    Config(String),
    /// A simulator failed to start (or is unknown).
    #[error("simulator {name}: {reason}")]
    Simulator {
        /// Link or device name.
        name: String,
        /// Why.
        reason: String,
    },
    /// A device could not be reached at start.
    #[error("device {name}: {reason}")]
    Device {
        /// Device name.
        name: String,
        /// Why.
        reason: String,
    },
}

/// One device's side of the cell: what [`CellDevice`] forwards to.
pub(crate) trait DeviceCtl: Send + Sync {
    fn name(&self) -> &str;
    fn axes(&self) -> Vec<String>;
    /// Reopens the driver (always).
    fn connect(&self) -> Result<(), DeviceError>;
    fn is_connected(&self) -> bool;
    /// A latched condition only the operator can clear, saying what to do
    /// ([`DeviceHandle::needs_operator`]).
    fn needs_operator(&self) -> Option<String> {
        None
    }
    /// Failed health checks in a row that make the device lost
    /// ([`DeviceHandle::lost_after_misses`]).
    fn lost_after_misses(&self) -> u32 {
        1
    }
}

/// The port a serial path names now (`None`: it does not exist): a restarted simulator's
/// symlink names a new pty.
pub(crate) fn link_target(path: &str) -> Option<PathBuf> {
    std::fs::canonicalize(path).ok()
}

/// A device for the station's reconnection: `connect` reopens the driver (unless it is
/// still healthy), `is_connected` is a short health check.
pub struct CellDevice {
    ctl: Arc<dyn DeviceCtl>,
}

impl std::fmt::Debug for CellDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CellDevice").field("name", &self.ctl.name()).finish()
    }
}

impl DeviceHandle for CellDevice {
    fn name(&self) -> &str {
        self.ctl.name()
    }

    fn connect(&mut self) -> Result<(), DeviceError> {
        if self.ctl.is_connected() {
            return Ok(());
        }
        self.ctl.connect()
    }

    fn is_connected(&mut self) -> bool {
        self.ctl.is_connected()
    }

    fn axes(&self) -> Vec<String> {
        self.ctl.axes()
    }

    fn needs_operator(&mut self) -> Option<String> {
        self.ctl.needs_operator()
    }

    fn lost_after_misses(&self) -> u32 {
        self.ctl.lost_after_misses()
    }
}

/// The axes of one device, in index order.
pub struct DeviceAxes {
    /// Device name.
    pub device: String,
    /// Its axes.
    pub axes: Vec<Box<dyn Axis + Send>>,
}

impl std::fmt::Debug for DeviceAxes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names: Vec<&str> = self.axes.iter().map(|a| a.name()).collect();
        f.debug_struct("DeviceAxes").field("device", &self.device).field("axes", &names).finish()
    }
}

/// A simulator of the cell.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SimulatorInfo {
    /// Its name: the link's (serial, CAN, POWERLINK) or the device's (`sim-axis`).
    pub name: String,
    /// The devices it simulates.
    pub devices: Vec<String>,
    /// Running now.
    pub running: bool,
}

struct SimEntry {
    name: String,
    devices: Vec<String>,
    ctl: Box<dyn SimControl>,
}

/// The running cell (see the crate documentation).
pub struct RunningCell {
    cell: Cell,
    slots: BTreeMap<String, Slot>,
    devices: Vec<Arc<dyn DeviceCtl>>,
    sims: Vec<SimEntry>,
    hubs: Vec<Hub>,
    juggler: Option<Arc<JugglerHandle>>,
    nfv2_links: Vec<Arc<nfv2::Nfv2Link>>,
    groups: Vec<CellGroup>,
    arms: Vec<ArmGroup>,
    stopped: bool,
}

impl std::fmt::Debug for RunningCell {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RunningCell")
            .field("cell", &self.cell.station.name)
            .field("axes", &self.slots.keys().collect::<Vec<_>>())
            .field("simulators", &self.simulators())
            .finish()
    }
}

/// Baud rate of a serial link: the first device's `baud`, else the family's usual rate.
fn link_baud(cell: &Cell, link: &str, kind: DeviceKind) -> u32 {
    let default = match kind {
        DeviceKind::Nfv2 => 57_600,
        _ => 115_200,
    };
    cell.devices_on_link(link).iter().find_map(|d| d.baud).unwrap_or(default)
}

/// Starts the simulators, opens the drivers and returns the running cell.
pub fn open_cell(cell: &Cell, options: CellOptions) -> Result<RunningCell, CellError> {
    let mut rc = RunningCell {
        cell: cell.clone(),
        slots: cell.axes.iter().map(|a| (a.name.clone(), new_slot())).collect(),
        devices: Vec::new(),
        sims: Vec::new(),
        hubs: Vec::new(),
        juggler: None,
        nfv2_links: Vec::new(),
        groups: Vec::new(),
        arms: Vec::new(),
        stopped: false,
    };
    let mut robots = BTreeMap::new();
    for link in &cell.links {
        let devices = cell.devices_on_link(&link.name);
        let simulated: Vec<String> = devices.iter().filter(|d| d.simulate).map(|d| d.name.clone()).collect();
        let Some(family) = devices.first().map(|d| d.kind) else { continue };
        if let Some(other) = devices.iter().find(|d| d.kind != family) {
            return Err(CellError::Config(format!(
                "link {}: devices of different kinds ({} and {})",
                link.name,
                family.as_str(),
                other.kind.as_str()
            )));
        }
        if simulated.is_empty() {
            continue;
        }
        if link.kind == LinkKind::Serial {
            return Err(CellError::Config(format!(
                "link {}: simulated devices need a pty-sim link, not a serial port",
                link.name
            )));
        }
        let baud = link_baud(cell, &link.name, family);
        let ctl: Option<Box<dyn SimControl>> = match family {
            DeviceKind::Ps1a => ps1a::simulate(cell, link, baud)?.map(|s| Box::new(s) as Box<dyn SimControl>),
            DeviceKind::Kv01 => Some(Box::new(kv01::simulate(link, baud)?)),
            DeviceKind::Nfv2 => nfv2::simulate(cell, link, baud)?.map(|s| Box::new(s) as Box<dyn SimControl>),
            DeviceKind::Cia402 => {
                if let Some(hub) = cia402::ensure_hub(link)? {
                    rc.hubs.push(hub);
                }
                cia402::CanSim::start(cell, link)?.map(|s| {
                    robots.insert(link.name.clone(), s.robot());
                    Box::new(s) as Box<dyn SimControl>
                })
            }
            DeviceKind::EplDrive => {
                let sup = cell.supervisor.as_ref().ok_or_else(|| {
                    CellError::Config(format!(
                        "link {}: simulated epl-drive devices need [supervisor] rules",
                        link.name
                    ))
                })?;
                let rules = juggler::read_rules(&sup.rules)?;
                let nodes: Vec<u8> =
                    devices.iter().filter_map(|d| d.address.and_then(|a| u8::try_from(a).ok())).collect();
                // The supervisor first: its leases must be there when the drives go operational.
                let program = Arc::new(ProgramSelector::new(options.juggler_pattern));
                let handle = Arc::new(juggler::start(
                    &link.uri,
                    sup,
                    rules.clone(),
                    &nodes,
                    &options,
                    Some(Arc::clone(&program)),
                )?);
                rc.juggler = Some(Arc::clone(&handle));
                Some(Box::new(juggler::SegmentSim::start(&link.uri, rules, options, program)?))
            }
            DeviceKind::SimAxis => None,
        };
        if let Some(ctl) = ctl {
            rc.sims.push(SimEntry { name: link.name.clone(), devices: simulated, ctl });
        }
    }
    build_devices(&mut rc, cell, &robots)?;
    // First connection.
    for d in &rc.devices {
        if let Err(e) = d.connect() {
            if options.require_devices {
                return Err(CellError::Device { name: d.name().into(), reason: e.to_string() });
            }
            tracing::warn!(device = d.name(), error = %e, "device not reachable at start; left to reconnection");
        }
    }
    Ok(rc)
}

fn rc_slot(slots: &BTreeMap<String, Slot>, name: &str) -> Slot {
    slots.get(name).cloned().unwrap_or_else(new_slot)
}

/// Creates the device objects (and groups) of every device; drivers are opened later.
fn build_devices(
    rc: &mut RunningCell,
    cell: &Cell,
    robots: &BTreeMap<String, Arc<std::sync::Mutex<Option<motus_robot::sim::SimRobot>>>>,
) -> Result<(), CellError> {
    let slots = rc.slots.clone();
    let slot = |name: &str| rc_slot(&slots, name);
    let mut handled_links = Vec::new();
    let mut ps1a_links = BTreeMap::new();
    let mut can_links = BTreeMap::new();
    for d in &cell.devices {
        let link = d.link.as_deref().and_then(|l| cell.link(l));
        let baud = link.map_or(0, |l| link_baud(cell, &l.name, d.kind));
        let need_link = || link.ok_or_else(|| CellError::Config(format!("device {}: no link", d.name)));
        match d.kind {
            DeviceKind::Ps1a => {
                let l = need_link()?;
                let shared = Arc::clone(
                    ps1a_links.entry(l.name.clone()).or_insert_with(|| ps1a::Ps1aLink::new(l, baud)),
                );
                let first = cell.axes_of_device(&d.name).first().map(|a| a.name.clone()).unwrap_or_default();
                rc.devices.push(Arc::new(ps1a::Ps1aDevice::new(cell, d, shared, slot(&first))?));
            }
            DeviceKind::Kv01 => {
                let l = need_link()?;
                let dev = kv01::Kv01Device::new(cell, d, l, baud, &slot)?;
                rc.arms.push(ArmGroup { arm: dev.arm_cell() });
                rc.devices.push(Arc::new(dev));
            }
            DeviceKind::Nfv2 => {
                let l = need_link()?;
                if handled_links.contains(&l.name) {
                    continue;
                }
                handled_links.push(l.name.clone());
                let shared = nfv2::Nfv2Link::new(cell, l, baud, &slot)?;
                for dev in nfv2::Nfv2Device::all(&shared) {
                    rc.devices.push(Arc::new(dev));
                }
                rc.nfv2_links.push(shared);
            }
            DeviceKind::Cia402 => {
                let l = need_link()?;
                let shared =
                    Arc::clone(can_links.entry(l.name.clone()).or_insert_with(|| cia402::CanLink::new(l)));
                let first = cell.axes_of_device(&d.name).first().map(|a| a.name.clone()).unwrap_or_default();
                rc.devices.push(Arc::new(cia402::Cia402Device::new(cell, d, shared, slot(&first))?));
            }
            DeviceKind::EplDrive => {
                let node = d.address.and_then(|a| u8::try_from(a).ok()).unwrap_or(0);
                let handle = rc.juggler.clone().ok_or_else(|| {
                    CellError::Config(format!(
                        "device {}: POWERLINK drives are only served with a [supervisor] and simulate = true",
                        d.name
                    ))
                })?;
                let axes = cell.axes_of_device(&d.name);
                for a in &axes {
                    put(
                        &slot(&a.name),
                        Box::new(juggler::EplAxis::new((*a).clone(), node, Arc::clone(&handle))),
                    );
                }
                rc.devices.push(Arc::new(juggler::EplDevice {
                    name: d.name.clone(),
                    axes: axes.iter().map(|a| a.name.clone()).collect(),
                    node,
                    handle,
                }));
            }
            DeviceKind::SimAxis => {
                let Some(a) = cell.axes_of_device(&d.name).into_iter().next() else { continue };
                let state = sim_axis::new_shared(a);
                put(&slot(&a.name), Box::new(sim_axis::SimAxis::new(a.clone(), Arc::clone(&state))));
                rc.sims.push(SimEntry {
                    name: d.name.clone(),
                    devices: vec![d.name.clone()],
                    ctl: Box::new(sim_axis::SimAxisControl(Arc::clone(&state))),
                });
                rc.devices.push(Arc::new(sim_axis::SimAxisDevice {
                    name: d.name.clone(),
                    axis: a.name.clone(),
                    state,
                }));
            }
        }
    }
    rc.groups = cell.groups.iter().map(|g| group(rc, cell, g, robots)).collect();
    Ok(())
}

/// The handle of one group.
fn group(
    rc: &RunningCell,
    cell: &Cell,
    g: &motus_station::config::Group,
    robots: &BTreeMap<String, Arc<std::sync::Mutex<Option<motus_robot::sim::SimRobot>>>>,
) -> CellGroup {
    let device_of = |axis: &str| cell.axis(axis).map(|a| a.device.clone());
    let link_of = |axis: &str| device_of(axis).and_then(|d| cell.device(&d).and_then(|d| d.link.clone()));
    let handle = match g.kind {
        GroupKind::Pantilt => rc
            .nfv2_links
            .iter()
            .find(|l| g.axes.first().and_then(|a| device_of(a)).is_some_and(|d| l.devices().contains(&d)))
            .filter(|l| l.has_head())
            .map_or(GroupHandle::Axes, |l| GroupHandle::PanTilt(PanTiltGroup { link: Arc::clone(l) })),
        GroupKind::Arm => {
            let kv01 = g.axes.first().and_then(|a| device_of(a)).and_then(|d| {
                let idx =
                    cell.devices.iter().filter(|x| x.kind == DeviceKind::Kv01).position(|x| x.name == d)?;
                rc.arms.get(idx).cloned()
            });
            kv01.map_or(GroupHandle::Axes, GroupHandle::Arm)
        }
        GroupKind::Omni => GroupHandle::Omni(OmniGroup {
            robot: g.axes.first().and_then(|a| link_of(a)).and_then(|l| robots.get(&l).cloned()),
        }),
        GroupKind::Juggler => rc.juggler.clone().map_or(GroupHandle::Axes, GroupHandle::Juggler),
        GroupKind::Gantry | GroupKind::Axes => GroupHandle::Axes,
    };
    CellGroup { name: g.name.clone(), kind: g.kind, axes: g.axes.clone(), handle }
}

impl RunningCell {
    /// The cell it runs.
    pub fn cell(&self) -> &Cell {
        &self.cell
    }

    /// Every configured axis, grouped per device (devices in file order, axes by index).
    /// Each call gives new handles on the same live axes.
    pub fn axes(&self) -> Vec<DeviceAxes> {
        self.cell
            .devices
            .iter()
            .map(|d| DeviceAxes {
                device: d.name.clone(),
                axes: self
                    .cell
                    .axes_of_device(&d.name)
                    .into_iter()
                    .filter_map(|a| self.axis(&a.name))
                    .collect(),
            })
            .collect()
    }

    /// The axis called `name` (a new handle on the live axis).
    pub fn axis(&self, name: &str) -> Option<Box<dyn Axis + Send>> {
        let config = self.cell.axis(name)?.clone();
        let slot = self.slots.get(name)?.clone();
        Some(Box::new(CellAxis::new(config, slot)))
    }

    /// One handle per device for the station's `Reconnector` (in file order; the NFv2
    /// controllers of one link are listed together).
    pub fn device_handles(&self) -> Vec<Box<dyn DeviceHandle>> {
        self.devices
            .iter()
            .map(|c| Box::new(CellDevice { ctl: Arc::clone(c) }) as Box<dyn DeviceHandle>)
            .collect()
    }

    /// The health check of device `name` (`None`: unknown device).
    pub fn device_connected(&self, name: &str) -> Option<bool> {
        self.devices.iter().find(|d| d.name() == name).map(|d| d.is_connected())
    }

    /// The groups, in file order.
    pub fn groups(&self) -> &[CellGroup] {
        &self.groups
    }

    /// The group called `name`.
    pub fn group(&self, name: &str) -> Option<&CellGroup> {
        self.groups.iter().find(|g| g.name == name)
    }

    /// The juggler's supervisor, when the cell has one.
    pub fn juggler(&self) -> Option<Arc<JugglerHandle>> {
        self.juggler.clone()
    }

    /// Every simulator.
    pub fn simulators(&self) -> Vec<SimulatorInfo> {
        self.sims
            .iter()
            .map(|s| SimulatorInfo {
                name: s.name.clone(),
                devices: s.devices.clone(),
                running: s.ctl.is_running(),
            })
            .collect()
    }

    fn sim_mut(&mut self, name: &str) -> Result<&mut SimEntry, CellError> {
        self.sims.iter_mut().find(|s| s.name == name || s.devices.iter().any(|d| d == name)).ok_or_else(
            || CellError::Simulator { name: name.into(), reason: "no such simulator in the cell".into() },
        )
    }

    /// Kills the simulator named `name` (a link name, or any device it simulates): its
    /// transport closes as if its process died.
    pub fn kill_simulator(&mut self, name: &str) -> Result<(), CellError> {
        let s = self.sim_mut(name)?;
        tracing::warn!(simulator = %s.name, "killing simulator");
        s.ctl.kill();
        Ok(())
    }

    /// Starts the simulator named `name` again (fresh state, as a restarted process).
    pub fn restart_simulator(&mut self, name: &str) -> Result<(), CellError> {
        let s = self.sim_mut(name)?;
        tracing::info!(simulator = %s.name, "restarting simulator");
        s.ctl.restart()
    }

    /// Stops every simulator, driver thread, supervisor and hub. Idempotent.
    pub fn stop(&mut self) {
        if self.stopped {
            return;
        }
        self.stopped = true;
        if let Some(j) = &self.juggler {
            j.shutdown();
        }
        for l in &self.nfv2_links {
            l.shutdown();
        }
        for a in &self.arms {
            kv01::shutdown(&a.arm);
        }
        for slot in self.slots.values() {
            *axis::lock(slot) = None;
        }
        for s in &mut self.sims {
            s.ctl.kill();
        }
        for h in &mut self.hubs {
            h.stop();
        }
    }
}

impl Drop for RunningCell {
    fn drop(&mut self) {
        self.stop();
    }
}
