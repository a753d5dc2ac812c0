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
        match *command {
            AxisCommand::MoveAbsolute { target, profile } => {
                let command = AxisCommand::MoveAbsolute { target: self.within_travel(target), profile };
                self.with_axis(|a| a.execute(&command))
            }
            _ => self.with_axis(|a| a.execute(command)),
        }
    }
}

impl StationAxis {
    /// A set-point at the end of the travel (a program going to X0 on an axis whose travel
    /// starts at 0) may lie outside it by the path's rounding (1e-17 m): within half a
    /// device unit, where the drive rounds to the same position, it is put on the end.
    /// Anything further is left to the axis, which refuses it (the run stops).
    fn within_travel(&self, target: f64) -> f64 {
        match self.shared.config.axis(&self.name) {
            Some(c) => onto_travel(target, c.limits.min, c.limits.max, self.scale.si_per_unit().abs() / 2.0),
            None => target,
        }
    }

    fn with_axis<T>(&self, f: impl FnOnce(&mut dyn Axis) -> Result<T, AxisError>) -> Result<T, AxisError> {
        match self.shared.axes.get(self.index) {
            Some(a) => f(&mut **lock(&a.axis)),
            None => Err(AxisError::Unsupported { axis: self.name.clone(), command: "commands".into() }),
        }
    }
}

/// `target` put on the end of the travel `min..=max` when it lies outside by at most `slack`.
fn onto_travel(target: f64, min: f64, max: f64, slack: f64) -> f64 {
    if target < min && target >= min - slack {
        min
    } else if target > max && target <= max + slack {
        max
    } else {
        target
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

#[cfg(test)]
mod tests {
    use super::onto_travel;

    #[test]
    fn rounding_past_the_travel_end_is_put_on_it_and_nothing_more() {
        let half_unit = 0.5e-6;
        assert_eq!(onto_travel(-7.1e-18, 0.0, 0.6, half_unit), 0.0);
        assert_eq!(onto_travel(0.6 + 1e-12, 0.0, 0.6, half_unit), 0.6);
        assert_eq!(onto_travel(0.3, 0.0, 0.6, half_unit), 0.3);
        // Beyond half a device unit: left to the axis, which refuses it.
        assert_eq!(onto_travel(-1e-6, 0.0, 0.6, half_unit), -1e-6);
        assert_eq!(onto_travel(0.61, 0.0, 0.6, half_unit), 0.61);
    }
}
