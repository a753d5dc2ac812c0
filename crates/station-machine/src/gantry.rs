//! The booked machine's gantry as the CNC program service drives it: the cell's
//! `kind = "gantry"` axes (program X, Y, Z in order), fed every cycle from the executor's
//! set-points through [`motus_cnc_planner::AxisSink`] (a `MoveAbsolute` per axis that moved).
//!
//! The sink commands nothing while the E-stop is pressed or the station stops: it fails
//! instead, which ends the run ("emergency stop"), and the E-stop's own quick stop halts the
//! axes. An axis that refuses a set-point ends the run with its error, and every gantry axis
//! gets a stop.

use std::sync::atomic::Ordering;
use std::sync::Arc;

use motus_axis::{Axis, AxisCommand, AxisError, AxisState, Capabilities, Scale};
use motus_cnc::{Limits3, SetpointSink};
use motus_cnc_planner::{AxisSink, Config, METRES_PER_MM};

use crate::{lock, Shared};

/// One station axis, shared with the HMI's commands (each call under the axis's lock).
struct StationAxis {
    shared: Arc<Shared>,
    index: usize,
    name: String,
    scale: Scale,
    capabilities: Capabilities,
}

impl Axis for StationAxis {
    fn name(&self) -> &str {
        &self.name
    }
    fn capabilities(&self) -> Capabilities {
        self.capabilities
    }
    fn scale(&self) -> &Scale {
        &self.scale
    }
    fn read_state(&mut self) -> Result<AxisState, AxisError> {
        self.with_axis(|a| a.read_state())
    }
    fn execute(&mut self, command: &AxisCommand) -> Result<(), AxisError> {
        self.with_axis(|a| a.execute(command))
    }
}

impl StationAxis {
    fn with_axis<T>(&self, f: impl FnOnce(&mut dyn Axis) -> Result<T, AxisError>) -> Result<T, AxisError> {
        match self.shared.axes.get(self.index) {
            Some(a) => f(&mut **lock(&a.axis)),
            None => Err(AxisError::Unsupported { axis: self.name.clone(), command: "commands".into() }),
        }
    }
}

/// The station index of each gantry axis (program X, Y, Z order), `None` when the cell has
/// no gantry or one of its axes is missing.
pub(crate) fn gantry_axes(shared: &Shared) -> Option<Vec<usize>> {
    let group = shared.config.groups.iter().find(|g| g.kind == motus_station::config::GroupKind::Gantry)?;
    group.axes.iter().map(|name| shared.axes.iter().position(|a| &a.view.id == name)).collect()
}

/// The set-point sink of the gantry (see the module documentation); `None` without one.
pub(crate) fn sink(shared: &Arc<Shared>, limits: &Limits3) -> Option<SetpointSink> {
    let indices = gantry_axes(shared)?;
    let mut sink = AxisSink::<3>::new(&Config::new(limits.axes), 1e-4);
    for (k, &index) in indices.iter().enumerate().take(3) {
        let entry = shared.axes.get(index)?;
        let (scale, capabilities) = {
            let a = lock(&entry.axis);
            (*a.scale(), a.capabilities())
        };
        let axis = StationAxis {
            shared: Arc::clone(shared),
            index,
            name: entry.view.id.clone(),
            scale,
            capabilities,
        };
        sink.map(k, Box::new(axis), METRES_PER_MM).ok()?;
    }
    let shared = Arc::clone(shared);
    Some(Box::new(move |sp| {
        if shared.estop.load(Ordering::SeqCst) || shared.stop.load(Ordering::Relaxed) {
            let _ = sink.stop_all();
            return Err("emergency stop: the program was stopped and the gantry halted".into());
        }
        sink.send(sp).map(|_| ()).map_err(|e| {
            let _ = sink.stop_all();
            format!("gantry: {e}; the program was stopped")
        })
    }))
}
