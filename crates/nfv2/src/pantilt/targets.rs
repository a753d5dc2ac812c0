//! Target streams for tracking: timestamped (pan, tilt) points, the target between them,
//! and the text form `motus pantilt <port> track <file-or-stdin>` reads.
//!
//! Text form: one point per line, `t pan tilt` (seconds from the start of the track,
//! degrees, degrees), separated by spaces, tabs or commas; `#` starts a comment; blank
//! lines are skipped; times must increase.

/// One target point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetPoint {
    /// Seconds from the start of the track.
    pub t: f64,
    /// Pan angle, degrees.
    pub pan_deg: f64,
    /// Tilt angle, degrees.
    pub tilt_deg: f64,
}

/// A malformed target line.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("target line {line}: {reason}")]
pub struct ParseTargetError {
    /// 1-based line number.
    pub line: usize,
    /// What is wrong.
    pub reason: String,
}

/// Parses one line; `Ok(None)` for a blank or comment line.
///
/// # Errors
/// [`ParseTargetError`] for anything but three finite numbers.
pub fn parse_target_line(text: &str, line: usize) -> Result<Option<TargetPoint>, ParseTargetError> {
    let content = text.split('#').next().unwrap_or_default().trim();
    if content.is_empty() {
        return Ok(None);
    }
    let fields: Vec<&str> =
        content.split(|c: char| c.is_whitespace() || c == ',').filter(|f| !f.is_empty()).collect();
    let err = |reason: String| ParseTargetError { line, reason };
    let [t, pan, tilt] = fields.as_slice() else {
        return Err(err(format!("expected `t pan tilt`, got {} field(s)", fields.len())));
    };
    let number = |name: &str, s: &str| -> Result<f64, ParseTargetError> {
        match s.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(err(format!("{name} {s:?} is not a finite number"))),
        }
    };
    Ok(Some(TargetPoint {
        t: number("t", t)?,
        pan_deg: number("pan", pan)?,
        tilt_deg: number("tilt", tilt)?,
    }))
}

/// Parses a whole track; times must increase strictly.
///
/// # Errors
/// [`ParseTargetError`] for a malformed line or a time that does not increase.
pub fn parse_track(text: &str) -> Result<Vec<TargetPoint>, ParseTargetError> {
    let mut points: Vec<TargetPoint> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if let Some(p) = parse_target_line(line, i + 1)? {
            if points.last().is_some_and(|last| p.t <= last.t) {
                return Err(ParseTargetError {
                    line: i + 1,
                    reason: format!("time {} does not increase", p.t),
                });
            }
            points.push(p);
        }
    }
    Ok(points)
}

/// The target between points: linear, with the segment's slope as its velocity; before
/// the first point the first point at rest; after the last one, extrapolated along the
/// last segment for at most `extrapolate` seconds (live feeds), then held.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct TargetTrack {
    points: Vec<TargetPoint>,
    pub(crate) extrapolate: f64,
}

/// A target on one axis: position and velocity.
pub(crate) type AxisTarget = (f64, f64);

impl TargetTrack {
    pub(crate) fn new(points: Vec<TargetPoint>, extrapolate: f64) -> Self {
        let mut track = TargetTrack { points: Vec::with_capacity(points.len()), extrapolate };
        for p in points {
            track.push(p);
        }
        track
    }

    /// Adds a point (ignored unless later than the last one).
    pub(crate) fn push(&mut self, p: TargetPoint) {
        if self.points.last().map_or(true, |last| p.t > last.t) && p.t.is_finite() {
            self.points.push(p);
        }
    }

    pub(crate) fn last_time(&self) -> Option<f64> {
        self.points.last().map(|p| p.t)
    }

    /// Pan and tilt targets at `t`.
    pub(crate) fn at(&self, t: f64) -> Option<[AxisTarget; 2]> {
        let first = self.points.first()?;
        if t <= first.t {
            return Some([(first.pan_deg, 0.0), (first.tilt_deg, 0.0)]);
        }
        let i = self.points.partition_point(|p| p.t <= t);
        let (a, b) = match (i.checked_sub(1).and_then(|j| self.points.get(j)), self.points.get(i)) {
            (Some(a), Some(b)) => (a, b),
            (Some(last), None) => {
                // After the last point: extrapolate along the last segment, then hold.
                let before = self.points.len().checked_sub(2).and_then(|j| self.points.get(j));
                let Some(prev) = before.filter(|_| self.extrapolate > 0.0) else {
                    return Some([(last.pan_deg, 0.0), (last.tilt_deg, 0.0)]);
                };
                let span = last.t - prev.t;
                let vp = (last.pan_deg - prev.pan_deg) / span;
                let vt = (last.tilt_deg - prev.tilt_deg) / span;
                let dt = t - last.t;
                if dt > self.extrapolate {
                    let h = self.extrapolate;
                    return Some([(last.pan_deg + vp * h, 0.0), (last.tilt_deg + vt * h, 0.0)]);
                }
                return Some([(last.pan_deg + vp * dt, vp), (last.tilt_deg + vt * dt, vt)]);
            }
            _ => return None,
        };
        let span = b.t - a.t;
        let f = (t - a.t) / span;
        let vp = (b.pan_deg - a.pan_deg) / span;
        let vt = (b.tilt_deg - a.tilt_deg) / span;
        Some([
            (a.pan_deg + f * (b.pan_deg - a.pan_deg), vp),
            (a.tilt_deg + f * (b.tilt_deg - a.tilt_deg), vt),
        ])
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn parses_lines_comments_and_commas() {
        let text = "# t pan tilt\n0 0 0\n\n0.5, 10, -5  # comment\n1.0\t20\t-10\n";
        let pts = parse_track(text).unwrap();
        assert_eq!(pts.len(), 3);
        assert_eq!(pts[1], TargetPoint { t: 0.5, pan_deg: 10.0, tilt_deg: -5.0 });
        assert_eq!(parse_track("0 0 0\n0 1 1").unwrap_err().line, 2);
        assert!(parse_track("0 0").is_err());
        assert!(parse_track("0 x 1").is_err());
        assert!(parse_track("0 inf 1").is_err());
    }

    #[test]
    fn interpolates_and_extrapolates_a_little() {
        let pts = vec![
            TargetPoint { t: 0.0, pan_deg: 0.0, tilt_deg: 0.0 },
            TargetPoint { t: 1.0, pan_deg: 10.0, tilt_deg: -10.0 },
        ];
        let held = TargetTrack::new(pts.clone(), 0.0);
        assert_eq!(held.at(-1.0), Some([(0.0, 0.0), (0.0, 0.0)]));
        assert_eq!(held.at(0.5), Some([(5.0, 10.0), (-5.0, -10.0)]));
        assert_eq!(held.at(2.0), Some([(10.0, 0.0), (-10.0, 0.0)]));
        let live = TargetTrack::new(pts, 0.1);
        let [(p, v), _] = live.at(1.05).unwrap();
        assert!((p - 10.5).abs() < 1e-9 && v == 10.0);
        let [(p, v), _] = live.at(3.0).unwrap();
        assert!((p - 11.0).abs() < 1e-9 && v == 0.0);
        assert_eq!(TargetTrack::default().at(0.0), None);
    }
}
