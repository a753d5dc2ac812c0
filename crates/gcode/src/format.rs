//! Printing canonical calls in the call names and argument order of LinuxCNC's `rs274`.
//!
//! [`Precision::Rs274`] prints numbers like `rs274` (`%.4f`, so the text can be diffed
//! with it); [`Precision::Full`] prints every number with Rust's shortest round-trip
//! formatting (`{}` on `f64`, e.g. `10`, `0.1`, `3.3333333333333335`), which loses nothing.
//! [`format_line`] adds `rs274`'s `%5d N..... ` prefix. [`write_canon`] and
//! [`write_line`] append the same text to a reused `String` (no allocation per call).

use std::fmt::Write;

use crate::canon::{Canon, CanonCall, ExValue, MSync, MotionControl, Plane, Units};

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
        Precision::Rs274 => {
            if fixed4(out, v) {
                return;
            }
            write!(out, "{v:.4}")
        }
    };
}

/// `{v:.4}` without the general formatting machinery, when the rounding is certain:
/// `x = |v| * 10^4` is within `x * 2^-53` of the exact product, so unless the fraction
/// of `x` lies that close to one half, rounding `x` gives the exact digits. Returns
/// `false` (nothing written) otherwise, or for large and non-finite values.
fn fixed4(out: &mut String, v: f64) -> bool {
    let x = v.abs() * 10_000.0;
    if x.is_nan() || x >= 1e15 {
        return false;
    }
    // x < 1e15 < 2^53: the truncation and the fraction are exact.
    let t = x as u64;
    let frac = x - t as f64;
    if (frac - 0.5).abs() <= x * f64::EPSILON {
        return false;
    }
    let n = t + u64::from(frac > 0.5);
    if v.is_sign_negative() {
        out.push('-');
    }
    let mut digits = [0u8; 20];
    let mut k = digits.len();
    let mut ip = n / 10_000;
    loop {
        k -= 1;
        if let Some(d) = digits.get_mut(k) {
            // A single decimal digit.
            *d = b'0' + (ip % 10) as u8;
        }
        ip /= 10;
        if ip == 0 {
            break;
        }
    }
    for &d in digits.get(k..).unwrap_or(&[]) {
        out.push(char::from(d));
    }
    out.push('.');
    let dec = n % 10_000;
    for div in [1000, 100, 10, 1] {
        // A single decimal digit.
        out.push(char::from(b'0' + (dec / div % 10) as u8));
    }
    true
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
    write_canon(&mut o, c, p);
    o
}

