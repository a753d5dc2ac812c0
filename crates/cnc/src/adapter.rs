//! Canonical calls of the interpreter -> items of the planner's block buffer.

use motus_cnc_planner::{ArcDirection, ExArray, PathItem, Plane, Segment};
use motus_gcode::{Canon, CanonCall, ExValue, MSync, MachineMove};

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

/// The block-buffer item of a canonical call (`None` for calls that do not reach the path:
/// units, planes, offsets, comments... — their effect is already in the machine coordinates).
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
