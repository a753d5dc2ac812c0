//! Printing canonical calls in the call names and argument order of LinuxCNC's `rs274`.
//!
//! [`Precision::Rs274`] prints numbers like `rs274` (`%.4f`, so the text can be diffed
//! with it); [`Precision::Full`] prints every number with Rust's shortest round-trip
//! formatting (`{}` on `f64`, e.g. `10`, `0.1`, `3.3333333333333335`), which loses nothing.
//! [`format_line`] adds `rs274`'s `%5d N..... ` prefix.

use std::fmt::Write;

use crate::canon::{Canon, CanonCall, ExValue, MSync, Plane, Units};

/// How numbers are printed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Precision {
    /// Shortest representation that reads back to the same `f64`.
    #[default]
    Full,
    /// Four decimals, like `rs274`.
    Rs274,
}

fn num(out: &mut String, v: f64, p: Precision) {
    // Writing to a String cannot fail.
    let _ = match p {
        Precision::Full => write!(out, "{v}"),
        Precision::Rs274 => write!(out, "{v:.4}"),
    };
}

fn nums(out: &mut String, vs: &[f64], p: Precision) {
    for (k, v) in vs.iter().enumerate() {
        if k > 0 {
            out.push_str(", ");
        }
        num(out, *v, p);
    }
}

/// The call as `rs274` prints it, e.g. `STRAIGHT_FEED(10, 5, 3, 0, 0, 0)`.
pub fn format_canon(c: &Canon, p: Precision) -> String {
    let mut o = String::with_capacity(64);
    match c {
        Canon::UseLengthUnits { units } => o.push_str(match units {
            Units::Mm => "USE_LENGTH_UNITS(CANON_UNITS_MM)",
            Units::Inch => "USE_LENGTH_UNITS(CANON_UNITS_INCHES)",
        }),
        Canon::SetG5xOffset { index, offset } => {
            let _ = write!(o, "SET_G5X_OFFSET({index}, ");
            nums(&mut o, offset, p);
            o.push(')');
        }
        Canon::SetG92Offset { offset } => {
            o.push_str("SET_G92_OFFSET(");
            nums(&mut o, offset, p);
            o.push(')');
        }
        Canon::SetXyRotation { degrees } => {
            o.push_str("SET_XY_ROTATION(");
            num(&mut o, *degrees, p);
            o.push(')');
        }
        Canon::SetFeedReference => o.push_str("SET_FEED_REFERENCE(CANON_XYZ)"),
        Canon::SetFeedMode => o.push_str("SET_FEED_MODE(0, 0)"),
        Canon::SetFeedRate { rate } => {
            o.push_str("SET_FEED_RATE(");
            num(&mut o, *rate, p);
            o.push(')');
        }
        Canon::SetSpindleSpeed { rpm } => {
            o.push_str("SET_SPINDLE_SPEED(0, ");
            num(&mut o, *rpm, p);
            o.push(')');
        }
        Canon::StartSpindleClockwise => o.push_str("START_SPINDLE_CLOCKWISE(0)"),
        Canon::StartSpindleCounterclockwise => o.push_str("START_SPINDLE_COUNTERCLOCKWISE(0)"),
        Canon::StopSpindleTurning => o.push_str("STOP_SPINDLE_TURNING(0)"),
        Canon::SetSpindleMode => {
            o.push_str("SET_SPINDLE_MODE(0 ");
            num(&mut o, 0.0, p);
            o.push(')');
        }
        Canon::MistOn => o.push_str("MIST_ON()"),
        Canon::FloodOn => o.push_str("FLOOD_ON()"),
        Canon::MistOff => o.push_str("MIST_OFF()"),
        Canon::FloodOff => o.push_str("FLOOD_OFF()"),
        Canon::SelectPlane { plane } => o.push_str(match plane {
            Plane::Xy => "SELECT_PLANE(CANON_PLANE_XY)",
            Plane::Xz => "SELECT_PLANE(CANON_PLANE_XZ)",
            Plane::Yz => "SELECT_PLANE(CANON_PLANE_YZ)",
        }),
        Canon::Comment { text } => {
            let _ = write!(o, "COMMENT(\"{text}\")");
        }
        Canon::Message { text } => {
            let _ = write!(o, "MESSAGE(\"{text}\")");
        }
        Canon::StraightTraverse { end } => {
            o.push_str("STRAIGHT_TRAVERSE(");
            nums(&mut o, end, p);
            o.push(')');
        }
        Canon::StraightFeed { end } => {
            o.push_str("STRAIGHT_FEED(");
            nums(&mut o, end, p);
            o.push(')');
        }
        Canon::ArcFeed(a) => {
            o.push_str("ARC_FEED(");
            nums(&mut o, &[a.first_end, a.second_end, a.first_centre, a.second_centre], p);
            let _ = write!(o, ", {}, ", a.rotation);
            nums(&mut o, &[a.axis_end, a.a, a.b, a.c], p);
            o.push(')');
        }
        Canon::Dwell { seconds } => {
            o.push_str("DWELL(");
            num(&mut o, *seconds, p);
            o.push(')');
        }
        Canon::OptionalProgramStop => o.push_str("OPTIONAL_PROGRAM_STOP()"),
        Canon::ProgramStop => o.push_str("PROGRAM_STOP()"),
        Canon::PalletShuttle => o.push_str("PALLET_SHUTTLE()"),
        Canon::ProgramEnd => o.push_str("PROGRAM_END()"),
        Canon::MFunction { number, sync } => {
            let s = match sync {
                MSync::Sync => "SYNC",
                MSync::Async => "ASYNC",
            };
            let _ = write!(o, "M_FUNCTION({number}, {s})");
        }
        Canon::ExternalParameter { array: _, index, value } => {
            let _ = match value {
                ExValue::B(v) => write!(o, "EXTERNAL_PARAMETER(B, {index}, {v})"),
                ExValue::W(v) => write!(o, "EXTERNAL_PARAMETER(W, {index}, {v})"),
                ExValue::L(v) => write!(o, "EXTERNAL_PARAMETER(L, {index}, {v})"),
                ExValue::F(v) => write!(o, "EXTERNAL_PARAMETER(F, {index}, {v})"),
            };
        }
    }
    o
}

