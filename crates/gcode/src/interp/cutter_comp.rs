//! Cutter radius compensation (G40, G41/G42 D tool, G41.1/G42.1 D diameter) in the XY
//! and XZ planes, after LinuxCNC 2.9's algorithm (`interp_convert.cc`, `interp_queue.cc`):
//! each compensated move is held back (queued) until the next one is known, so that a
//! concave corner can move its end point back to where the tool touches both sides; a
//! convex corner gets an arc about the programmed corner (a straight traverse to the arc's
//! end for G0). Calls LinuxCNC queues with the moves (feed rate, dwell, spindle, coolant,
//! comments) wait in the same queue; others pass it.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use super::motion::{arc_length, straight_length};
use super::Interpreter;
use crate::block::{g, Block};
use crate::canon::{ArcFeed, Canon, CanonCall, MachineMove, Plane, Pose};
use crate::error::{CompError, ErrorKind, KResult};

/// LinuxCNC's `TOLERANCE_CONCAVE_CORNER` (radians).
const SMALL: f64 = 0.05;

/// LinuxCNC's `TOLERANCE_EQUAL` (2.9).
const TOLERANCE_EQUAL: f64 = 1e-6;

/// The compensation side.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(super) enum Side {
    /// G40.
    #[default]
    Off,
    /// G41 / G41.1: the tool left of the path.
    Left,
    /// G42 / G42.1: the tool right of the path.
    Right,
}

/// A call held in the compensation queue; for moves, the data LinuxCNC keeps to move their
/// end point later.
#[derive(Debug, Clone)]
pub(super) struct Pending {
    call: CanonCall,
    /// Straight moves: the programmed direction (not normalised).
    dir: (f64, f64),
    /// Arcs: the programmed sweep (radians, signed; 0 for an inserted corner arc).
    sweep: f64,
    /// Feed moves: the rate in mm/min.
    feed: f64,
    /// A place holder for one of LinuxCNC's "interpreter: ..." comments (not sent: it only
    /// counts in `qc_scale`).
    phantom: bool,
}

/// Cutter compensation state.
#[derive(Debug, Clone, Default)]
pub(super) struct CompState {
    pub(super) side: Side,
    radius: f64,
    /// The tool's orientation (lathe tools 1-8; 0 or 9 for a mill).
    orientation: u8,
    first_move: bool,
    /// The compensated tool position (program units, X Y Z).
    cur: [f64; 3],
    /// Calls held back until the next move is known.
    pub(super) queue: Vec<Pending>,
    /// LinuxCNC's `endpoint`: where the queued move starts (`None`: not valid).
    endpoint: Option<(f64, f64)>,
    /// After G40 the next move must be straight.
    pub(super) arc_not_allowed: bool,
    /// Where the tool is after the last move sent (program units).
    sent: Pose,
    /// The first call of the last queue sent, if an arc (see `stale_front_arc`).
    last_front: Option<ArcFeed>,
    /// After G40: the tool's machine position, the start of the next move.
    pub(super) exit_start: Option<Pose>,
}

impl CompState {
    /// G40 in force.
    pub(super) fn new() -> Self {
        Self::default()
    }

    /// `#<_ccomp>` as LinuxCNC sets it: 400 (off), 410 (left), 420 (right), G41.1/G42.1
    /// included.
    pub(super) fn ccomp(&self) -> f64 {
        match self.side {
            Side::Off => 400.0,
            Side::Left => 410.0,
            Side::Right => 420.0,
        }
    }

    /// Compensation is on with a non-zero radius (moves are offset).
    pub(super) fn active(&self) -> bool {
        self.side != Side::Off && self.radius > 0.0
    }

    /// The first queued call, if it is an arc.
    fn front_arc(&self) -> Option<ArcFeed> {
        match self.queue.first().map(|p| &p.call.canon) {
            Some(Canon::ArcFeed(a)) => Some(*a),
            _ => None,
        }
    }

    /// As [`CompState::front_arc`], but when the queue is empty (after M0/M1) LinuxCNC
    /// reads its vector's first slot anyway: the first call of the last queue sent.
    fn stale_front_arc(&self) -> Option<ArcFeed> {
        if self.queue.is_empty() {
            self.last_front
        } else {
            self.front_arc()
        }
    }

    /// Holds a non-motion call behind the queued moves.
    pub(super) fn hold(&mut self, call: CanonCall) {
        self.queue.push(Pending { call, dir: (0.0, 0.0), sweep: 0.0, feed: 0.0, phantom: false });
    }

    /// Where LinuxCNC queues one of its own "interpreter: ..." comments (which this
    /// interpreter does not send), a place holder, so that `qc_scale`'s count is LinuxCNC's.
    pub(super) fn phantom(&mut self) {
        if !self.queue.is_empty() {
            let call =
                CanonCall { line: 0, n: None, canon: Canon::Comment { text: String::new() }, machine: None };
            self.queue.push(Pending { call, dir: (0.0, 0.0), sweep: 0.0, feed: 0.0, phantom: true });
        }
    }

