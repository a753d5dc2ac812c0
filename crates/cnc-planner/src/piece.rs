//! Planned pieces: straight lines, blend arcs and zero-length markers, with their limits.

use crate::item::ExArray;
use crate::vector::{add_scaled, scale};
use serde::Serialize;

/// A non-motion entry of the block buffer, placed at one point of the path.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "marker", rename_all = "snake_case")]
pub enum Marker {
    /// M-function (synchronous ones stop the path here).
    MFunction {
        /// M number.
        number: u16,
        /// Synchronous.
        sync: bool,
    },
    /// External parameter write.
    ExternalParameter {
        /// Array.
        array: ExArray,
        /// Index.
        index: u8,
        /// Value.
        value: f64,
    },
    /// Dwell (stops the path here).
    Dwell {
        /// Waiting time in seconds.
        seconds: f64,
    },
    /// Decoder synchronisation point (stops the path here).
    DecoderSync,
    /// Exact stop at a corner that cannot be blended (reversal, zero tolerance).
    ExactStop,
}

impl Marker {
    /// True when the path must come to rest at this marker.
    pub fn stops(&self) -> bool {
        match self {
            Marker::MFunction { sync, .. } => *sync,
            Marker::ExternalParameter { .. } => false,
            Marker::Dwell { .. } | Marker::DecoderSync | Marker::ExactStop => true,
        }
    }
}

/// Geometry of a piece, parameterised by the distance `x` from its start.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Geometry<const N: usize> {
    /// `start + x * dir` (`dir` is a unit vector).
    Line {
        /// Start point.
        start: [f64; N],
        /// Unit direction.
        dir: [f64; N],
    },
    /// `centre + r (cos φ e1 + sin φ e2)` with `φ = phi0 + x / r`.
    Arc {
        /// Centre.
        centre: [f64; N],
        /// First unit basis vector of the arc's plane.
        e1: [f64; N],
        /// Second unit basis vector, orthogonal to `e1`.
        e2: [f64; N],
        /// Radius.
        radius: f64,
        /// Angle at the start.
        phi0: f64,
    },
    /// A zero-length marker at `at`.
    Point {
        /// Location.
        at: [f64; N],
        /// What happens here.
        marker: Marker,
    },
}

/// One planned piece of the path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Piece<const N: usize> {
    /// Shape.
    pub geometry: Geometry<N>,
    /// Length along the path (0 for markers).
    pub length: f64,
    /// Velocity cap from the axes (and the centripetal limit on blends); never exceeded.
    pub cap: f64,
    /// Programmed feed (infinite for rapids); scaled by the override.
    pub feed: f64,
    /// Tangential acceleration limit (both signs).
    pub accel: f64,
    /// Program line that produced the piece.
    pub line: u32,
    /// Block sequence number (one per pushed item).
    pub block: u64,
    /// Path length from the start of the buffer to the start of this piece.
    pub s_start: f64,
    /// Exit-speed limit from the look-ahead with the hard caps.
    pub(crate) vx_hard: f64,
    /// Temporary stop at the end of this piece (single-block mode).
    pub(crate) stop_after: bool,
    /// Exit-speed limit from the look-ahead with the feed (override applied).
    pub(crate) vx_soft: f64,
}

impl<const N: usize> Piece<N> {
    /// Point at distance `x` from the start.
    pub fn position(&self, x: f64) -> [f64; N] {
        match &self.geometry {
            Geometry::Line { start, dir } => add_scaled(start, x, dir),
            Geometry::Arc { centre, e1, e2, radius, phi0 } => {
                let phi = phi0 + x / radius;
                let p = add_scaled(centre, radius * phi.cos(), e1);
                add_scaled(&p, radius * phi.sin(), e2)
            }
            Geometry::Point { at, .. } => *at,
        }
    }

    /// Unit tangent at distance `x` (zero for markers).
    pub fn tangent(&self, x: f64) -> [f64; N] {
        match &self.geometry {
            Geometry::Line { dir, .. } => *dir,
            Geometry::Arc { e1, e2, radius, phi0, .. } => {
                let phi = phi0 + x / radius;
                add_scaled(&scale(-phi.sin(), e1), phi.cos(), e2)
            }
            Geometry::Point { .. } => [0.0; N],
        }
    }

    /// Curvature vector `d²p/dx²` at distance `x` (zero on lines).
    pub fn curvature(&self, x: f64) -> [f64; N] {
        match &self.geometry {
            Geometry::Arc { e1, e2, radius, phi0, .. } => {
                let phi = phi0 + x / radius;
                let k = -1.0 / radius;
                add_scaled(&scale(k * phi.cos(), e1), k * phi.sin(), e2)
            }
            _ => [0.0; N],
        }
    }

    /// The marker, for zero-length pieces.
    pub fn marker(&self) -> Option<Marker> {
        match self.geometry {
            Geometry::Point { marker, .. } => Some(marker),
            _ => None,
        }
    }

    /// Highest speed at the start of the piece from which `exit` can still be reached at its
    /// end within the acceleration limit and the cap `cap` (markers pass `exit` through).
    pub fn entry_limit(&self, exit: f64, cap: f64) -> f64 {
        if self.length > 0.0 {
            cap.min((exit * exit + 2.0 * self.accel * self.length).sqrt())
        } else {
            cap.min(exit)
        }
    }

    /// Speed cap with the feed override `ovr` applied (rapids are not scaled).
    pub fn soft_cap(&self, ovr: f64) -> f64 {
        if self.feed.is_finite() {
            self.cap.min(self.feed * ovr)
        } else {
            self.cap
        }
    }
}
