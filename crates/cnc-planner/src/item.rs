//! Input items of the block buffer: what the interpreter (decoder) produces.
//!
//! Coordinates are in CNC units (mm, or degrees for rotary axes), feeds in units per second.
//! `N` is the number of axes; axes 0, 1 and 2 are X, Y and Z (arcs need `N >= 3`), further
//! axes (A, B, C, auxiliary) follow in the order the caller chooses. The path length used for
//! the feed rate is the Euclidean length over all `N` axes.

use serde::{Deserialize, Serialize};

/// The plane of a circular arc (G17, G18, G19), naming the two circle axes and the helix axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Plane {
    /// G17: circle in X-Y, helix along Z.
    Xy,
    /// G18: circle in Z-X, helix along Y.
    Zx,
    /// G19: circle in Y-Z, helix along X.
    Yz,
}

impl Plane {
    /// Axis indices `(first, second, helix)`: the arc turns counter-clockwise from `first`
    /// towards `second` when seen from the positive helix axis.
    pub fn axes(self) -> (usize, usize, usize) {
        match self {
            Plane::Xy => (0, 1, 2),
            Plane::Zx => (2, 0, 1),
            Plane::Yz => (1, 2, 0),
        }
    }
}

/// Direction of an arc (G2 clockwise, G3 counter-clockwise).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ArcDirection {
    /// G2.
    Clockwise,
    /// G3.
    CounterClockwise,
}

/// One motion segment; the start is the end of the previous one.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Segment<const N: usize> {
    /// Straight line (G0 when `rapid`, G1 otherwise).
    Line {
        /// End point (all axes).
        #[serde(with = "serde_arrays")]
        end: [f64; N],
        /// Programmed feed rate in units per second along the path (ignored when `rapid`).
        feed: f64,
        /// Rapid traverse: as fast as the axes allow, not scaled by the feed override.
        rapid: bool,
    },
    /// Circular or helical arc (G2/G3) in `plane`; axes outside the circle move linearly
    /// with the angle (helix and any further axes).
    Arc {
        /// End point (all axes).
        #[serde(with = "serde_arrays")]
        end: [f64; N],
        /// Centre in the plane's `(first, second)` coordinates (absolute).
        centre: [f64; 2],
        /// Plane of the circle.
        plane: Plane,
        /// Turning direction.
        direction: ArcDirection,
        /// Additional full turns (G-code `P` minus one); 0 for an ordinary arc.
        extra_turns: u32,
        /// Programmed feed rate in units per second along the path.
        feed: f64,
    },
}

impl<const N: usize> Segment<N> {
    /// End point of the segment.
    pub fn end(&self) -> [f64; N] {
        match self {
            Segment::Line { end, .. } | Segment::Arc { end, .. } => *end,
        }
    }
}

/// The four external-parameter arrays shared with the PLC (EXB, EXW, EXL, EXF).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ExArray {
    /// int8 values (EXB).
    B,
    /// int16 values (EXW).
    W,
    /// int32 values (EXL).
    L,
    /// float32 values (EXF).
    F,
}

/// One entry of the block buffer.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "item", rename_all = "snake_case")]
pub enum PathItem<const N: usize> {
    /// A motion segment.
    Motion(Segment<N>),
    /// M-function `number`; a synchronous one stops the path here until
    /// [`crate::Executor::acknowledge`], an asynchronous one is reported and does not stop.
    MFunction {
        /// M number (0..1023).
        number: u16,
        /// Synchronous (waits for the technology's acknowledgement).
        sync: bool,
    },
    /// Write of an external parameter, reported when the path reaches this point.
    ExternalParameter {
        /// Which array.
        array: ExArray,
        /// Index in the array (0..99).
        index: u8,
        /// Value written.
        value: f64,
    },
    /// Dwell (G4): exact stop, then wait.
    Dwell {
        /// Waiting time in seconds.
        seconds: f64,
    },
    /// Decoder synchronisation (G170 in the source): the decoder may not push further items
    /// until the path has reached this point (exact stop).
    DecoderSync,
    /// How the moves after this point join (G61, G61.1, G64 P Q), until the next one.
    PathControl(PathMode),
}

/// How consecutive moves join (the corner at the end of a move takes that move's mode).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "mode", rename_all = "snake_case")]
pub enum PathMode {
    /// G64 P Q: corners blended within `tolerance` (0: the machine's path tolerance); lines of
    /// one feed that stay within `naive_cam` of a single line are folded into it (CAM output's
    /// short segments; 0: never).
    Blend {
        /// Largest distance of a blend from the programmed corner, units.
        tolerance: f64,
        /// Naive-CAM folding tolerance, units.
        naive_cam: f64,
    },
    /// G61: every programmed point is reached (the path stops at a corner; it runs on only
    /// where two moves are collinear).
    ExactPath,
    /// G61.1: the path stops at the end of every move.
    ExactStop,
}

impl Default for PathMode {
    /// Blending within the machine's path tolerance, no folding.
    fn default() -> Self {
        PathMode::Blend { tolerance: 0.0, naive_cam: 0.0 }
    }
}

/// Serde support for `[f64; N]` with a const generic `N`.
pub(crate) mod serde_arrays {
    use serde::de::Error as _;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    /// Serialise as a sequence.
    pub fn serialize<S: Serializer, const N: usize>(v: &[f64; N], s: S) -> Result<S::Ok, S::Error> {
        v.as_slice().serialize(s)
    }

    /// Deserialise from a sequence of exactly `N` numbers.
    pub fn deserialize<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<[f64; N], D::Error> {
        let v = Vec::<f64>::deserialize(d)?;
        let len = v.len();
        v.try_into().map_err(|_| D::Error::custom(format!("expected {N} coordinates, got {len}")))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn json_round_trip_and_length_check() {
        let items: Vec<PathItem<3>> = vec![
            PathItem::Motion(Segment::Line { end: [1.0, 2.0, 3.0], feed: 10.0, rapid: false }),
            PathItem::Motion(Segment::Arc {
                end: [0.0, 2.0, 0.0],
                centre: [0.0, 1.0],
                plane: Plane::Xy,
                direction: ArcDirection::Clockwise,
                extra_turns: 1,
                feed: 5.0,
            }),
            PathItem::MFunction { number: 60, sync: true },
            PathItem::ExternalParameter { array: ExArray::W, index: 60, value: 3600.0 },
            PathItem::Dwell { seconds: 0.5 },
            PathItem::DecoderSync,
        ];
        let json = serde_json::to_string(&items).unwrap();
        let back: Vec<PathItem<3>> = serde_json::from_str(&json).unwrap();
        assert_eq!(back, items);
        let line = r#"{"item":"motion","kind":"line","end":[1,2],"feed":1,"rapid":false}"#;
        let err = serde_json::from_str::<PathItem<3>>(line).unwrap_err().to_string();
        assert!(err.contains("expected 3 coordinates, got 2"), "{err}");
    }
}
