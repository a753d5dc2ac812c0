//! 1209A controllers (NFv2): the simulated controllers on a pty (`motus sim nfv2`), one
//! scheduler per link serving every controller on it, one [`Nfv2Axis`] per controller, and
//! the [`PanTilt`] head when a `pantilt` group names exactly the link's two controllers.

use std::path::PathBuf;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use motus_nfv2::{
    AxisConfig, Drive, DriveConfig, HeadAxis, Nfv2Axis, Nfv2Bus, PanTilt, PanTiltConfig, Scheduler,
    SchedulerConfig,
};
use motus_serial::BusConfig;
use motus_station::config::{Cell, DeviceKind, GroupKind, Link};
use motus_station::devices::DeviceError;

use crate::axis::{lock, put, Slot};
use crate::sim::{serve_pty, SimThread};
use crate::{link_target, CellError, DeviceCtl};

/// No valid answer for this long: the controller is lost.
const STALE: Duration = Duration::from_millis(400);

/// The simulated controllers of a link.
pub(crate) fn simulate(cell: &Cell, link: &Link, baud: u32) -> Result<Option<SimThread>, CellError> {
    let addresses: Vec<u8> = cell
        .devices_on_link(&link.name)
        .iter()
        .filter(|d| d.simulate && d.kind == DeviceKind::Nfv2)
        .filter_map(|d| d.address.and_then(|a| u8::try_from(a).ok()))
        .collect();
    if addresses.is_empty() {
        return Ok(None);
    }
    let name = link.name.clone();
    let sim = serve_pty(&link.name, PathBuf::from(&link.uri), baud, move |pty, stop| {
        let options = motus_nfv2_sim::LineOptions { addresses: addresses.clone(), ..Default::default() };
        let mut line = motus_nfv2_sim::SimLine::new(pty, options)
            .map_err(|e| CellError::Simulator { name: name.clone(), reason: e.to_string() })?;
        let n = name.clone();
        Ok(Box::new(move || {
            if let Err(e) = line.run(&stop) {
                tracing::warn!(simulator = %n, error = %e, "NFv2 simulator stopped");
            }
        }))
    })?;
    Ok(Some(sim))
}

/// One controller of the link.
struct Controller {
    device: String,
    axis: String,
    config: AxisConfig,
    slot: Slot,
}

/// What runs on the link while it is up.
struct Running {
    target: Option<PathBuf>,
    scheduler: Arc<Scheduler>,
    pantilt: Option<Arc<PanTilt>>,
    drives: Vec<Drive>,
}

/// The host side of one NFv2 link.
pub(crate) struct Nfv2Link {
    path: String,
    baud: u32,
    controllers: Vec<Controller>,
    pantilt: Option<PanTiltConfig>,
    running: Mutex<Option<Running>>,
}

impl Nfv2Link {
    /// The link's controllers and, if a pantilt group covers exactly them, the head.
    pub(crate) fn new(
        cell: &Cell,
        link: &Link,
        baud: u32,
        slots: &dyn Fn(&str) -> Slot,
    ) -> Result<Arc<Self>, CellError> {
        let mut controllers = Vec::new();
        for d in cell.devices_on_link(&link.name).into_iter().filter(|d| d.kind == DeviceKind::Nfv2) {
            let address = d.address.and_then(|a| u8::try_from(a).ok()).ok_or_else(|| {
                CellError::Config(format!("device {}: an NFv2 controller needs an address", d.name))
            })?;
            let Some(a) = cell.axes_of_device(&d.name).into_iter().next() else { continue };
            let mut config = AxisConfig::new(address);
            config.counts_per_rev = std::f64::consts::TAU / a.scale.si_per_unit();
            config.soft_limits = Some((a.limits.min, a.limits.max));
            controllers.push(Controller {
                device: d.name.clone(),
                axis: a.name.clone(),
                config,
                slot: slots(&a.name),
            });
        }
        let pantilt = head(cell, &controllers);
        Ok(Arc::new(Self { path: link.uri.clone(), baud, controllers, pantilt, running: Mutex::new(None) }))
    }

    fn lock(&self) -> MutexGuard<'_, Option<Running>> {
        self.running.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The device names on this link.
    pub(crate) fn devices(&self) -> Vec<String> {
        self.controllers.iter().map(|c| c.device.clone()).collect()
    }

    /// True when the link serves a pan-tilt head.
    pub(crate) fn has_head(&self) -> bool {
        self.pantilt.is_some()
    }

    /// The head, while the link runs.
    pub(crate) fn pantilt(&self) -> Option<Arc<PanTilt>> {
        self.lock().as_ref().and_then(|r| r.pantilt.clone())
    }

    /// True when the link is open on the port its path names and controller `i` answers.
    fn fresh(&self, i: usize) -> bool {
        let g = self.lock();
        let Some(r) = g.as_ref() else { return false };
        if r.target.is_none() || r.target != link_target(&self.path) {
            return false;
        }
        r.drives.get(i).and_then(|d| d.snapshot().last_answer).is_some_and(|t| t.elapsed() < STALE)
    }

