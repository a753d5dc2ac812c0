//! The block buffer and the look-ahead planner.
//!
//! Items pushed by the decoder become pieces: arcs are split into chords within the chord
//! tolerance; every corner between two lines is rounded by a circular blend tangent to both
//! lines, as large as the path tolerance allows (its midpoint stays within
//! `path_tolerance` of the programmed corner) but using at most half of either line. Each
//! blend is stored as two half arcs so the block boundary (where markers such as
//! asynchronous M-functions sit) is the blend's midpoint. Per-axis limits are projected onto
//! each piece: on a line with unit direction `u`, speed `<= min vmax_i/|u_i|` and acceleration
//! `<= min amax_i/|u_i|`; on a blend with plane basis `e1, e2` the per-axis amplitude
//! `r_i = sqrt(e1_i² + e2_i²)` bounds both the tangent and the normal components, so speed
//! `<= min vmax_i/r_i`, centripetal acceleration `v²/R <= k A` and tangential acceleration
//! `<= A - v_top²/R` with `A = min amax_i/r_i` and `k` the configured centripetal share.
//!
//! The look-ahead is the classic backward pass (as in grbl or Klipper): each piece gets the
//! highest exit speed from which everything after it can still be slowed down within the
//! acceleration limits, ending at rest at the end of the known path and at every stop
//! marker. It is updated incrementally on every push (stopping where values no longer
//! change) and once per override change. The forward pass is done online by the executor.
//! The last pushed line stays pending until the next one arrives (its end corner is not
//! known yet), or until a stopping item or [`Planner::finish`] closes it.
//!
//! Path control ([`PathMode`], G61/G61.1/G64 P Q) applies per move: the corner at the end of
//! a move takes that move's mode. G64 P bounds the blend (P 0: the machine's path
//! tolerance); G64 Q folds consecutive lines of one feed into one while every folded point
//! stays within Q of it; G61 blends nothing (the path stops at every corner that is not
//! straight on); G61.1 stops at the end of every move. The chords of one arc always join
//! as G64 (they are the planner's own approximation of one move).

use crate::arc::{linearise, ArcSpec};
use crate::config::Config;
use crate::error::{ConfigError, PushError};
use crate::item::{PathItem, PathMode, Segment};
use crate::piece::{Geometry, Marker, Piece};
use crate::vector::{add_scaled, dot, norm, scale, sub};
use std::collections::VecDeque;

/// Highest feed override the planner allows (200 %).
pub const MAX_OVERRIDE: f64 = 2.0;

/// Lines shorter than this (in units) are dropped.
const MIN_LENGTH: f64 = 1e-9;

/// Points one folded line (G64 Q) keeps for its check at most; a longer run starts anew.
const MAX_FOLDED: usize = 64;

/// A line whose end corner is not known yet.
#[derive(Debug, Clone, Copy)]
struct Pending<const N: usize> {
    start: [f64; N],
    end: [f64; N],
    dir: [f64; N],
    /// Programmed (untrimmed) length.
    full: f64,
    feed: f64,
    line: u32,
    block: u64,
    /// The path mode in force for this move (its end corner).
    mode: PathMode,
}

/// Block buffer with look-ahead.
#[derive(Debug, Clone)]
pub struct Planner<const N: usize> {
    cfg: Config<N>,
    pieces: VecDeque<Piece<N>>,
    base: u64,
    cursor: usize,
    pending: Option<Pending<N>>,
    /// The programmed points folded into the pending line (G64 Q), its start and end
    /// excluded.
    folded: Vec<[f64; N]>,
    /// The path mode for the moves pushed from now on.
    mode: PathMode,
    pending_markers: Vec<(Marker, u32, u64)>,
    position: [f64; N],
    s_end: f64,
    ovr: f64,
    block: u64,
    awaiting_sync: Option<u32>,
    segments: u64,
}

