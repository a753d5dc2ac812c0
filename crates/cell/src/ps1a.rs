//! PS1A modules: the simulated line on a pty (`motus sim ps1a`) and one [`Ps1aAxis`] per
//! module on a bus shared by the link (as `motus axis ps1a://...` opens it).

use std::path::PathBuf;
use std::sync::{Arc, Mutex, PoisonError};

use motus_axis::FaultKind;
use motus_ps1a::{AxisConfig, Ps1aAxis, Ps1aBus};
use motus_ps1a_protocol::{Command, LowStatus, Parameters, U24};
use motus_ps1a_sim::{LineOptions, SimLine};
use motus_serial::{BusConfig, BusMaster, SerialLink, Traced};
use motus_station::config::{Cell, Device, Link};
use motus_station::devices::DeviceError;

use crate::axis::{put, Slot};
use crate::sim::{serve_pty, SimThread};
use crate::{CellError, DeviceCtl};

/// The simulated modules of a link (addresses of its simulated PS1A devices).
pub(crate) fn simulate(cell: &Cell, link: &Link, baud: u32) -> Result<Option<SimThread>, CellError> {
    let addresses: Vec<u8> = cell
        .devices_on_link(&link.name)
        .iter()
        .filter(|d| d.simulate && d.kind == motus_station::config::DeviceKind::Ps1a)
        .filter_map(|d| d.address.and_then(|a| u8::try_from(a).ok()))
        .collect();
    if addresses.is_empty() {
        return Ok(None);
    }
    let name = link.name.clone();
    let sim = serve_pty(&link.name, PathBuf::from(&link.uri), baud, move |pty, stop| {
        let options = LineOptions { addresses: addresses.clone(), ..LineOptions::default() };
        let mut line = SimLine::new(pty, options)
            .map_err(|e| CellError::Simulator { name: name.clone(), reason: e.to_string() })?;
        let n = name.clone();
        Ok(Box::new(move || {
            if let Err(e) = line.run(&stop) {
                tracing::warn!(simulator = %n, error = %e, "PS1A simulator stopped");
            }
        }))
    })?;
    Ok(Some(sim))
}

/// The host side of one PS1A link: one bus for the link's life, shared by its modules.
///
/// The bus is opened once and kept: its serial link closes the port after an IO error (a
/// restarted simulator, an unplugged adapter) and reopens the path at the next transaction.
/// A second bus on the same path would find the port taken (ports are opened exclusively):
/// the first one, reopened by a health check of another module, held it, and the module that
/// needed a new connect after the restart never came back.
pub(crate) struct Ps1aLink {
    path: String,
    baud: u32,
    bus: Mutex<Option<Ps1aBus>>,
}

impl Ps1aLink {
    pub(crate) fn new(link: &Link, baud: u32) -> Arc<Self> {
        Arc::new(Self { path: link.uri.clone(), baud, bus: Mutex::new(None) })
    }

    /// The bus, opened at the first call that finds the port.
    fn bus(&self) -> Result<Ps1aBus, DeviceError> {
        let mut g = self.bus.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(bus) = g.as_ref() {
            return Ok(bus.clone());
        }
        let link = SerialLink::open(&self.path, self.baud)
            .map_err(|e| DeviceError::Link { link: self.path.clone(), reason: e.to_string() })?;
        let bus = Ps1aBus::new(Arc::new(BusMaster::new(Box::new(Traced::new(link)), BusConfig::default())));
        *g = Some(bus.clone());
        Ok(bus)
    }
}

/// One PS1A module of the cell.
pub(crate) struct Ps1aDevice {
    name: String,
    axis: String,
    link: Arc<Ps1aLink>,
    config: AxisConfig,
    slot: Slot,
    /// The bus of the last connect.
    bus: Mutex<Option<Ps1aBus>>,
}

/// A module counts as lost after this many health checks in a row without a valid reply: a
/// loaded host drops a reply now and then (the 32.5 ms reply window), and one miss must not
/// take the axis away mid-move.
const LOST_AFTER_MISSES: u32 = 3;

impl Ps1aDevice {
    pub(crate) fn new(
        cell: &Cell,
        device: &Device,
        link: Arc<Ps1aLink>,
        slot: Slot,
    ) -> Result<Self, CellError> {
        let axis = cell.axes_of_device(&device.name).first().map(|a| (a.name.clone(), a.scale, a.limits));
        let (axis, scale, limits) =
            axis.ok_or_else(|| CellError::Config(format!("device {}: no [[axis]] uses it", device.name)))?;
        let addr = device.address.and_then(|a| u8::try_from(a).ok()).ok_or_else(|| {
            CellError::Config(format!("device {}: a PS1A needs an address 0..255", device.name))
        })?;
        // The module's maximum position: the upper machine limit in device units (a limit of a
        // whole number of units, 0.65535 m at 1e-5 m, is that number despite the float error).
        let units = scale.position_from_si(limits.max);
        let max = if (units - units.round()).abs() < 1e-6 { units.round() } else { units.floor() };
        let max_position = U24::new(if max >= 1.0 { max as u32 } else { 1 }).unwrap_or(U24::MAX);
        let config = AxisConfig { addr, scale, max_position, ..AxisConfig::default() };
        Ok(Self { name: device.name.clone(), axis, link, config, slot, bus: Mutex::new(None) })
    }
}

impl DeviceCtl for Ps1aDevice {
    fn name(&self) -> &str {
        &self.name
    }

    fn axes(&self) -> Vec<String> {
        vec![self.axis.clone()]
    }

    fn connect(&self) -> Result<(), DeviceError> {
        let bus = self.link.bus()?;
        let mut axis = Ps1aAxis::new(bus.clone(), self.config);
        motus_axis::Axis::read_state(&mut axis).map_err(|e| DeviceError::NoAnswer(e.to_string()))?;
        // The module's parameters cannot be read back: they are written on every connect
        // (connects happen at start and after the module was lost), as `motus demo` does.
        let parameters = Parameters {
            address: self.config.addr,
            max_position: self.config.max_position,
            ..Parameters::default()
        };
        bus.write_parameters(self.config.addr, parameters)
            .map_err(|e| DeviceError::Refused(e.to_string()))?;
        put(&self.slot, Box::new(axis));
        *self.bus.lock().unwrap_or_else(PoisonError::into_inner) = Some(bus);
        Ok(())
    }

    fn is_connected(&self) -> bool {
        // The serial link reopens its port by itself, so a restarted module answers again:
        // it is found by its status (no parameters) or by the axis's latched reset fault, and
        // needs a connect (which writes its parameters).
        let bus = self.bus.lock().unwrap_or_else(PoisonError::into_inner).clone();
        let Some(bus) = bus else { return false };
        match bus.transact(self.config.addr, Command::StatusRequest) {
            Ok(r) if !r.low.has(LowStatus::NO_PARAMETERS) => {}
            _ => return false,
        }
        match self.slot.try_lock() {
            Ok(mut g) => g.as_mut().is_some_and(|a| {
                a.read_state().is_ok_and(|s| !s.faults.iter().any(|f| f.kind == FaultKind::DeviceReset))
            }),
            Err(_) => true,
        }
    }

    fn lost_after_misses(&self) -> u32 {
        LOST_AFTER_MISSES
    }
}