    /// Compensation is on (G41/G42), whatever the radius.
    pub(super) fn on(&self) -> bool {
        self.side != Side::Off
    }
}

/// Whether LinuxCNC queues `c` behind a held-back compensated move (its `enqueue_*` calls).
pub(super) fn is_queued(c: &Canon) -> bool {
    matches!(
        c,
        Canon::SetFeedRate { .. }
            | Canon::Dwell { .. }
            | Canon::SetFeedMode { .. }
            | Canon::MistOn
            | Canon::MistOff
            | Canon::FloodOn
            | Canon::FloodOff
            | Canon::StartSpindleClockwise
            | Canon::StartSpindleCounterclockwise
            | Canon::StopSpindleTurning
            | Canon::SetSpindleMode { .. }
            | Canon::SetSpindleSpeed { .. }
            | Canon::Comment { .. }
    )
}

/// LinuxCNC's `TOOL_INSIDE_ARC`.
fn tool_inside_arc(side: Side, turn: i32) -> bool {
    (side == Side::Left && turn > 0) || (side == Side::Right && turn < 0)
}

/// LinuxCNC's `find_turn`: the signed sweep (radians) from `p1` to `p2` about `c`.
fn find_turn(p1: (f64, f64), c: (f64, f64), turn: i32, p2: (f64, f64)) -> f64 {
    if turn == 0 {
        return 0.0;
    }
    let mut alpha = (p1.1 - c.1).atan2(p1.0 - c.0);
    let mut beta = (p2.1 - c.1).atan2(p2.0 - c.0);
    if turn > 0 {
        if beta <= alpha {
            beta += TAU;
        }
        beta - alpha + f64::from(turn - 1) * TAU
    } else {
        if alpha <= beta {
            alpha += TAU;
        }
        beta - alpha + f64::from(turn + 1) * TAU
    }
}

fn get(p: &Pose, k: usize) -> f64 {
    p.get(k).copied().unwrap_or(0.0)
}

/// Plane indices: first, second coordinate and the axis (X, Y, Z under G17; Z, X, Y under
/// G18), as `Plane::axes` gives them.
type Axes = (usize, usize, usize);

/// A pose's coordinates in the plane (first, second, axis).
fn plane3(axes: Axes, p: &Pose) -> (f64, f64, f64) {
    (get(p, axes.0), get(p, axes.1), get(p, axes.2))
}

/// A pose with its plane coordinates (first, second, axis) replaced.
fn with_plane(axes: Axes, p: &Pose, x: f64, y: f64, z: f64) -> Pose {
    let mut q = *p;
    for (k, v) in [(axes.0, x), (axes.1, y), (axes.2, z)] {
        if let Some(s) = q.get_mut(k) {
            *s = v;
        }
    }
    q
}

/// A compensation error.
fn cc(col: u32, e: CompError) -> (u32, ErrorKind) {
    (col, ErrorKind::CutterComp(e))
}