impl<const N: usize> Planner<N> {
    /// Empty buffer starting at `start`.
    pub fn new(cfg: Config<N>, start: [f64; N]) -> Result<Self, ConfigError> {
        cfg.validate()?;
        Ok(Self {
            cfg,
            pieces: VecDeque::new(),
            base: 0,
            cursor: 0,
            pending: None,
            folded: Vec::new(),
            mode: PathMode::default(),
            pending_markers: Vec::new(),
            position: start,
            s_end: 0.0,
            ovr: 1.0,
            block: 0,
            awaiting_sync: None,
            segments: 0,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &Config<N> {
        &self.cfg
    }

    /// Programmed end point of everything pushed so far.
    pub fn position(&self) -> [f64; N] {
        self.position
    }

    /// Planned pieces still held (executed history first, then the pieces ahead).
    pub fn pieces(&self) -> &VecDeque<Piece<N>> {
        &self.pieces
    }

    /// Global index of `pieces()[0]` (pieces dropped from the history are counted).
    pub fn base(&self) -> u64 {
        self.base
    }

    /// Number of pieces ahead of the executor (its current piece included).
    pub fn ahead(&self) -> usize {
        self.pieces.len().saturating_sub(self.cursor)
    }

    /// Motion segments (lines and arc chords) accepted so far.
    pub fn segments(&self) -> u64 {
        self.segments
    }

    /// Line of a decoder synchronisation point not reached yet, if any.
    pub fn awaiting_sync(&self) -> Option<u32> {
        self.awaiting_sync
    }

    /// True when a line is waiting for its successor (call [`Planner::finish`] at the end).
    pub fn has_pending(&self) -> bool {
        self.pending.is_some() || !self.pending_markers.is_empty()
    }

    /// The current feed override (1.0 = 100 %).
    pub fn feed_override(&self) -> f64 {
        self.ovr
    }

    /// Appends one item of program line `line`.
    pub fn push(&mut self, line: u32, item: PathItem<N>) -> Result<(), PushError> {
        if let Some(line) = self.awaiting_sync {
            return Err(PushError::AwaitingDecoderSync { line });
        }
        if self.ahead() >= self.cfg.buffer_capacity {
            return Err(PushError::Full { capacity: self.cfg.buffer_capacity });
        }
        let first_new = self.pieces.len();
        self.block += 1;
        let block = self.block;
        match item {
            PathItem::Motion(seg) => self.push_motion(line, block, seg)?,
            PathItem::MFunction { number, sync } => {
                self.push_marker(Marker::MFunction { number, sync }, line, block);
            }
            PathItem::ExternalParameter { array, index, value } => {
                self.push_marker(Marker::ExternalParameter { array, index, value }, line, block);
            }
            PathItem::Dwell { seconds } => {
                if !(seconds.is_finite() && seconds >= 0.0) {
                    return Err(PushError::Dwell { line, seconds });
                }
                self.push_marker(Marker::Dwell { seconds }, line, block);
            }
            PathItem::DecoderSync => {
                self.push_marker(Marker::DecoderSync, line, block);
                self.awaiting_sync = Some(line);
            }
            PathItem::PathControl(mode) => {
                if let PathMode::Blend { tolerance, naive_cam } = mode {
                    for t in [tolerance, naive_cam] {
                        if !(t.is_finite() && t >= 0.0) {
                            return Err(PushError::Tolerance { line, tolerance: t });
                        }
                    }
                }
                self.mode = mode;
            }
        }
        self.backward(first_new);
        Ok(())
    }

    /// Ends the program (or a section): the pending line is planned to stop at its end.
    pub fn finish(&mut self) {
        let first_new = self.pieces.len();
        self.flush_pending();
        self.backward(first_new);
    }

    /// Sets the feed override (clamped to `0..=2`) and re-plans the pieces ahead.
    pub fn set_override(&mut self, ovr: f64) {
        self.ovr = if ovr.is_finite() { ovr.clamp(0.0, MAX_OVERRIDE) } else { 1.0 };
        self.replan_all();
    }

    fn push_motion(&mut self, line: u32, block: u64, seg: Segment<N>) -> Result<(), PushError> {
        let end = seg.end();
        if let Some(axis) = end.iter().position(|v| !v.is_finite()) {
            return Err(PushError::NonFinite { line, axis });
        }
        match seg {
            Segment::Line { end, feed, rapid } => {
                let feed = if rapid {
                    f64::INFINITY
                } else if feed.is_finite() && feed > 0.0 {
                    feed
                } else {
                    return Err(PushError::Feed { line, feed });
                };
                self.add_line(end, feed, line, block);
            }
            Segment::Arc { end, centre, plane, direction, extra_turns, feed } => {
                if !(feed.is_finite() && feed > 0.0) {
                    return Err(PushError::Feed { line, feed });
                }
                let spec = ArcSpec { start: self.position, end, centre, plane, direction, extra_turns };
                let points = linearise(&spec, self.cfg.chord_tolerance)
                    .map_err(|reason| PushError::Arc { line, reason })?;
                for p in points {
                    self.add_line(p, feed, line, block);
                }
            }
        }
        Ok(())
    }

    fn push_marker(&mut self, marker: Marker, line: u32, block: u64) {
        if marker.stops() {
            self.flush_pending();
            self.emit_marker(marker, line, block);
        } else if self.pending.is_some() {
            self.pending_markers.push((marker, line, block));
        } else {
            self.emit_marker(marker, line, block);
        }
    }

    fn emit_marker(&mut self, marker: Marker, line: u32, block: u64) {
        let cap = if marker.stops() { 0.0 } else { f64::INFINITY };
        let at = self.position;
        self.emit(Piece {
            geometry: Geometry::Point { at, marker },
            length: 0.0,
            cap,
            feed: f64::INFINITY,
            accel: f64::INFINITY,
            line,
            block,
            s_start: 0.0,
            vx_hard: 0.0,
            stop_after: false,
            vx_soft: 0.0,
        });
    }

    fn emit_pending_markers(&mut self) {
        let markers = std::mem::take(&mut self.pending_markers);
        for (m, line, block) in markers {
            self.emit_marker(m, line, block);
        }
    }

    fn flush_pending(&mut self) {
        if let Some(p) = self.pending.take() {
            self.emit_line(p.start, &p.end, p.feed, p.line, p.block);
        }
        self.emit_pending_markers();
    }

    fn add_line(&mut self, end: [f64; N], feed: f64, line: u32, block: u64) {
        let delta = sub(&end, &self.position);
        let len = norm(&delta);
        if len < MIN_LENGTH {
            return;
        }
        self.segments += 1;
        if let Some(p) = self.pending {
            if self.folds(&p, &end, feed, block) {
                // G64 Q: the pending line now ends here, through the points it folded.
                self.folded.push(p.end);
                let delta = sub(&end, &p.start);
                let full = norm(&delta);
                self.pending = Some(Pending { end, dir: scale(1.0 / full, &delta), full, ..p });
                self.position = end;
                return;
            }
        }
        let dir = scale(1.0 / len, &delta);
        let mut start = self.position;
        if let Some(p) = self.pending.take() {
            start = self.junction(p, &dir, len, feed, line, block);
        }
        self.folded.clear();
        self.pending = Some(Pending { start, end, dir, full: len, feed, line, block, mode: self.mode });
        self.position = end;
    }

    /// Whether a line to `end` folds into the pending line `p` (G64 Q): both feeds of one
    /// rate under one blending mode with a folding tolerance, another move than `p` (an arc's
    /// chords are not folded), no marker between them, and every programmed point of the run
    /// within the tolerance of the line from `p`'s start to `end`, in order along it.
    fn folds(&self, p: &Pending<N>, end: &[f64; N], feed: f64, block: u64) -> bool {
        let PathMode::Blend { naive_cam, .. } = p.mode else { return false };
        if naive_cam <= 0.0
            || self.mode != p.mode
            || p.block == block
            || feed != p.feed
            || feed.is_infinite()
            || !self.pending_markers.is_empty()
            || self.folded.len() >= MAX_FOLDED
        {
            return false;
        }
        let chord = sub(end, &p.start);
        let length = norm(&chord);
        if length < MIN_LENGTH {
            return false;
        }
        let u = scale(1.0 / length, &chord);
        let mut along = 0.0;
        self.folded.iter().chain(std::iter::once(&p.end)).all(|q| {
            let w = sub(q, &p.start);
            let t = dot(&w, &u);
            let ok = t > along && t < length && norm(&add_scaled(&w, -t, &u)) <= naive_cam;
            along = t;
            ok
        })
    }

    /// Plans the corner at the end of `p` towards `dir`; returns where the next line starts.
    fn junction(
        &mut self,
        p: Pending<N>,
        dir: &[f64; N],
        len: f64,
        feed: f64,
        line: u32,
        block: u64,
    ) -> [f64; N] {
        // The chords of one arc join as one move; otherwise the corner takes `p`'s mode.
        let same_move = p.block == block;
        if p.mode == PathMode::ExactStop && !same_move {
            self.emit_line(p.start, &p.end, p.feed, p.line, p.block);
            self.emit_pending_markers();
            self.emit_marker(Marker::ExactStop, p.line, p.block);
            return p.end;
        }
        let cos = dot(&p.dir, dir).clamp(-1.0, 1.0);
        let theta = cos.acos();
        if theta < 1e-7 {
            // Straight on: no corner at all.
            self.emit_line(p.start, &p.end, p.feed, p.line, p.block);
            self.emit_pending_markers();
            return p.end;
        }
        let tol = match p.mode {
            _ if same_move => self.cfg.path_tolerance,
            PathMode::Blend { tolerance, .. } if tolerance > 0.0 => tolerance,
            PathMode::Blend { .. } => self.cfg.path_tolerance,
            PathMode::ExactPath | PathMode::ExactStop => 0.0,
        };
        let half = theta / 2.0;
        if tol <= 0.0 || theta > std::f64::consts::PI - 1e-3 {
            self.emit_line(p.start, &p.end, p.feed, p.line, p.block);
            self.emit_pending_markers();
            self.emit_marker(Marker::ExactStop, p.line, p.block);
            return p.end;
        }
        // Distance of the tangent points from the corner: the blend's midpoint lies
        // R (1/cos(half) - 1) from the corner; with d = R tan(half) the tolerance gives
        // d <= tol sin(half) / (1 - cos(half)).
        let one_minus_cos = 2.0 * (half / 2.0).sin().powi(2);
        let d_tol = tol * half.sin() / one_minus_cos;
        let d = d_tol.min(0.5 * p.full.min(len));
        let radius = d / half.tan();
        let t1 = add_scaled(&p.end, -d, &p.dir);
        let t2 = add_scaled(&p.end, d, dir);
        let normal = add_scaled(dir, -cos, &p.dir);
        let normal = scale(1.0 / norm(&normal), &normal);
        let centre = add_scaled(&t1, radius, &normal);
        let e1 = scale(-1.0, &normal);
        let e2 = p.dir;
        self.emit_line(p.start, &t1, p.feed, p.line, p.block);
        self.emit_arc(centre, e1, e2, radius, 0.0, half, p.feed, p.line, p.block);
        self.position = add_scaled(&add_scaled(&centre, radius * half.cos(), &e1), radius * half.sin(), &e2);
        self.emit_pending_markers();
        self.emit_arc(centre, e1, e2, radius, half, half, feed, line, block);
        t2
    }

    fn emit_line(&mut self, start: [f64; N], end: &[f64; N], feed: f64, line: u32, block: u64) {
        let delta = sub(end, &start);
        let length = norm(&delta);
        self.position = *end;
        if length < 1e-12 {
            return;
        }
        let dir = scale(1.0 / length, &delta);
        let (mut cap, mut accel) = (f64::INFINITY, f64::INFINITY);
        for (u, l) in dir.iter().zip(&self.cfg.axes) {
            let u = u.abs();
            if u > 1e-12 {
                cap = cap.min(l.velocity / u);
                accel = accel.min(l.acceleration / u);
            }
        }
        self.emit(Piece {
            geometry: Geometry::Line { start, dir },
            length,
            cap,
            feed,
            accel,
            line,
            block,
            s_start: 0.0,
            vx_hard: 0.0,
            stop_after: false,
            vx_soft: 0.0,
        });
    }

    #[allow(clippy::too_many_arguments)]
    fn emit_arc(
        &mut self,
        centre: [f64; N],
        e1: [f64; N],
        e2: [f64; N],
        radius: f64,
        phi0: f64,
        sweep: f64,
        feed: f64,
        line: u32,
        block: u64,
    ) {
        let length = radius * sweep;
        if length < 1e-12 {
            return;
        }
        let (mut vmax, mut amax) = (f64::INFINITY, f64::INFINITY);
        for ((a, b), l) in e1.iter().zip(&e2).zip(&self.cfg.axes) {
            let r = a.hypot(*b);
            if r > 1e-12 {
                vmax = vmax.min(l.velocity / r);
                amax = amax.min(l.acceleration / r);
            }
        }
        let k = self.cfg.blend_centripetal_share;
        let cap = vmax.min((k * amax * radius).sqrt());
        let top = if feed.is_finite() { cap.min(feed * MAX_OVERRIDE) } else { cap };
        let accel = (amax - top * top / radius).max((1.0 - k) * amax);
        self.emit(Piece {
            geometry: Geometry::Arc { centre, e1, e2, radius, phi0 },
            length,
            cap,
            feed,
            accel,
            line,
            block,
            s_start: 0.0,
            vx_hard: 0.0,
            stop_after: false,
            vx_soft: 0.0,
        });
    }

    fn emit(&mut self, mut piece: Piece<N>) {
        piece.s_start = self.s_end;
        self.s_end += piece.length;
        self.pieces.push_back(piece);
    }

    /// Backward pass from the end of the buffer down to the executor's piece; pieces at
    /// indices `< first_new` existed before and stop the pass when unchanged.
    fn backward(&mut self, first_new: usize) {
        let ovr = self.ovr;
        let (mut exit_h, mut exit_s) = (0.0_f64, 0.0_f64);
        let last = self.pieces.len();
        for j in (self.cursor..last).rev() {
            let Some(p) = self.pieces.get_mut(j) else { break };
            if j < first_new && j + 1 < last && p.vx_hard == exit_h && p.vx_soft == exit_s {
                break;
            }
            if p.stop_after {
                exit_h = 0.0;
                exit_s = 0.0;
            }
            p.vx_hard = exit_h;
            p.vx_soft = exit_s;
            exit_h = p.entry_limit(exit_h, p.cap);
            exit_s = p.entry_limit(exit_s, p.soft_cap(ovr));
        }
    }

    /// Full backward pass over every piece ahead of the executor.
    pub(crate) fn replan_all(&mut self) {
        // No piece index is below 0, so the pass never stops early.
        self.backward(0);
    }

    /// Tells the planner which piece the executor is in (the look-ahead never changes
    /// pieces before it).
    pub(crate) fn set_cursor(&mut self, cursor: usize) {
        self.cursor = cursor.min(self.pieces.len());
    }

    /// Sets or clears the temporary stop at the end of piece `j` and re-plans.
    pub(crate) fn set_stop_after(&mut self, j: usize, on: bool) {
        if let Some(p) = self.pieces.get_mut(j) {
            p.stop_after = on;
        }
        self.replan_all();
    }

    /// Drops executed pieces beyond the configured history; returns how many were dropped.
    pub(crate) fn trim_history(&mut self) -> usize {
        let excess = self.cursor.saturating_sub(self.cfg.history);
        if excess > 0 {
            self.pieces.drain(..excess);
            self.base += excess as u64;
            self.cursor -= excess;
        }
        excess
    }

    /// The decoder synchronisation point was reached.
    pub(crate) fn sync_reached(&mut self) {
        self.awaiting_sync = None;
    }

    /// Forgets every piece (after a stop); the next item starts at `position`.
    pub(crate) fn clear(&mut self, position: [f64; N]) {
        self.base += self.pieces.len() as u64;
        self.pieces.clear();
        self.cursor = 0;
        self.pending = None;
        self.folded.clear();
        self.pending_markers.clear();
        self.position = position;
        self.s_end = 0.0;
        self.awaiting_sync = None;
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use crate::config::AxisLimits;

    fn cfg() -> Config<3> {
        Config::new([
            AxisLimits { velocity: 200.0, acceleration: 2000.0 },
            AxisLimits { velocity: 150.0, acceleration: 1500.0 },
            AxisLimits { velocity: 50.0, acceleration: 500.0 },
        ])
    }

    fn line(end: [f64; 3], feed: f64) -> PathItem<3> {
        PathItem::Motion(Segment::Line { end, feed, rapid: false })
    }

    #[test]
    fn right_angle_blend_matches_hand_computation() {
        // Corner +X then +Y, tolerance 0.05 (hand computation):
        // d = tol sin45 / (1 - cos45) = 0.05 * 0.707107 / 0.292893 = 0.120711,
        // R = d / tan45 = 0.120711, midpoint to corner R (1/cos45 - 1) = 0.05.
        // Plane basis e1 = (0,-1,0), e2 = (1,0,0): A = min(2000, 1500) = 1500,
        // cap = sqrt(0.8 * 1500 * 0.120711) = 12.0355 mm/s.
        let mut p = Planner::new(cfg(), [0.0; 3]).unwrap();
        p.push(1, line([10.0, 0.0, 0.0], 100.0)).unwrap();
        p.push(2, line([10.0, 10.0, 0.0], 100.0)).unwrap();
        p.finish();
        let pieces: Vec<_> = p.pieces().iter().copied().collect();
        assert_eq!(pieces.len(), 4);
        let d = 0.05 * std::f64::consts::FRAC_1_SQRT_2 / (1.0 - std::f64::consts::FRAC_1_SQRT_2);
        assert!((pieces[0].length - (10.0 - d)).abs() < 1e-12);
        let Geometry::Arc { radius, .. } = pieces[1].geometry else { panic!() };
        assert!((radius - 0.120_710_678).abs() < 1e-8, "{radius}");
        let mid = pieces[1].position(pieces[1].length);
        let dev = ((mid[0] - 10.0).powi(2) + mid[1].powi(2)).sqrt();
        assert!((dev - 0.05).abs() < 1e-12, "{dev}");
        assert!((pieces[1].cap - 12.0355).abs() < 1e-4, "{}", pieces[1].cap);
        assert_eq!(pieces[1].line, 1);
        assert_eq!(pieces[2].line, 2);
        // Line caps: X line: min(200/1) = 200; acceleration 2000.
        assert_eq!(pieces[0].cap, 200.0);
        assert_eq!(pieces[0].accel, 2000.0);
        // Look-ahead: the first line may leave at the blend cap; the last ends at rest.
        assert!((pieces[0].vx_hard - pieces[1].cap).abs() < 1e-12);
        assert_eq!(pieces[3].vx_hard, 0.0);
        // Continuity: arcs start where the lines end, tangent to them.
        let e0 = pieces[0].position(pieces[0].length);
        let s1 = pieces[1].position(0.0);
        assert!((0..3).all(|i| (e0[i] - s1[i]).abs() < 1e-12));
        let t = pieces[1].tangent(0.0);
        assert!((t[0] - 1.0).abs() < 1e-12 && t[1].abs() < 1e-12);
        let t = pieces[2].tangent(pieces[2].length);
        assert!(t[0].abs() < 1e-12 && (t[1] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn reversal_is_an_exact_stop_and_collinear_is_free() {
        let mut p = Planner::new(cfg(), [0.0; 3]).unwrap();
        p.push(1, line([10.0, 0.0, 0.0], 100.0)).unwrap();
        p.push(2, line([20.0, 0.0, 0.0], 100.0)).unwrap();
        p.push(3, line([5.0, 0.0, 0.0], 100.0)).unwrap();
        p.finish();
        let kinds: Vec<_> = p.pieces().iter().map(|q| (q.length, q.marker())).collect();
        assert_eq!(kinds.len(), 4, "{kinds:?}");
        assert_eq!(kinds[2].1, Some(Marker::ExactStop));
        // Collinear junction: the first line may leave at the full speed cap (200, as the
        // second line can stop within 10 mm from sqrt(2 * 2000 * 10) = 200).
        assert!((p.pieces()[0].vx_hard - 200.0).abs() < 1e-9);
        assert_eq!(p.pieces()[1].vx_hard, 0.0);
    }

    #[test]
    fn buffer_capacity_and_bad_items_are_refused() {
        let mut c = cfg();
        c.buffer_capacity = 4;
        let mut p = Planner::new(c, [0.0; 3]).unwrap();
        // The last line stays pending; every corner adds three pieces (trimmed line and two
        // half blends): after three pushes 6 pieces are ahead and the fourth is refused.
        for k in 0..3 {
            p.push(k, line([k as f64 + 1.0, (k % 2) as f64, 0.0], 10.0)).unwrap();
        }
        assert_eq!(p.ahead(), 6);
        assert_eq!(p.push(9, line([0.0; 3], 10.0)), Err(PushError::Full { capacity: 4 }));
        let mut p = Planner::new(cfg(), [0.0; 3]).unwrap();
        assert_eq!(p.push(3, line([1.0, 0.0, 0.0], 0.0)), Err(PushError::Feed { line: 3, feed: 0.0 }));
        assert_eq!(
            p.push(4, line([f64::NAN, 0.0, 0.0], 1.0)),
            Err(PushError::NonFinite { line: 4, axis: 0 })
        );
        assert!(matches!(p.push(5, PathItem::Dwell { seconds: -1.0 }), Err(PushError::Dwell { .. })));
        let mut bad = cfg();
        bad.axes[1].acceleration = 0.0;
        assert!(matches!(Planner::new(bad, [0.0; 3]), Err(ConfigError::Acceleration { axis: 1, .. })));
    }

    fn mode(m: PathMode) -> PathItem<3> {
        PathItem::PathControl(m)
    }

    /// Distance of a blend's midpoint from the right-angle corner at (10, 0).
    fn corner_deviation(p: &Planner<3>) -> f64 {
        let arc = p.pieces().iter().find(|q| matches!(q.geometry, Geometry::Arc { .. })).unwrap();
        let mid = arc.position(arc.length);
        ((mid[0] - 10.0).powi(2) + mid[1].powi(2)).sqrt()
    }

    #[test]
    fn g64_p_sets_the_blend_tolerance_of_the_corners_after_it() {
        for (tolerance, want) in [(0.0, 0.05), (0.01, 0.01), (0.2, 0.2)] {
            let mut p = Planner::new(cfg(), [0.0; 3]).unwrap();
            p.push(1, mode(PathMode::Blend { tolerance, naive_cam: 0.0 })).unwrap();
            p.push(2, line([10.0, 0.0, 0.0], 100.0)).unwrap();
            p.push(3, line([10.0, 10.0, 0.0], 100.0)).unwrap();
            p.finish();
            let dev = corner_deviation(&p);
            assert!((dev - want).abs() < 1e-12, "P {tolerance}: {dev}");
        }
        // The mode of the move before the corner counts: G64 P0.2 after the first line is
        // too late for its corner.
        let mut p = Planner::new(cfg(), [0.0; 3]).unwrap();
        p.push(1, line([10.0, 0.0, 0.0], 100.0)).unwrap();
        p.push(2, mode(PathMode::Blend { tolerance: 0.2, naive_cam: 0.0 })).unwrap();
        p.push(3, line([10.0, 10.0, 0.0], 100.0)).unwrap();
        p.finish();
        assert!((corner_deviation(&p) - 0.05).abs() < 1e-12);
        assert_eq!(
            p.push(4, mode(PathMode::Blend { tolerance: -1.0, naive_cam: 0.0 })),
            Err(PushError::Tolerance { line: 4, tolerance: -1.0 })
        );
    }

    #[test]
    fn g61_stops_at_corners_and_g61_1_at_every_move() {
        let markers = |m: PathMode| {
            let mut p = Planner::new(cfg(), [0.0; 3]).unwrap();
            p.push(1, mode(m)).unwrap();
            p.push(2, line([10.0, 0.0, 0.0], 100.0)).unwrap();
            p.push(3, line([20.0, 0.0, 0.0], 100.0)).unwrap(); // collinear
            p.push(4, line([20.0, 10.0, 0.0], 100.0)).unwrap(); // corner
                                                                // An arc: its chords are one move.
            p.push(
                5,
                PathItem::Motion(Segment::Arc {
                    end: [20.0, 30.0, 0.0],
                    centre: [20.0, 20.0],
                    plane: crate::item::Plane::Xy,
                    direction: crate::item::ArcDirection::CounterClockwise,
                    extra_turns: 0,
                    feed: 100.0,
                }),
            )
            .unwrap();
            p.finish();
            let stops: Vec<u32> =
                p.pieces().iter().filter(|q| q.marker() == Some(Marker::ExactStop)).map(|q| q.line).collect();
            let arcs = p.pieces().iter().filter(|q| matches!(q.geometry, Geometry::Arc { .. })).count();
            (stops, arcs)
        };
        let (stops, blends) = markers(PathMode::default());
        assert!(stops.is_empty() && blends > 0, "G64: {stops:?}");
        let (stops, _) = markers(PathMode::ExactPath);
        // G61: a stop at the corner (3 -> 4) and where the arc leaves the line (4 -> 5);
        // none on the collinear join.
        assert_eq!(stops, vec![3, 4], "G61");
        let (stops, blends) = markers(PathMode::ExactStop);
        assert_eq!(stops, vec![2, 3, 4], "G61.1: after every move, not between an arc's chords");
        assert!(blends > 0, "the arc's chords still join");
    }

    #[test]
    fn g64_q_folds_short_cam_segments_within_its_tolerance() {
        // A CAM line broken into 100 segments of 0.1 mm that wobble 0.002 mm off the line.
        let run = |naive_cam: f64, feed2: f64| {
            let mut p = Planner::new(cfg(), [0.0; 3]).unwrap();
            p.push(0, mode(PathMode::Blend { tolerance: 0.0, naive_cam })).unwrap();
            for k in 1..=100u32 {
                let y = if k % 2 == 0 { 0.0 } else { 0.002 };
                let feed = if k > 50 { feed2 } else { 100.0 };
                p.push(k, line([f64::from(k) * 0.1, y, 0.0], feed)).unwrap();
            }
            p.finish();
            // Pieces of the path (lines and blends).
            p.pieces().iter().filter(|q| q.marker().is_none()).count()
        };
        let unfolded = run(0.0, 100.0);
        let folded = run(0.01, 100.0);
        // At most 64 points per folded line: 100 points make 2 lines and the blend between.
        assert!(unfolded >= 100 && folded <= 4, "Q 0: {unfolded} pieces, Q 0.01: {folded}");
        assert!(run(0.001, 100.0) >= 100, "a wobble beyond Q is not folded");
        let two_feeds = run(0.01, 50.0);
        assert!((2..=4).contains(&two_feeds), "two feeds are two lines: {two_feeds}");
    }
}
