//! The KV-01 arm: the simulated arm on a pty (`motus sim kv01`) and the arm driver with one
//! [`Kv01JointAxis`] per configured joint (as `motus axis kv01://...?joint=N` opens it).

use std::path::PathBuf;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use motus_kv01::{ArmConfig, Kv01Arm, Kv01Bus, Kv01JointAxis};
use motus_kv01_protocol::CrcMode;
use motus_serial::{BusConfig, BusMaster, SerialLink, Traced};
use motus_station::config::{Cell, Device, Link};
use motus_station::devices::DeviceError;

use crate::axis::{put, Slot};
use crate::sim::{serve_pty, SimThread};
use crate::{link_target, CellError, DeviceCtl};

/// The running arm with the port its path named when it was opened.
pub(crate) type ArmCell = Arc<Mutex<Option<(Option<PathBuf>, Arc<Kv01Arm>)>>>;

/// A joint reading older than this means the arm no longer answers.
const STALE: Duration = Duration::from_millis(500);

/// The simulated arm on the link's pty.
pub(crate) fn simulate(link: &Link, baud: u32) -> Result<SimThread, CellError> {
    let name = link.name.clone();
    serve_pty(&link.name, PathBuf::from(&link.uri), baud, move |pty, stop| {
        let mut line = motus_kv01_sim::SimLine::new(pty, motus_kv01_sim::LineOptions::default())
            .map_err(|e| CellError::Simulator { name: name.clone(), reason: e.to_string() })?;
        let n = name.clone();
        Ok(Box::new(move || {
            if let Err(e) = line.run(&stop) {
                tracing::warn!(simulator = %n, error = %e, "KV-01 simulator stopped");
            }
        }))
    })
}

/// The arm of the cell (one device, up to six joint axes).
pub(crate) struct Kv01Device {
    name: String,
    path: String,
    baud: u32,
    /// (axis name, joint 1..=6, slot)
    joints: Vec<(String, u8, Slot)>,
    arm: ArmCell,
}

impl Kv01Device {
    pub(crate) fn new(
        cell: &Cell,
        device: &Device,
        link: &Link,
        baud: u32,
        slots: &dyn Fn(&str) -> Slot,
    ) -> Result<Self, CellError> {
        let mut joints = Vec::new();
        for a in cell.axes_of_device(&device.name) {
            let joint = u8::try_from(a.index + 1).ok().filter(|j| (1..=6).contains(j)).ok_or_else(|| {
                CellError::Config(format!("axis {}: KV-01 joint index must be 0..5", a.name))
            })?;
            joints.push((a.name.clone(), joint, slots(&a.name)));
        }
        Ok(Self {
            name: device.name.clone(),
            path: link.uri.clone(),
            baud,
            joints,
            arm: Arc::new(Mutex::new(None)),
        })
    }

    /// The running arm (for the arm group).
    pub(crate) fn arm_cell(&self) -> ArmCell {
        Arc::clone(&self.arm)
    }
}

impl DeviceCtl for Kv01Device {
    fn name(&self) -> &str {
        &self.name
    }

    fn axes(&self) -> Vec<String> {
        self.joints.iter().map(|(n, _, _)| n.clone()).collect()
    }

    fn connect(&self) -> Result<(), DeviceError> {
        let mut g = self.arm.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some((_, old)) = g.take() {
            old.shutdown();
        }
        let target = link_target(&self.path);
        let link = SerialLink::open(&self.path, self.baud)
            .map_err(|e| DeviceError::Link { link: self.path.clone(), reason: e.to_string() })?;
        let bus = Kv01Bus::new(
            Arc::new(BusMaster::new(Box::new(Traced::new(link)), BusConfig::default())),
            CrcMode::Strict,
        );
        let arm = Arc::new(
            Kv01Arm::start(bus, ArmConfig::default())
                .map_err(|e| DeviceError::Link { link: self.path.clone(), reason: e.to_string() })?,
        );
        if !healthy(&arm) {
            arm.shutdown();
            return Err(DeviceError::NoAnswer(format!("the KV-01 arm on {} does not answer", self.path)));
        }
        for (_, joint, slot) in &self.joints {
            let axis = Kv01JointAxis::new(Arc::clone(&arm), *joint)
                .map_err(|e| DeviceError::Refused(e.to_string()))?;
            put(slot, Box::new(axis));
        }
        *g = Some((target, arm));
        Ok(())
    }

    fn is_connected(&self) -> bool {
        let g = self.arm.lock().unwrap_or_else(PoisonError::into_inner);
        match g.as_ref() {
            Some((target, arm)) => *target == link_target(&self.path) && target.is_some() && healthy(arm),
            None => false,
        }
    }
}

/// Every joint was read within [`STALE`].
fn healthy(arm: &Kv01Arm) -> bool {
    let joints = arm.joints();
    !joints.is_empty() && joints.iter().all(|j| j.age < STALE)
}

/// Shuts the arm's controller down (cell stop).
pub(crate) fn shutdown(arm: &ArmCell) {
    if let Some((_, a)) = arm.lock().unwrap_or_else(PoisonError::into_inner).take() {
        a.shutdown();
    }
}