    /// True when the link is not open on the port its path names now.
    fn needs_reopen(&self) -> bool {
        let g = self.lock();
        g.as_ref().is_none_or(|r| r.target.is_none() || r.target != link_target(&self.path))
    }

    /// (Re)opens the line, the scheduler (or head) and every controller's axis.
    fn reopen(&self) -> Result<(), DeviceError> {
        let mut g = self.lock();
        if let Some(old) = g.take() {
            for c in &self.controllers {
                *lock(&c.slot) = None;
            }
            old.scheduler.shutdown();
        }
        let target = link_target(&self.path);
        let link_err = |e: String| DeviceError::Link { link: self.path.clone(), reason: e };
        let bus =
            Nfv2Bus::open(&self.path, self.baud, BusConfig { margin: Duration::from_millis(3), retries: 2 })
                .map_err(|e| link_err(e.to_string()))?;
        let (scheduler, pantilt) = match &self.pantilt {
            Some(config) => {
                let head =
                    Arc::new(PanTilt::start(bus, config.clone()).map_err(|e| link_err(e.to_string()))?);
                (Arc::clone(head.scheduler()), Some(head))
            }
            None => {
                let drives =
                    self.controllers.iter().map(|c| c.config.drive.clone()).collect::<Vec<DriveConfig>>();
                let s = Scheduler::start(bus, drives, SchedulerConfig::default())
                    .map_err(|e| link_err(e.to_string()))?;
                (Arc::new(s), None)
            }
        };
        let mut drives = Vec::new();
        for c in &self.controllers {
            let drive =
                scheduler.drive(c.config.drive.address).map_err(|e| DeviceError::Refused(e.to_string()))?;
            let axis = Nfv2Axis::new(
                drive.clone(),
                c.config.clone(),
                format!("nfv2:{}#{}", self.path, c.config.drive.address),
            )
            .map_err(|e| DeviceError::Refused(e.to_string()))?;
            put(&c.slot, Box::new(axis));
            drives.push(drive);
        }
        *g = Some(Running { target, scheduler, pantilt, drives });
        Ok(())
    }

    /// Stops the scheduler (cell stop).
    pub(crate) fn shutdown(&self) {
        if let Some(r) = self.lock().take() {
            r.scheduler.shutdown();
        }
    }
}

/// The head's settings when a pantilt group names two controllers of this link.
fn head(cell: &Cell, controllers: &[Controller]) -> Option<PanTiltConfig> {
    let g = cell.groups.iter().find(|g| {
        g.kind == GroupKind::Pantilt
            && controllers.len() == 2
            && g.axes.iter().all(|a| controllers.iter().any(|c| &c.axis == a))
    })?;
    let axis = |name: &str| -> Option<HeadAxis> {
        let c = controllers.iter().find(|c| c.axis == name)?;
        let a = cell.axis(name)?;
        Some(HeadAxis {
            address: c.config.drive.address,
            counts_per_rev: c.config.counts_per_rev,
            limits_deg: (a.limits.min.to_degrees(), a.limits.max.to_degrees()),
            velocity_deg_s: a.max_velocity.to_degrees(),
            acceleration_deg_s2: a.max_acceleration.to_degrees(),
        })
    };
    let pan = axis(g.axes.first()?)?;
    let tilt = axis(g.axes.get(1)?)?;
    Some(PanTiltConfig { pan, tilt, ..PanTiltConfig::default() })
}

/// One controller as a device.
pub(crate) struct Nfv2Device {
    link: Arc<Nfv2Link>,
    index: usize,
    name: String,
    axis: String,
}

impl Nfv2Device {
    /// Every controller of the link as a device.
    pub(crate) fn all(link: &Arc<Nfv2Link>) -> Vec<Nfv2Device> {
        link.controllers
            .iter()
            .enumerate()
            .map(|(index, c)| Nfv2Device {
                link: Arc::clone(link),
                index,
                name: c.device.clone(),
                axis: c.axis.clone(),
            })
            .collect()
    }
}

impl DeviceCtl for Nfv2Device {
    fn name(&self) -> &str {
        &self.name
    }

    fn axes(&self) -> Vec<String> {
        vec![self.axis.clone()]
    }

    fn connect(&self) -> Result<(), DeviceError> {
        // A sibling controller may have reopened the link already; a link open on the
        // port its path names is kept (reopening it would cut the siblings off).
        if !self.link.fresh(self.index) && self.link.needs_reopen() {
            self.link.reopen()?;
        }
        let deadline = Instant::now() + Duration::from_secs(1);
        while Instant::now() < deadline {
            if self.link.fresh(self.index) {
                return Ok(());
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        Err(DeviceError::NoAnswer(format!("controller {} on {} does not answer", self.name, self.link.path)))
    }

    fn is_connected(&self) -> bool {
        self.link.fresh(self.index)
    }
}