impl Interpreter<'_> {
    /// G40, G41, G42, G41.1 or G42.1 (group 7), in LinuxCNC's order (after units).
    pub(super) fn cutter_comp_code(&mut self, code: u16, b: &Block, col: u32) -> KResult<()> {
        if code == g::G40 {
            self.cutter_comp_off(col)?;
            return Ok(());
        }
        if self.plane == Plane::Yz {
            return Err(cc(col, CompError::PlaneNotXyOrXz));
        }
        if self.comp.on() {
            return Err(cc(col, CompError::AlreadyOn));
        }
        let name = match code {
            g::G41 => "G41",
            g::G42 => "G42",
            g::G41_1 => "G41.1",
            _ => "G42.1",
        };
        let (radius, orientation) = if code == g::G41_1 || code == g::G42_1 {
            let d = b.d.ok_or((col, ErrorKind::CompNoD(name)))?;
            let orientation = match b.l {
                None => 0,
                Some(_) if self.plane != Plane::Xz => return Err((col, ErrorKind::CompLWordNotG18(name))),
                Some(l) => {
                    let r = crate::expr::round(l);
                    if !(0.0..=9.0).contains(&r) {
                        return Err(cc(col, CompError::InvalidOrientation));
                    }
                    // 0..=9.
                    r as u8
                }
            };
            (d / 2.0, orientation)
        } else {
            let index = match b.d {
                None => 0,
                Some(d) => {
                    let r = crate::expr::round(d);
                    if (d - r).abs() > 0.0001 || r < 0.0 || r > f64::from(u32::MAX) {
                        return Err((col, ErrorKind::CompDNotWhole(name)));
                    }
                    // Whole and in range.
                    self.tool_index(r as u32, col)?
                }
            };
            let index = if index == 0 { self.tool.current.1 } else { index };
            let (diameter_mm, orientation) = index
                .checked_sub(1)
                .and_then(|i| self.config.tools.get(i))
                .map_or((0.0, 0), |t| (t.diameter, t.orientation));
            if self.plane != Plane::Xz && !matches!(orientation, 0 | 9) {
                return Err((col, ErrorKind::CompLatheToolNotG18(name)));
            }
            (diameter_mm / self.units.mm_per_unit() / 2.0, orientation)
        };
        let left = code == g::G41 || code == g::G41_1;
        // A negative radius swaps the side.
        let side = if (radius < 0.0) == left { Side::Right } else { Side::Left };
        self.comp.side = side;
        self.comp.radius = radius.abs();
        self.comp.orientation = orientation;
        self.comp.first_move = true;
        let (x, y, z) = plane3(self.plane.axes(), &self.pos);
        self.comp.cur = [x, y, z];
        self.comp.sent = self.pos;
        self.comp.endpoint = None;
        Ok(())
    }

    /// G40 (and the program end): sends what is queued; the next move starts from the
    /// tool's compensated position.
    pub(super) fn cutter_comp_off(&mut self, col: u32) -> KResult<()> {
        if self.comp.active() && !self.comp.first_move {
            let [cx, cy, _] = self.comp.cur;
            self.move_endpoint_and_flush(cx, cy, col)?;
            self.comp.exit_start = Some(self.to_machine(&self.comp.sent));
            self.comp.arc_not_allowed = true;
        }
        self.comp.side = Side::Off;
        self.comp.first_move = true;
        Ok(())
    }

    /// The position LinuxCNC reports (#5420-, `#<_x>`): the compensated tool's when
    /// compensation is active, else the programmed point.
    pub(super) fn comp_tool_position(&self) -> Pose {
        if self.comp.active() {
            let [x, y, z] = self.comp.cur;
            with_plane(self.plane.axes(), &self.pos, x, y, z)
        } else {
            self.pos
        }
    }

    /// Before M0, M1, M2 or M30: the held-back moves end where the tool is, and are sent.
    pub(super) fn comp_flush_for_stop(&mut self, col: u32) -> KResult<()> {
        let [cx, cy, _] = self.comp.cur;
        self.move_endpoint_and_flush(cx, cy, col)?;
        self.dequeue_canons();
        Ok(())
    }

    /// G20/G21 while moves are held: LinuxCNC's `qc_scale` (which scales its `endpoint`
    /// once per queued call) and the radius, the tool and the sent positions by `factor`.
    pub(super) fn comp_scale(&mut self, factor: f64) {
        let c = &mut self.comp;
        for v in c.cur.iter_mut() {
            *v *= factor;
        }
        for v in c.sent.iter_mut().take(3) {
            *v *= factor;
        }
        c.radius *= factor;
        if c.queue.is_empty() {
            return;
        }
        if let Some((x, y)) = c.endpoint.as_mut() {
            for _ in 0..c.queue.len() {
                *x *= factor;
                *y *= factor;
            }
        }
        for p in &mut c.queue {
            match &mut p.call.canon {
                Canon::StraightFeed { end } | Canon::StraightTraverse { end } => {
                    for v in end.iter_mut().take(3) {
                        *v *= factor;
                    }
                }
                Canon::ArcFeed(a) => {
                    for v in [
                        &mut a.first_end,
                        &mut a.second_end,
                        &mut a.axis_end,
                        &mut a.first_centre,
                        &mut a.second_centre,
                    ] {
                        *v *= factor;
                    }
                }
                _ => {}
            }
        }
    }

    /// Sends the queue (LinuxCNC's `dequeue_canons`).
    pub(super) fn dequeue_canons(&mut self) {
        self.comp.endpoint = None;
        let axes = self.plane.axes();
        if !self.comp.queue.is_empty() {
            self.comp.last_front = self.comp.front_arc();
        }
        // Taken and given back: the queue keeps its allocation.
        let mut queue = std::mem::take(&mut self.comp.queue);
        let (dx, dz) = self.lathe_origin_shift();
        for p in queue.drain(..) {
            if p.phantom {
                continue;
            }
            let mut call = p.call;
            if dx != 0.0 || dz != 0.0 {
                match &mut call.canon {
                    Canon::StraightTraverse { end } | Canon::StraightFeed { end } => {
                        if let Some(v) = end.get_mut(0) {
                            *v += dx;
                        }
                        if let Some(v) = end.get_mut(2) {
                            *v += dz;
                        }
                    }
                    // G18: the first coordinate is Z, the second X.
                    Canon::ArcFeed(a) => {
                        a.first_end += dz;
                        a.first_centre += dz;
                        a.second_end += dx;
                        a.second_centre += dx;
                    }
                    _ => {}
                }
            }
            let start = self.comp.sent;
            let ms = self.to_machine(&start);
            match &call.canon {
                Canon::StraightTraverse { end } | Canon::StraightFeed { end } => {
                    let me = self.to_machine(end);
                    call.machine = Some(if matches!(call.canon, Canon::StraightTraverse { .. }) {
                        MachineMove::Traverse { start: ms, end: me }
                    } else {
                        MachineMove::Feed { start: ms, end: me, feed: p.feed }
                    });
                    self.comp.sent = *end;
                }
                Canon::ArcFeed(a) => {
                    let end = with_plane(
                        axes,
                        &[0.0, 0.0, 0.0, a.a, a.b, a.c],
                        a.first_end,
                        a.second_end,
                        a.axis_end,
                    );
                    let me = self.to_machine(&end);
                    let mc = self.to_machine(&with_plane(
                        axes,
                        &start,
                        a.first_centre,
                        a.second_centre,
                        get(&start, axes.2),
                    ));
                    call.machine = Some(MachineMove::Arc {
                        start: ms,
                        end: me,
                        centre: [get(&mc, 0), get(&mc, 1), get(&mc, 2)],
                        plane: self.plane,
                        rotation: a.rotation,
                        feed: p.feed,
                    });
                    self.comp.sent = end;
                }
                _ => {}
            }
            self.out.push_back(call);
        }
        self.comp.queue = queue;
    }

    /// LinuxCNC's `latheorigin_x` / `latheorigin_z`: under G18 a lathe tool (orientation
    /// 1-8) is controlled at its nose radius's centre, so the moves sent are shifted by a
    /// radius in X and Z towards the tool's origin (X, Z).
    fn lathe_origin_shift(&self) -> (f64, f64) {
        if self.plane != Plane::Xz {
            return (0.0, 0.0);
        }
        let (o, r) = (self.comp.orientation, self.comp.radius);
        let dx = match o {
            1 | 2 | 6 => -r,
            3 | 4 | 8 => r,
            _ => 0.0,
        };
        let dz = match o {
            2 | 3 | 7 => -r,
            1 | 4 | 5 => r,
            _ => 0.0,
        };
        (dx, dz)
    }

    /// LinuxCNC's `move_endpoint_and_flush`: every queued move now ends at (x, y); then
    /// the queue is sent.
    fn move_endpoint_and_flush(&mut self, x: f64, y: f64, col: u32) -> KResult<()> {
        if self.comp.queue.is_empty() {
            return Ok(());
        }
        let ep = self.comp.endpoint;
        // LinuxCNC 2.9's allowance for an arc made longer by the new end point (radians).
        let sweep_slack = match self.units {
            crate::canon::Units::Mm => 0.0254,
            crate::canon::Units::Inch => 0.001,
        };
        let (f, s) = (self.plane.axes().0, self.plane.axes().1);
        let (ex, ey) = ep.unwrap_or((0.0, 0.0));
        for p in &mut self.comp.queue {
            match &mut p.call.canon {
                Canon::ArcFeed(a) => {
                    let c = (a.first_centre, a.second_centre);
                    let r1 = (a.first_end - c.0).hypot(a.second_end - c.1);
                    let r2 = (x - c.0).hypot(y - c.1);
                    let l2 = find_turn((ex, ey), c, a.rotation, (x, y));
                    if (r1 - r2).abs() > 0.01 {
                        return Err(cc(col, CompError::InvalidArc));
                    }
                    if p.sweep != 0.0 && ep.is_some() && l2.abs() > p.sweep.abs() + sweep_slack {
                        return Err(cc(col, CompError::ArcGouge));
                    }
                    a.first_end = x;
                    a.second_end = y;
                }
                Canon::StraightTraverse { end } | Canon::StraightFeed { end } => {
                    let dot = p.dir.0 * (x - ex) + p.dir.1 * (y - ey);
                    if ep.is_some() && dot < 0.0 {
                        return Err(cc(
                            col,
                            if matches!(p.call.canon, Canon::StraightTraverse { .. }) {
                                CompError::StraightTraverseGouge
                            } else {
                                CompError::StraightFeedGouge
                            },
                        ));
                    }
                    if let Some(v) = end.get_mut(f) {
                        *v = x;
                    }
                    if let Some(v) = end.get_mut(s) {
                        *v = y;
                    }
                }
                _ => {}
            }
        }
        self.dequeue_canons();
        self.comp.endpoint = Some((x, y));
        Ok(())
    }

    fn enqueue(&mut self, canon: Canon, dir: (f64, f64), sweep: f64, feed: f64) {
        let call = CanonCall { line: self.cur_line, n: self.cur_n, canon, machine: None };
        self.comp.queue.push(Pending { call, dir, sweep, feed, phantom: false });
    }

    /// A compensated G0/G1 from the programmed point `self.pos` to the programmed `end`.
    pub(super) fn comp_straight(&mut self, rapid: bool, b: &Block, end: Pose, col: u32) -> KResult<()> {
        // Under G93 the rate is the programmed move's (LinuxCNC's), sent behind the held move.
        let feed = if rapid { 0.0 } else { self.move_feed(straight_length(&self.pos, &end), b, 1, col)? };
        let r = self.comp.radius;
        let left = self.comp.side == Side::Left;
        let [cx, cy, cz] = self.comp.cur;
        let axes = self.plane.axes();
        let (px, py, pz) = plane3(axes, &end);
        let make = |x: f64, y: f64, z: f64| {
            let e = with_plane(axes, &end, x, y, z);
            if rapid {
                Canon::StraightTraverse { end: e }
            } else {
                Canon::StraightFeed { end: e }
            }
        };
        if self.comp.first_move {
            if (px - cx).hypot(py - cy) <= r {
                return Err(cc(col, CompError::EntryTooShort));
            }
            let alpha = (py - cy).atan2(px - cx) + if left { FRAC_PI_2 } else { -FRAC_PI_2 };
            let (ex, ey) = (px + r * alpha.cos(), py + r * alpha.sin());
            self.comp.endpoint = Some((cx, cy));
            self.enqueue(make(ex, ey, pz), (alpha.cos(), alpha.sin()), 0.0, feed);
            self.comp.first_move = false;
            self.comp.cur = [ex, ey, pz];
            return Ok(());
        }
        let (opx, opy, _) = plane3(axes, &self.pos);
        if px == opx && py == opy {
            self.enqueue(make(cx, cy, pz), (0.0, 0.0), 0.0, feed);
            self.comp.cur = [cx, cy, pz];
            return Ok(());
        }
        let mut theta = (cy - opy).atan2(cx - opx);
        let mut alpha = (py - opy).atan2(px - opx);
        let (beta, gamma) = if left {
            if theta < alpha {
                theta += TAU;
            }
            (theta - alpha - FRAC_PI_2, FRAC_PI_2)
        } else {
            if alpha < theta {
                alpha += TAU;
            }
            (alpha - theta - FRAC_PI_2, -FRAC_PI_2)
        };
        let (ex, ey) = (px + r * (alpha + gamma).cos(), py + r * (alpha + gamma).sin());
        let (mx, my) = (opx + r * (alpha + gamma).cos(), opy + r * (alpha + gamma).sin());
        let front_arc = self.comp.front_arc();
        let concave = !(-SMALL..=PI + SMALL).contains(&beta)
            || (beta > PI - SMALL
                && front_arc.is_some_and(|a| (!left && a.rotation > 0) || (left && a.rotation < 0)));
        if !concave && beta > SMALL {
            // Convex corner: an arc about the programmed corner (G0: a straight traverse).
            self.move_endpoint_and_flush(cx, cy, col)?;
            let corner = if rapid {
                Canon::StraightTraverse { end: with_plane(axes, &end, mx, my, cz) }
            } else {
                corner_arc((mx, my), (opx, opy), left, cz, &end)
            };
            self.enqueue(corner, (0.0, 0.0), 0.0, feed);
            self.dequeue_canons();
            self.comp.endpoint = Some((mx, my));
        } else if concave {
            if let Some(prev) = self.comp.stale_front_arc() {
                self.arc_to_line_corner(&prev, (opx, opy), (px, py), col)?;
            } else {
                let half = (beta + PI) / 2.0;
                if half == 0.0 {
                    return Err(cc(col, CompError::ZeroDegreeCorner));
                }
                let retreat = r / half.tan();
                let (qx, qy) = (cx + retreat * (theta + gamma).cos(), cy + retreat * (theta + gamma).sin());
                self.move_endpoint_and_flush(qx, qy, col)?;
            }
        } else {
            // Collinear, or a tangent arc to line.
            self.dequeue_canons();
            self.comp.endpoint = Some((cx, cy));
        }
        self.enqueue(make(ex, ey, pz), (px - opx, py - opy), 0.0, feed);
        self.comp.cur = [ex, ey, pz];
        Ok(())
    }

    /// A concave corner from the queued (compensated) arc `prev` to a line from `op` to `p`.
    fn arc_to_line_corner(&mut self, prev: &ArcFeed, op: (f64, f64), p: (f64, f64), col: u32) -> KResult<()> {
        let r = self.comp.radius;
        let side = self.comp.side;
        let oldrad = (prev.second_centre - prev.second_end).hypot(prev.first_centre - prev.first_end);
        let base_dir = (p.1 - op.1).atan2(p.0 - op.0);
        let theta = if prev.rotation > 0 { base_dir + FRAC_PI_2 } else { base_dir - FRAC_PI_2 };
        let phi = (prev.second_centre - op.1).atan2(prev.first_centre - op.0);
        let inside = tool_inside_arc(side, prev.rotation);
        let oldrad_uncomp = if inside { oldrad + r } else { oldrad - r };
        let d = oldrad_uncomp * (theta - phi).cos();
        let msg = CompError::ArcToStraightGouge;
        let angle = if inside {
            let l = (d - r) / oldrad;
            if !(-1.0..=1.0).contains(&l) {
                return Err(cc(col, msg));
            }
            if prev.rotation > 0 {
                -l.acos() + theta + PI
            } else {
                l.acos() + theta + PI
            }
        } else {
            let l = (d + r) / oldrad;
            if !(-1.0..=1.0).contains(&l) {
                return Err(cc(col, msg));
            }
            if prev.rotation > 0 {
                l.acos() + theta + PI
            } else {
                -l.acos() + theta + PI
            }
        };
        let mx = prev.first_centre + oldrad * angle.cos();
        let my = prev.second_centre + oldrad * angle.sin();
        self.move_endpoint_and_flush(mx, my, col)
    }

    /// The first compensated move is an arc (LinuxCNC's `convert_arc_comp1`): the tool
    /// follows an arc through the offset end point that is tangent to the tool at its start.
    fn comp_entry_arc(
        &mut self,
        end: Pose,
        centre: (f64, f64),
        turn: i32,
        feed: f64,
        col: u32,
    ) -> KResult<()> {
        let r = self.comp.radius;
        let side = self.comp.side;
        let [cx, cy, cz] = self.comp.cur;
        let axes = self.plane.axes();
        let (ex, ey, ez) = plane3(axes, &end);
        if (ex - cx).hypot(ey - cy) <= r {
            return Err(cc(col, CompError::EntryArcTooShort));
        }
        let inside = tool_inside_arc(side, turn);
        if inside && (centre.0 - cx).hypot(centre.1 - cy) <= r {
            return Err(cc(col, CompError::ArcTooSmall));
        }
        let gamma =
            if inside { (centre.1 - ey).atan2(centre.0 - ex) } else { (ey - centre.1).atan2(ex - centre.0) };
        let (nx, ny) = (ex + r * gamma.cos(), ey + r * gamma.sin());
        // The new centre: on the line from the new end towards the programmed centre, as far
        // from the start as from the new end.
        let b_len = (cy - ny).hypot(cx - nx) / 2.0;
        let ab_ang = (centre.1 - ny).atan2(centre.0 - nx);
        let a_ang = (cy - ny).atan2(cx - nx) - ab_ang;
        if a_ang.cos().abs() < TOLERANCE_EQUAL {
            return Err(cc(col, CompError::ArcTooSmall));
        }
        let c_len = b_len / a_ang.cos();
        let (ncx, ncy) = (nx + c_len * ab_ang.cos(), ny + c_len * ab_ang.sin());
        let sweep = find_turn((cx, cy), (ncx, ncy), turn, (nx, ny));
        if !matches!(self.comp.orientation, 0 | 9) {
            // LinuxCNC moves a lathe tool's origin first (a move to where it is).
            let at = with_plane(axes, &end, cx, cy, cz);
            self.enqueue(Canon::StraightFeed { end: at }, (0.0, 0.0), 0.0, feed);
            self.comp.endpoint = Some((cx, cy));
        }
        let arc = Canon::ArcFeed(ArcFeed {
            first_end: nx,
            second_end: ny,
            first_centre: ncx,
            second_centre: ncy,
            rotation: turn,
            axis_end: ez,
            a: get(&end, 3),
            b: get(&end, 4),
            c: get(&end, 5),
        });
        self.enqueue(arc, (0.0, 0.0), sweep, feed);
        self.comp.first_move = false;
        self.comp.cur = [nx, ny, ez];
        Ok(())
    }

    /// A compensated G2/G3 from the programmed point `self.pos`: `centre` and `turn` are the
    /// programmed arc's, `end` its programmed end.
    pub(super) fn comp_arc(
        &mut self,
        b: &Block,
        end: Pose,
        centre: (f64, f64),
        turn: i32,
        col: u32,
    ) -> KResult<()> {
        let cw = turn < 0;
        let (st, en) = (plane3(self.plane.axes(), &self.pos), plane3(self.plane.axes(), &end));
        let length = arc_length((st.0, st.1), (en.0, en.1), centre, turn, en.2 - st.2);
        let feed = self.move_feed(length, b, if cw { 2 } else { 3 }, col)?;
        if self.comp.first_move {
            return self.comp_entry_arc(end, centre, turn, feed, col);
        }
        let r = self.comp.radius;
        let side = self.comp.side;
        let left = side == Side::Left;
        let [cx, cy, cz] = self.comp.cur;
        let axes = self.plane.axes();
        let (opx, opy, _) = plane3(axes, &self.pos);
        let (ex, ey, ez) = plane3(axes, &end);
        let (ccx, ccy) = centre;
        let arc_radius = (ccx - ex).hypot(ccy - ey);
        let mut theta = (cy - opy).atan2(cx - opx);
        theta = if left { theta - FRAC_PI_2 } else { theta + FRAC_PI_2 };
        let mut delta = (ccy - opy).atan2(ccx - opx);
        let alpha = if cw { delta + FRAC_PI_2 } else { delta - FRAC_PI_2 };
        let mut beta = if left { theta - alpha } else { alpha - theta };
        if beta > 1.5 * PI {
            beta -= TAU;
        } else if beta < -FRAC_PI_2 {
            beta += TAU;
        }
        let inside = tool_inside_arc(side, turn);
        let gamma = if (left && !cw) || (!left && cw) {
            if arc_radius <= r {
                return Err(cc(col, CompError::ArcTooSmall));
            }
            (ccy - ey).atan2(ccx - ex)
        } else {
            delta += PI;
            (ey - ccy).atan2(ex - ccx)
        };
        let (nx, ny) = (ex + r * gamma.cos(), ey + r * gamma.sin());
        let main = Canon::ArcFeed(ArcFeed {
            first_end: nx,
            second_end: ny,
            first_centre: ccx,
            second_centre: ccy,
            rotation: turn,
            axis_end: ez,
            a: get(&end, 3),
            b: get(&end, 4),
            c: get(&end, 5),
        });
        let sweep = find_turn((opx, opy), centre, turn, (ex, ey));
        if !(-SMALL..=PI + SMALL).contains(&beta) || ((beta - PI).abs() < SMALL && !inside) {
            // Concave.
            let (mx, my) = if let Some(prev) = self.comp.stale_front_arc() {
                let oldrad = (prev.second_centre - prev.second_end).hypot(prev.first_centre - prev.first_end);
                let newrad = if inside { arc_radius - r } else { arc_radius + r };
                let arc_cc = (prev.second_centre - ccy).hypot(prev.first_centre - ccx);
                if oldrad == 0.0 || arc_cc == 0.0 {
                    return Err(cc(col, CompError::ArcToArcSameCentre));
                }
                let a = (oldrad * oldrad + arc_cc * arc_cc - newrad * newrad) / (2.0 * oldrad * arc_cc);
                if !(-1.0..=1.0).contains(&a) {
                    return Err(cc(col, CompError::ArcToArcGouge));
                }
                let pullback = a.acos();
                let cc_dir = (ccy - prev.second_centre).atan2(ccx - prev.first_centre);
                let dir = if tool_inside_arc(side, prev.rotation) == (turn > 0) {
                    cc_dir + pullback
                } else {
                    cc_dir - pullback
                };
                (prev.first_centre + oldrad * dir.cos(), prev.second_centre + oldrad * dir.sin())
            } else {
                let cyv = arc_radius * (beta - FRAC_PI_2).sin();
                let msg = CompError::ArcGouge;
                let (dist, angle) = if inside {
                    let dist = arc_radius - r;
                    let l = (cyv + r) / dist;
                    if !(-1.0..=1.0).contains(&l) {
                        return Err(cc(col, msg));
                    }
                    (dist, if turn > 0 { theta + l.asin() } else { theta - l.asin() })
                } else {
                    let dist = arc_radius + r;
                    let l = (cyv - r) / dist;
                    if !(-1.0..=1.0).contains(&l) {
                        return Err(cc(col, msg));
                    }
                    (dist, if turn > 0 { theta + PI - l.asin() } else { theta + PI + l.asin() })
                };
                (ccx + dist * angle.cos(), ccy + dist * angle.sin())
            };
            self.move_endpoint_and_flush(mx, my, col)?;
            self.enqueue(main, (0.0, 0.0), sweep, feed);
        } else if beta > SMALL {
            // Convex: an arc about the programmed corner first.
            let (mx, my) = (opx + r * delta.cos(), opy + r * delta.sin());
            self.dequeue_canons();
            self.enqueue(corner_arc((mx, my), (opx, opy), left, cz, &end), (0.0, 0.0), 0.0, feed);
            self.dequeue_canons();
            self.comp.endpoint = Some((mx, my));
            self.enqueue(main, (0.0, 0.0), sweep, feed);
        } else {
            self.dequeue_canons();
            self.comp.endpoint = Some((cx, cy));
            self.enqueue(main, (0.0, 0.0), sweep, feed);
        }
        self.comp.cur = [nx, ny, ez];
        Ok(())
    }
}

