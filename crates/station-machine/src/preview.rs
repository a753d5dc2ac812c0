//! The tool path of a program for the HMI's preview: a polyline in machine millimetres
//! (arcs as chords of at most [`ARC_STEP`]), thinned to a bounded number of points — when
//! it would pass [`MAX_POINTS`], the spacing doubles and every other point goes, so a long
//! program's preview still covers all of it.

use motus_gcode::{MachineMove, Pose};
use motus_station_web::ProgramPreview;

/// Points a preview keeps at most.
pub(crate) const MAX_POINTS: usize = 20_000;
/// Largest angle of one arc chord, radians (5 degrees).
const ARC_STEP: f64 = std::f64::consts::PI / 36.0;
/// Chords of one arc at most (a many-turn helix stays bounded).
const MAX_CHORDS: usize = 2_000;

/// A preview being built (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PreviewBuilder {
    points: Vec<[f64; 3]>,
    rapid: Vec<bool>,
    spacing: f64,
}

impl Default for PreviewBuilder {
    fn default() -> Self {
        Self { points: Vec::new(), rapid: Vec::new(), spacing: 0.01 }
    }
}

fn every_other<T: Copy>(v: &[T]) -> Vec<T> {
    v.iter().step_by(2).copied().collect()
}

fn xyz(p: &Pose) -> [f64; 3] {
    [p[0], p[1], p[2]]
}

impl PreviewBuilder {
    fn push(&mut self, p: [f64; 3], rapid: bool) {
        if !p.iter().all(|v| v.is_finite()) {
            return;
        }
        if let Some(q) = self.points.last() {
            let d: f64 = p.iter().zip(q).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
            // A rapid's end always stays: the preview shows where the tool travels fast.
            if d < self.spacing && !rapid {
                return;
            }
        }
        self.points.push(p);
        self.rapid.push(rapid);
        if self.points.len() > MAX_POINTS {
            self.spacing *= 2.0;
            let last = (self.points.last().copied(), self.rapid.last().copied());
            self.points = every_other(&self.points);
            self.rapid = every_other(&self.rapid);
            if let (Some(p), Some(r)) = last {
                if self.points.last() != Some(&p) {
                    self.points.push(p);
                    self.rapid.push(r);
                }
            }
        }
    }

    /// Adds one machine move.
    pub(crate) fn visit(&mut self, m: &MachineMove) {
        let (start, end) = match m {
            MachineMove::Traverse { start, end } | MachineMove::Feed { start, end, .. } => (start, end),
            MachineMove::Arc { start, end, .. } => (start, end),
        };
        if self.points.is_empty() {
            self.push(xyz(start), true);
        }
        match m {
            MachineMove::Traverse { .. } => self.push(xyz(end), true),
            MachineMove::Feed { .. } => self.push(xyz(end), false),
            MachineMove::Arc { start, end, centre, plane, rotation, .. } => {
                let (a, b, c) = plane.axes();
                let (s, e) = (xyz(start), xyz(end));
                let (ca, cb) = (centre.get(a).copied().unwrap_or(0.0), centre.get(b).copied().unwrap_or(0.0));
                let at = |p: &[f64; 3], i: usize| p.get(i).copied().unwrap_or(0.0);
                let (sa, sb) = (at(&s, a) - ca, at(&s, b) - cb);
                let (ea, eb) = (at(&e, a) - ca, at(&e, b) - cb);
                let (r0, r1) = (sa.hypot(sb), ea.hypot(eb));
                let (t0, t1) = (sb.atan2(sa), eb.atan2(ea));
                let ccw = *rotation >= 0;
                let sweep = crate::checker::arc_sweep(t0, t1, *rotation);
                let n = ((sweep / ARC_STEP).ceil() as usize).clamp(1, MAX_CHORDS);
                for k in 1..=n {
                    let f = k as f64 / n as f64;
                    let t = if ccw { t0 + sweep * f } else { t0 - sweep * f };
                    let r = r0 + (r1 - r0) * f;
                    let mut p = s;
                    if let Some(v) = p.get_mut(a) {
                        *v = ca + r * t.cos();
                    }
                    if let Some(v) = p.get_mut(b) {
                        *v = cb + r * t.sin();
                    }
                    if let Some(v) = p.get_mut(c) {
                        *v = at(&s, c) + (at(&e, c) - at(&s, c)) * f;
                    }
                    self.push(if k == n { e } else { p }, false);
                }
            }
        }
    }

    /// The finished preview.
    pub(crate) fn finish(self) -> ProgramPreview {
        ProgramPreview { points: self.points, spacing_mm: self.spacing, rapid: self.rapid }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use motus_gcode::interpret;

    fn preview(src: &str) -> ProgramPreview {
        let mut b = PreviewBuilder::default();
        for c in interpret(src).unwrap() {
            if let Some(m) = &c.machine {
                b.visit(m);
            }
        }
        b.finish()
    }

    #[test]
    fn lines_and_arcs_become_a_polyline() {
        let p = preview("G21 G90 G0 X10 Y0\nG1 X20 F100\nG3 X0 Y0 I-10 J0\nM2\n");
        assert_eq!(p.points[0], [0.0, 0.0, 0.0]);
        assert_eq!(p.points[1], [10.0, 0.0, 0.0]);
        assert!(p.rapid[1] && !p.rapid[2]);
        assert_eq!(p.points[2], [20.0, 0.0, 0.0]);
        // A half circle of radius 10 about (10, 0), counter-clockwise: through (10, 10).
        assert_eq!(p.points.len(), 3 + 36, "{:?}", p.points);
        let top = p.points.iter().map(|q| q[1]).fold(f64::MIN, f64::max);
        assert!((top - 10.0).abs() < 1e-9, "{top}");
        assert_eq!(*p.points.last().unwrap(), [0.0, 0.0, 0.0]);
    }

    #[test]
    fn a_long_program_is_thinned_not_cut() {
        let mut src = String::from("G21 G90 F1000\n");
        for k in 0..30_000 {
            src.push_str(&format!("G1 X{} Y{}\n", k % 100, k / 100));
        }
        src.push_str("M2\n");
        let p = preview(&src);
        assert!(p.points.len() <= MAX_POINTS + 1, "{}", p.points.len());
        assert!(p.spacing_mm > 0.01);
        assert_eq!(*p.points.last().unwrap(), [99.0, 299.0, 0.0], "the end is kept");
    }
}