/// A line as `rs274` prints it: `%5d` counter, the N field (`N..... ` or `N10    `), the call.
pub fn format_line(counter: u32, call: &CanonCall, p: Precision) -> String {
    let nfield = match call.n {
        Some(n) => format!("N{n:<5} "),
        None => "N..... ".to_owned(),
    };
    format!("{counter:5} {nfield}{}", format_canon(&call.canon, p))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use crate::canon::{ArcFeed, ExArray};

    #[test]
    fn rs274_text() {
        // Expected strings copied from rs274 output (LinuxCNC 2.9, Debian 12).
        let c = Canon::StraightFeed { end: [10.0, 5.0, 3.0, 0.0, 0.0, 0.0] };
        assert_eq!(
            format_canon(&c, Precision::Rs274),
            "STRAIGHT_FEED(10.0000, 5.0000, 3.0000, 0.0000, 0.0000, 0.0000)"
        );
        let a = Canon::ArcFeed(ArcFeed {
            first_end: 20.0,
            second_end: 5.0,
            first_centre: 15.0,
            second_centre: 5.0,
            rotation: -1,
            axis_end: 3.0,
            a: 0.0,
            b: 0.0,
            c: 0.0,
        });
        assert_eq!(
            format_canon(&a, Precision::Rs274),
            "ARC_FEED(20.0000, 5.0000, 15.0000, 5.0000, -1, 3.0000, 0.0000, 0.0000, 0.0000)"
        );
        assert_eq!(format_canon(&a, Precision::Full), "ARC_FEED(20, 5, 15, 5, -1, 3, 0, 0, 0)");
        let call = CanonCall {
            line: 3,
            n: Some(10),
            canon: Canon::StraightTraverse { end: [1.0, 2.0, 3.0, 0.0, 0.0, 0.0] },
            machine: None,
        };
        assert_eq!(
            format_line(10, &call, Precision::Rs274),
            "   10 N10    STRAIGHT_TRAVERSE(1.0000, 2.0000, 3.0000, 0.0000, 0.0000, 0.0000)"
        );
        let e = Canon::ExternalParameter { array: ExArray::W, index: 60, value: ExValue::W(3600) };
        assert_eq!(format_canon(&e, Precision::Full), "EXTERNAL_PARAMETER(W, 60, 3600)");
        let m = Canon::MFunction { number: 60, sync: MSync::Sync };
        assert_eq!(format_canon(&m, Precision::Full), "M_FUNCTION(60, SYNC)");
    }
}
