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

    /// Starts a driver when there is none, the link's port changed (a restarted
    /// simulator), a latched module was power-cycled, or nothing answers; otherwise the
    /// running driver is kept, since it is what keeps every module's 700 ms time-out from
    /// tripping: a reconnection must never leave the arm without traffic while one module is
    /// silent.
    fn connect(&self) -> Result<(), DeviceError> {
        let mut g = self.arm.lock().unwrap_or_else(PoisonError::into_inner);
        let target = link_target(&self.path);
        let keep = g.as_ref().is_some_and(|(t, arm)| *t == target && target.is_some() && !must_restart(arm));
        if !keep {
            // Nothing may hold the old driver: its port must be closed before it is opened
            // again (the port is opened exclusively).
            for (_, _, slot) in &self.joints {
                *crate::axis::lock(slot) = None;
            }
            if let Some((_, old)) = g.take() {
                old.shutdown();
            }
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
            for (_, joint, slot) in &self.joints {
                let axis = Kv01JointAxis::new(Arc::clone(&arm), *joint)
                    .map_err(|e| DeviceError::Refused(e.to_string()))?;
                put(slot, Box::new(axis));
            }
            *g = Some((target, arm));
        }
        let silent = g.as_ref().map_or_else(Vec::new, |(_, arm)| silent_joints(arm));
        if silent.is_empty() {
            return Ok(());
        }
        let list = silent.iter().map(u8::to_string).collect::<Vec<_>>().join(", ");
        Err(DeviceError::NoAnswer(format!("the KV-01 arm on {}: module(s) {list} do not answer", self.path)))
    }

    fn is_connected(&self) -> bool {
        let g = self.arm.lock().unwrap_or_else(PoisonError::into_inner);
        match g.as_ref() {
            Some((target, arm)) => *target == link_target(&self.path) && target.is_some() && healthy(arm),
            None => false,
        }
    }

    fn needs_operator(&self) -> Option<String> {
        let g = self.arm.lock().unwrap_or_else(PoisonError::into_inner);
        let (_, arm) = g.as_ref()?;
        let modules: Vec<u8> =
            arm.latched_timeouts().iter().filter(|l| !l.answers_normally_again).map(|l| l.joint).collect();
        latched_message(&modules)
    }
}

/// The joints whose module neither gave a reading nor answered "TO" within [`STALE`] on the
/// arm's clock (a latched module still answers: the arm is there, and its alarm says what to
/// do).
fn silent_joints(arm: &Kv01Arm) -> Vec<u8> {
    let latched = arm.latched_timeouts();
    let answering =
        |joint: u8| latched.iter().any(|l| l.joint == joint && arm.clock().elapsed(l.last_answer) < STALE);
    arm.joints().iter().filter(|j| j.age >= STALE && !answering(j.joint)).map(|j| j.joint).collect()
}

/// The driver must be started again: a latched module answers normally again (it was
/// power-cycled, and this driver keeps the joint disabled), or no module answers at all.
fn must_restart(arm: &Kv01Arm) -> bool {
    arm.latched_timeouts().iter().any(|l| l.answers_normally_again) || silent_joints(arm).len() >= 6
}

/// Every module answers, and the driver need not be restarted.
fn healthy(arm: &Kv01Arm) -> bool {
    !must_restart(arm) && silent_joints(arm).is_empty()
}

/// What the operator must do about the modules (1..=6) that latched their 700 ms safety
/// time-out (`None`: none did).
pub(crate) fn latched_message(modules: &[u8]) -> Option<String> {
    let list = |v: &[u8]| v.iter().map(u8::to_string).collect::<Vec<_>>().join(", ");
    match modules {
        [] => None,
        [m] => Some(format!(
            "KV-01 module {m} latched its 700 ms communication time-out: power-cycle the arm (or restart \
             its simulator); joint {m} stays disabled until then"
        )),
        many => Some(format!(
            "KV-01 modules {} latched their 700 ms communication time-out: power-cycle the arm (or restart \
             its simulator); joints {} stay disabled until then",
            list(many),
            list(many)
        )),
    }
}

/// Shuts the arm's controller down (cell stop).
pub(crate) fn shutdown(arm: &ArmCell) {
    if let Some((_, a)) = arm.lock().unwrap_or_else(PoisonError::into_inner).take() {
        a.shutdown();
    }
}

#[cfg(test)]
mod tests {
    use super::latched_message;

    #[test]
    fn the_latched_message_says_what_to_do() {
        assert_eq!(latched_message(&[]), None);
        assert_eq!(
            latched_message(&[3]).as_deref(),
            Some(
                "KV-01 module 3 latched its 700 ms communication time-out: power-cycle the arm (or restart \
                 its simulator); joint 3 stays disabled until then"
            )
        );
        let many = latched_message(&[1, 2, 6]).unwrap_or_default();
        assert!(many.starts_with("KV-01 modules 1, 2, 6 latched their 700 ms"), "{many}");
        assert!(many.contains("power-cycle the arm"), "{many}");
    }
}