/// The arc a convex corner gets: about the programmed corner `centre` to `end_xy` (the
/// compensated start of the next move), clockwise for G41, counter-clockwise for G42, the
/// third axis and A, B, C at `axis_end` and `end`'s.
fn corner_arc(end_xy: (f64, f64), centre: (f64, f64), left: bool, axis_end: f64, end: &Pose) -> Canon {
    Canon::ArcFeed(ArcFeed {
        first_end: end_xy.0,
        second_end: end_xy.1,
        first_centre: centre.0,
        second_centre: centre.1,
        rotation: if left { -1 } else { 1 },
        axis_end,
        a: get(end, 3),
        b: get(end, 4),
        c: get(end, 5),
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic)]

    use crate::canon::{Canon, MachineMove, Pose};
    use crate::{interpret, CanonCall};

    fn machine_moves(calls: &[CanonCall]) -> Vec<(Pose, Pose)> {
        calls
            .iter()
            .filter_map(|c| match c.machine {
                Some(
                    MachineMove::Traverse { start, end }
                    | MachineMove::Feed { start, end, .. }
                    | MachineMove::Arc { start, end, .. },
                ) => Some((start, end)),
                None => None,
            })
            .collect()
    }

    /// Distance from `p` to the segment `a`-`b`.
    fn to_segment(p: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let t = (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
        (p.0 - a.0 - t * dx).hypot(p.1 - a.1 - t * dy)
    }

    const SQUARE: &str = "G21 G90 F100\nG0 X-10 Y-10\nG41.1 D4 G1 X0 Y0\nG1 Y20\nG1 X20\nG1 Y0\nG1 X0\n\
                          G1 X0 Y20\nG40 G1 X-10 Y30\nM2\n";

    #[test]
    fn machine_moves_are_continuous_through_the_queue_and_the_exit() {
        for src in [
            SQUARE,
            "G20 G90 F10\nG0 X0 Y0 Z1\nG41.1 D0.25 G1 X1 Y0\nG1 Z-0.1\nG3 X2 Y1 R1\nG1 Y2\nG0 X0\nG2 X-1 Y1 R1\n\
             G1 Y0.5\nG40 G0 X-2 Y-2\nG1 X0 Y0\nM2\n",
        ] {
            let calls = interpret(src).unwrap();
            let moves = machine_moves(&calls);
            assert!(moves.len() > 6);
            for w in moves.windows(2) {
                for k in 0..6 {
                    assert!((w[0].1[k] - w[1].0[k]).abs() < 1e-9, "{src}: {:?} then {:?}", w[0], w[1]);
                }
            }
        }
    }

    #[test]
    fn outside_square_keeps_the_tool_a_radius_away_from_the_part() {
        let calls = interpret(SQUARE).unwrap();
        let part = [(0.0, 0.0), (0.0, 20.0), (20.0, 20.0), (20.0, 0.0), (0.0, 0.0)];
        let ends: Vec<(f64, f64)> = calls
            .iter()
            .filter_map(|c| match &c.canon {
                Canon::StraightFeed { end } => Some((end[0], end[1])),
                Canon::ArcFeed(a) => Some((a.first_end, a.second_end)),
                _ => None,
            })
            .collect();
        // Entry, then four sides with a corner arc before each new side, then the exit.
        let on_path = &ends[1..ends.len() - 1];
        assert!(on_path.len() >= 8);
        for p in on_path {
            let d = part.windows(2).map(|s| to_segment(*p, s[0], s[1])).fold(f64::INFINITY, f64::min);
            assert!((d - 2.0).abs() < 1e-9, "{p:?} is {d} from the part");
            // Outside (G41 going clockwise).
            assert!(!(p.0 > 0.0 && p.0 < 20.0 && p.1 > 0.0 && p.1 < 20.0), "{p:?} inside");
        }
    }

    #[test]
    fn ccomp_parameter_follows_the_code() {
        let src = "G21 F100\nG0 X0 Y0\n(DEBUG,#<_ccomp>)\nG41.1 D2 G1 X10\n(DEBUG,#<_ccomp>)\nG40 G1 X20\n\
                   G42 G1 X30\n(DEBUG,#<_ccomp>)\nG40\n(DEBUG,#<_ccomp>)\n\
                   G42.1 D2 G1 X40\n(DEBUG,#<_ccomp>)\nG40 X50\nM2\n";
        let texts: Vec<String> = interpret(src)
            .unwrap()
            .into_iter()
            .filter_map(|c| match c.canon {
                Canon::Message { text } => Some(text),
                _ => None,
            })
            .collect();
        assert_eq!(texts, ["400.000000", "410.000000", "420.000000", "400.000000", "420.000000"]);
    }

    #[test]
    fn errors_are_typed() {
        use crate::error::{CompError, ErrorKind};
        for (src, line, kind) in [
            ("G21 F100\nG0 X0 Y0\nG41.1 D10 G1 X1\nG1 Y0.1\nG1 X20\nM2\n", 3, CompError::EntryTooShort),
            ("G21 F100\nG0 X0 Y0\nG41.1 D10 G1 X20\nG1 Y1\nG1 X40\nM2\n", 5, CompError::StraightFeedGouge),
            ("G21 F100\nG0 X0 Y0\nG41.1 D2 G1 X20\nG41.1 D2 G1 X40\nM2\n", 4, CompError::AlreadyOn),
            ("G21 F100\nG0 X0 Y0\nG41.1 D2 G1 X20\nG40\nG2 X30 Y0 R5\nM2\n", 5, CompError::ArcAfterExit),
            ("G21 F100\nG0 X0 Y0\nG41.1 D2 G1 X20\nG81 X5 Y5 Z-1 R1\nM2\n", 4, CompError::CannedCycle),
        ] {
            let e = interpret(src).unwrap_err();
            assert_eq!((e.line, e.kind), (line, ErrorKind::CutterComp(kind)), "{src}");
        }
    }

    #[test]
    fn calls_wait_behind_the_held_move() {
        let calls = interpret("G21 F100\nG0 X-10 Y0\nG41.1 D2 G1 X0\nG1 X10 F200\nG40 G1 X20\nM2\n").unwrap();
        let line_of = |pred: &dyn Fn(&Canon) -> bool| calls.iter().position(|c| pred(&c.canon)).unwrap();
        let feed_200 = line_of(&|c| matches!(c, Canon::SetFeedRate { rate } if *rate == 200.0));
        let entry = line_of(&|c| matches!(c, Canon::StraightFeed { .. }));
        assert!(entry < feed_200, "the entry move is sent before line 4's feed rate");
        assert_eq!(calls[feed_200].line, 4);
        assert_eq!(calls[entry].line, 3);
    }
}