/// Appends the text of [`format_canon`] to `o`.
pub fn write_canon(o: &mut String, c: &Canon, p: Precision) {
    match c {
        Canon::UseLengthUnits { units } => o.push_str(match units {
            Units::Mm => "USE_LENGTH_UNITS(CANON_UNITS_MM)",
            Units::Inch => "USE_LENGTH_UNITS(CANON_UNITS_INCHES)",
        }),
        Canon::SetG5xOffset { index, offset } => {
            let _ = write!(o, "SET_G5X_OFFSET({index}, ");
            nums(o, offset, p);
            o.push(')');
        }
        Canon::SetG92Offset { offset } => {
            o.push_str("SET_G92_OFFSET(");
            nums(o, offset, p);
            o.push(')');
        }
        Canon::SetXyRotation { degrees } => {
            o.push_str("SET_XY_ROTATION(");
            num(o, *degrees, p);
            o.push(')');
        }
        Canon::SetFeedReference => o.push_str("SET_FEED_REFERENCE(CANON_XYZ)"),
        Canon::SetFeedMode { per_revolution } => {
            o.push_str(if *per_revolution { "SET_FEED_MODE(0, 1)" } else { "SET_FEED_MODE(0, 0)" });
        }
        Canon::SetFeedRate { rate } => {
            o.push_str("SET_FEED_RATE(");
            num(o, *rate, p);
            o.push(')');
        }
        Canon::SetSpindleSpeed { rpm } => {
            o.push_str("SET_SPINDLE_SPEED(0, ");
            num(o, *rpm, p);
            o.push(')');
        }
        Canon::StartSpindleClockwise => o.push_str("START_SPINDLE_CLOCKWISE(0)"),
        Canon::StartSpindleCounterclockwise => o.push_str("START_SPINDLE_COUNTERCLOCKWISE(0)"),
        Canon::StopSpindleTurning => o.push_str("STOP_SPINDLE_TURNING(0)"),
        Canon::SetSpindleMode { max_rpm } => {
            o.push_str("SET_SPINDLE_MODE(0 ");
            num(o, *max_rpm, p);
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
            nums(o, end, p);
            o.push(')');
        }
        Canon::StraightFeed { end } => {
            o.push_str("STRAIGHT_FEED(");
            nums(o, end, p);
            o.push(')');
        }
        Canon::ArcFeed(a) => {
            o.push_str("ARC_FEED(");
            nums(o, &[a.first_end, a.second_end, a.first_centre, a.second_centre], p);
            let _ = write!(o, ", {}, ", a.rotation);
            nums(o, &[a.axis_end, a.a, a.b, a.c], p);
            o.push(')');
        }
        Canon::Dwell { seconds } => {
            o.push_str("DWELL(");
            num(o, *seconds, p);
            o.push(')');
        }
        Canon::SetMotionControlMode { mode, tolerance } => match mode {
            MotionControl::ExactStop => o.push_str("SET_MOTION_CONTROL_MODE(CANON_EXACT_STOP)"),
            MotionControl::ExactPath => o.push_str("SET_MOTION_CONTROL_MODE(CANON_EXACT_PATH)"),
            MotionControl::Continuous => {
                o.push_str("SET_MOTION_CONTROL_MODE(CANON_CONTINUOUS, ");
                // rs274 prints this tolerance with six decimals.
                let _ = match p {
                    Precision::Full => write!(o, "{tolerance}"),
                    Precision::Rs274 => write!(o, "{tolerance:.6}"),
                };
                o.push(')');
            }
        },
        Canon::SetNaivecamTolerance { tolerance } => {
            o.push_str("SET_NAIVECAM_TOLERANCE(");
            num(o, *tolerance, p);
            o.push(')');
        }
        Canon::SelectTool { tool } => {
            let _ = write!(o, "SELECT_TOOL({tool})");
        }
        Canon::StartChange => o.push_str("START_CHANGE()"),
        Canon::ChangeTool { index } => {
            let _ = write!(o, "CHANGE_TOOL({index})");
        }
        Canon::UseToolLengthOffset { offset } => {
            o.push_str("USE_TOOL_LENGTH_OFFSET(");
            for (k, v) in offset.iter().enumerate() {
                if k == 3 {
                    o.push_str(", ");
                } else if k > 0 {
                    o.push(' ');
                }
                num(o, *v, p);
            }
            o.push_str(", ");
            for k in 0..3 {
                if k > 0 {
                    o.push(' ');
                }
                num(o, 0.0, p);
            }
            o.push(')');
        }
        Canon::OptionalProgramStop => o.push_str("OPTIONAL_PROGRAM_STOP()"),
        Canon::ProgramStop => o.push_str("PROGRAM_STOP()"),
        Canon::PalletShuttle => o.push_str("PALLET_SHUTTLE()"),
        Canon::ProgramEnd => o.push_str("PROGRAM_END()"),
        Canon::DigitalOutput { index, on, with_motion } => {
            let verb = if *on { "SET" } else { "CLEAR" };
            let kind = if *with_motion { "MOTION" } else { "AUX" };
            let _ = write!(o, "{verb}_{kind}_OUTPUT_BIT({index})");
        }
        Canon::AnalogOutput { index, value, with_motion } => {
            let kind = if *with_motion { "MOTION" } else { "AUX" };
            let _ = match p {
                Precision::Full => write!(o, "SET_{kind}_OUTPUT_VALUE({index},{value})"),
                Precision::Rs274 => write!(o, "SET_{kind}_OUTPUT_VALUE({index},{value:.6})"),
            };
        }
        Canon::WaitInput { index, analog, mode, timeout } => {
            let kind = if *analog { "ANALOG_INPUT" } else { "DIGITAL_INPUT" };
            let _ = write!(o, "WAIT({index}, {kind}, {}, ", mode.number());
            num(o, *timeout, p);
            o.push(')');
        }
        Canon::ChangeToolNumber { index } => {
            let _ = write!(o, "CHANGE_TOOL_NUMBER({index})");
        }
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
}

/// A line as `rs274` prints it: `%5d` counter, the N field (`N..... ` or `N10    `), the call.
pub fn format_line(counter: u32, call: &CanonCall, p: Precision) -> String {
    let mut o = String::with_capacity(96);
    write_line(&mut o, counter, call, p);
    o
}

/// Appends the text of [`format_line`] to `o` (without a line terminator).
pub fn write_line(o: &mut String, counter: u32, call: &CanonCall, p: Precision) {
    // Writing to a String cannot fail.
    let _ = write!(o, "{counter:5} ");
    let _ = match call.n {
        Some(n) => write!(o, "N{n:<5} "),
        None => {
            o.push_str("N..... ");
            Ok(())
        }
    };
    write_canon(o, &call.canon, p);
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
        let io = Canon::AnalogOutput { index: 2, value: -1.0, with_motion: false };
        assert_eq!(format_canon(&io, Precision::Rs274), "SET_AUX_OUTPUT_VALUE(2,-1.000000)");
        let io = Canon::DigitalOutput { index: 3, on: false, with_motion: true };
        assert_eq!(format_canon(&io, Precision::Full), "CLEAR_MOTION_OUTPUT_BIT(3)");
        let m = Canon::MFunction { number: 60, sync: MSync::Sync };
        assert_eq!(format_canon(&m, Precision::Full), "M_FUNCTION(60, SYNC)");
    }

    #[test]
    fn fixed4_is_rust_dot4() {
        // The fast path must print exactly what `{:.4}` prints (the reference).
        let mut vals =
            vec![0.0, -0.0, -0.00001, 0.00005, 1.00005, 2.5, -1234.56789, 0.99995, 9.99999, 1e14, 1e16];
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        for _ in 0..200_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let mag = [1e-6, 1e-2, 1.0, 1e3, 1e6, 1e11][(x % 6) as usize];
            let v = ((x >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * mag;
            vals.push(v);
            // Decimal ties and near-ties, the hard cases.
            vals.push(((x % 2_000_000) as f64 + 0.5) / 10_000.0);
        }
        let (mut fast, mut s) = (0, String::new());
        for v in vals {
            s.clear();
            if fixed4(&mut s, v) {
                fast += 1;
                assert_eq!(s, format!("{v:.4}"), "{v:e}");
            }
        }
        // About every random value (the ties fall back, as they must).
        assert!(fast > 190_000, "fast path taken {fast} times");
    }
}
