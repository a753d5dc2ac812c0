//! Canonical calls of the interpreter -> items of the planner's block buffer.
//!
//! Moves arrive in machine millimetres; path control (G61, G61.1, G64 P Q) arrives in
//! program units, so the [`Adapter`] follows the length units (`USE_LENGTH_UNITS`) to hand
//! the planner its tolerances in millimetres.

use motus_cnc_planner::{ArcDirection, ExArray, PathItem, PathMode, Plane, Segment};
use motus_gcode::{Canon, CanonCall, ExValue, MSync, MachineMove, MotionControl, Units};

use crate::AXES;

fn xyz(p: &[f64; 6]) -> [f64; AXES] {
    let [x, y, z, ..] = *p;
    [x, y, z]
}

fn plane(p: motus_gcode::Plane) -> Plane {
    match p {
        motus_gcode::Plane::Xy => Plane::Xy,
        motus_gcode::Plane::Xz => Plane::Zx,
        motus_gcode::Plane::Yz => Plane::Yz,
    }
}

/// The conversion of one program's canonical calls (it keeps the modal state the items need).
#[derive(Debug, Clone)]
pub struct Adapter {
    /// Millimetres per program unit.
    mm: f64,
    /// G61 / G61.1 / G64 and its P (mm).
    mode: MotionControl,
    tolerance: f64,
    /// G64 Q (mm).
    naive_cam: f64,
}

impl Default for Adapter {
    /// Millimetres, G64 without P or Q (as the interpreter starts).
    fn default() -> Self {
        Self { mm: 1.0, mode: MotionControl::Continuous, tolerance: 0.0, naive_cam: 0.0 }
    }
}

impl Adapter {
    /// The block-buffer item of a canonical call (`None` for calls that do not reach the
    /// path: planes, offsets, comments... — their effect is already in the machine
    /// coordinates).
    pub fn item(&mut self, call: &CanonCall) -> Option<PathItem<AXES>> {
        match &call.canon {
            Canon::UseLengthUnits { units } => {
                self.mm = match units {
                    Units::Mm => 1.0,
                    Units::Inch => 25.4,
                };
                None
            }
            Canon::SetMotionControlMode { mode, tolerance } => {
                self.mode = *mode;
                self.tolerance = tolerance * self.mm;
                Some(self.path_control())
            }
            Canon::SetNaivecamTolerance { tolerance } => {
                self.naive_cam = tolerance * self.mm;
                Some(self.path_control())
            }
            _ => item(call),
        }
    }

    fn path_control(&self) -> PathItem<AXES> {
        PathItem::PathControl(match self.mode {
            MotionControl::ExactStop => PathMode::ExactStop,
            MotionControl::ExactPath => PathMode::ExactPath,
            MotionControl::Continuous => {
                PathMode::Blend { tolerance: self.tolerance, naive_cam: self.naive_cam }
            }
        })
    }
}

/// The block-buffer item of a canonical call that needs no modal state: moves, M-functions,
/// external parameters, dwells (`None` for the others; see [`Adapter::item`]).
pub fn item(call: &CanonCall) -> Option<PathItem<AXES>> {
    if let Some(m) = &call.machine {
        return Some(PathItem::Motion(match m {
            MachineMove::Traverse { end, .. } => Segment::Line { end: xyz(end), feed: 0.0, rapid: true },
            MachineMove::Feed { end, feed, .. } => {
                Segment::Line { end: xyz(end), feed: feed / 60.0, rapid: false }
            }
            MachineMove::Arc { end, centre, plane: p, rotation, feed, .. } => {
                let pl = plane(*p);
                let (a, b, _) = pl.axes();
                let c = [centre.get(a).copied().unwrap_or(0.0), centre.get(b).copied().unwrap_or(0.0)];
                Segment::Arc {
                    end: xyz(end),
                    centre: c,
                    plane: pl,
                    direction: if *rotation < 0 {
                        ArcDirection::Clockwise
                    } else {
                        ArcDirection::CounterClockwise
                    },
                    extra_turns: rotation.unsigned_abs().saturating_sub(1),
                    feed: feed / 60.0,
                }
            }
        }));
    }
    match &call.canon {
        Canon::MFunction { number, sync } => {
            Some(PathItem::MFunction { number: *number, sync: *sync == MSync::Sync })
        }
        Canon::ExternalParameter { array, index, value } => {
            let _ = array; // the value's type names the array
            let (array, value) = match value {
                ExValue::B(v) => (ExArray::B, f64::from(*v)),
                ExValue::W(v) => (ExArray::W, f64::from(*v)),
                ExValue::L(v) => (ExArray::L, f64::from(*v)),
                ExValue::F(v) => (ExArray::F, f64::from(*v)),
            };
            Some(PathItem::ExternalParameter { array, index: *index, value })
        }
        Canon::Dwell { seconds } => Some(PathItem::Dwell { seconds: *seconds }),
        _ => None,
    }
}
