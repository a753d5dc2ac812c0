//! Modal state changes of a block, in LinuxCNC's order of execution: feed mode, F, S,
//! spindle, coolant, the seed's M-functions, dwell, plane, units, coordinate system,
//! distance modes, G10/G92, motion, stops and the program-end reset.

use super::cycles::Cycle;
use super::io::{IoCodes, MCodeDialect};
use super::motion::Motion;
use super::rotation::{self, rotate, rotation_param};
use super::{origin_param, Interpreter};
use crate::block::{g, Block};
use crate::canon::{Canon, MSync, Plane, Pose, Units};
use crate::error::{CompError, ErrorKind, KResult};

impl Interpreter<'_> {
    /// Executes the block's words (the line's assignments, comment and EX writes are done).
    pub(super) fn execute_block(&mut self, b: &mut Block) -> KResult<()> {
        let io = self.take_io_codes(b)?;
        let b = &*b;
        let gcode = |grp: usize| b.g.get(grp).copied().flatten();
        self.check_words(b, io)?;
        // Axis words belong to a code other than motion (G10, G28/G30, G43.1, G52, G92).
        let mut axes_used = false;
        if let Some((code, _)) = gcode(5) {
            // LinuxCNC queues an "interpreter: feed mode ..." comment here.
            self.comp.phantom();
            self.set_feed_mode(code);
        }
        if let Some(f) = b.f {
            if f < 0.0 {
                return Err((b.first_col, ErrorKind::NegativeFeed));
            }
            self.feed_word(f);
        }
        if let Some((code, _)) = gcode(14) {
            self.set_spindle_mode(code, b);
        }
        if let Some(s) = b.s {
            if s < 0.0 {
                return Err((b.first_col, ErrorKind::NegativeSpindle));
            }
            self.rpm = s;
            self.emit(Canon::SetSpindleSpeed { rpm: s });
        }
        // LinuxCNC's order: T, M62-M68, M6 or M61.
        self.select_tool(b)?;
        self.io_words(b, io)?;
        self.change_tool(b)?;
        if io.set_tool {
            self.set_current_tool(b)?;
        }
        match b.m_spindle {
            Some(3) => {
                self.spindle = 1;
                self.emit(Canon::StartSpindleClockwise);
            }
            Some(4) => {
                self.spindle = -1;
                self.emit(Canon::StartSpindleCounterclockwise);
            }
            Some(_) => {
                self.spindle = 0;
                self.emit(Canon::StopSpindleTurning);
            }
            None => {}
        }
        match b.m_coolant {
            Some(7) => {
                self.mist = true;
                self.emit(Canon::MistOn);
            }
            Some(8) => {
                self.flood = true;
                self.emit(Canon::FloodOn);
            }
            Some(_) => {
                self.mist = false;
                self.flood = false;
                self.emit(Canon::MistOff);
                self.emit(Canon::FloodOff);
            }
            None => {}
        }
        for &(m, _) in &b.m_user {
            let sync = if self.config.async_m_functions.contains(&m) { MSync::Async } else { MSync::Sync };
            self.emit(Canon::MFunction { number: m, sync });
        }
        if let Some((_, col)) = gcode(0).filter(|(c, _)| *c == g::G4) {
            let p = b.p.ok_or((col, ErrorKind::DwellMissing))?;
            if p < 0.0 {
                return Err((col, ErrorKind::NegativeDwell));
            }
            self.emit(Canon::Dwell { seconds: p });
        }
        if let Some((code, col)) = gcode(2) {
            let plane = match code {
                g::G17 => Plane::Xy,
                g::G18 => Plane::Xz,
                _ => Plane::Yz,
            };
            if self.comp.on() && plane != self.plane {
                return Err(comp_err(col, CompError::PlaneChange));
            }
            self.plane = plane;
            self.emit(Canon::SelectPlane { plane: self.plane });
        }
        if let Some((code, _)) = gcode(6) {
            let units = if code == g::G20 { Units::Inch } else { Units::Mm };
            if units != self.units {
                self.comp_scale(if units == Units::Inch { 1.0 / 25.4 } else { 25.4 });
            }
            self.set_units(units);
        }
        if let Some((code, col)) = gcode(7) {
            self.cutter_comp_code(code, b, col)?;
        }
        if let Some((code, col)) = gcode(8) {
            if code == g::G43_1 {
                axes_used = true;
            }
            self.tool_length_offset(code, b, col)?;
        }
        if let Some((code, col)) = gcode(12) {
            if self.comp.on() {
                return Err(comp_err(col, CompError::CoordSystemChange));
            }
            let k = match code {
                540 => 0,
                550 => 1,
                560 => 2,
                570 => 3,
                580 => 4,
                590 => 5,
                591 => 6,
                592 => 7,
                _ => 8,
            };
            // LinuxCNC: selecting the active system again emits nothing.
            if k != self.coord {
                self.select_coord(k);
                self.emit(Canon::SetG92Offset { offset: self.g92 });
                self.emit(Canon::SetXyRotation { degrees: self.rot });
            }
        }
        if let Some((code, col)) = gcode(13) {
            if self.comp.on() {
                return Err(comp_err(col, CompError::ControlModeChange));
            }
            self.set_path_control(code, b);
        }
        // A change of distance mode queues an "interpreter: ..." comment in LinuxCNC.
        if let Some((code, _)) = gcode(3) {
            if self.absolute != (code == g::G90) {
                self.comp.phantom();
            }
            self.absolute = code == g::G90;
        }
        if let Some((code, _)) = gcode(4) {
            if self.arc_absolute != (code == g::G90_1) {
                self.comp.phantom();
            }
            self.arc_absolute = code == g::G90_1;
        }
        if let Some((code, col)) = gcode(10) {
            if self.comp.on() {
                return Err(comp_err(col, CompError::RetractModeChange));
            }
            self.cycles.retract_to_initial = code == g::G98;
        }
        let nonmodal = gcode(0);
        if let Some((code, col)) = nonmodal {
            if self.comp.on() {
                let msg = match code {
                    g::G92 | g::G92_1 | g::G92_2 | g::G92_3 | g::G52 => Some(CompError::AxisOffsetChange),
                    g::G28 | g::G30 => Some(CompError::ReferenceMove),
                    g::G28_1 | g::G30_1 => Some(CompError::ReferenceSet),
                    _ => None,
                };
                if let Some(msg) = msg {
                    return Err(comp_err(col, msg));
                }
            }
            match code {
                g::G10 => {
                    axes_used = true;
                    self.g10(b, col)?;
                }
                g::G92 => {
                    axes_used = true;
                    if !b.has_axes() {
                        return Err((col, ErrorKind::G92NoAxes));
                    }
                    let mut new = self.g92;
                    for k in 0..6 {
                        if let (Some(v), Some(slot), Some(p)) =
                            (b.axes.get(k).copied().flatten(), new.get_mut(k), self.pos.get(k))
                        {
                            *slot = p + *slot - v;
                        }
                    }
                    self.set_g92(new, G92Params::Save);
                }
                g::G28 | g::G30 => {
                    axes_used = true;
                    self.go_to_reference(code, b);
                }
                g::G28_1 | g::G30_1 => self.store_reference(code),
                g::G52 => {
                    axes_used = true;
                    self.set_local_offset(b);
                }
                g::G92_1 => self.set_g92([0.0; 6], G92Params::Clear),
                g::G92_2 => self.set_g92([0.0; 6], G92Params::Suspend),
                g::G92_3 => {
                    let mut new = [0.0; 6];
                    for (k, slot) in new.iter_mut().enumerate() {
                        *slot = self.params.get(5211 + k) / self.user_units_per_program_unit(k);
                    }
                    self.set_g92(new, G92Params::Restore);
                }
                _ => {}
            }
        }
        let explicit_motion = gcode(1);
        if axes_used && explicit_motion.is_some_and(|(c, _)| c != g::G80) {
            return Err((b.first_col, ErrorKind::TwoAxisUsers));
        }
        let previous = self.motion;
        if let Some((code, _)) = explicit_motion {
            if code == g::G80 {
                // LinuxCNC: "interpreter: motion mode set to none".
                self.comp.phantom();
            }
            let m = match code {
                g::G0 => Some(Motion::Rapid),
                g::G1 => Some(Motion::Feed),
                g::G2 => Some(Motion::Cw),
                g::G3 => Some(Motion::Ccw),
                other => Cycle::from_code(other).map(Motion::Cycle),
            };
            self.set_motion_mode(m);
        }
        let g53 = nonmodal.filter(|(c, _)| *c == g::G53);
        if !axes_used {
            let arc_words = explicit_motion.is_some_and(|(c, _)| c == g::G2 || c == g::G3)
                && (b.r.is_some() || b.ijk.iter().any(Option::is_some));
            // LinuxCNC: an explicit G0/G1 without axis words still moves (to where it is).
            let bare_straight = explicit_motion.is_some_and(|(c, _)| c == g::G0 || c == g::G1);
            let bare_cycle = explicit_motion.is_some_and(|(c, _)| Cycle::from_code(c).is_some());
            if b.has_axes() || arc_words || bare_straight || bare_cycle {
                let Some(m) = self.motion else {
                    return Err((b.axis_col.unwrap_or(b.first_col), ErrorKind::AxisWithoutMotion));
                };
                let mcol = explicit_motion.map_or(b.first_col, |(_, c)| c);
                if let Motion::Cycle(c) = m {
                    if self.comp.on() {
                        return Err(comp_err(mcol, CompError::CannedCycle));
                    }
                    if let Some((_, col)) = g53 {
                        return Err((col, ErrorKind::G53WithoutStraight));
                    }
                    self.cycle(c, b, previous != Some(m), mcol)?;
                } else {
                    self.motion(m, b, g53.map(|(_, c)| c), mcol)?;
                }
            } else if let Some((_, col)) = g53 {
                return Err((col, ErrorKind::G53WithoutStraight));
            }
        }
        if b.m_stop.is_some() || io.pallet {
            // LinuxCNC sends the held-back compensated move before a stop or the end.
            self.comp_flush_for_stop(b.first_col)?;
        }
        if io.pallet {
            // M60: the pallets are exchanged, then the program stops.
            self.emit(Canon::PalletShuttle);
            self.emit(Canon::ProgramStop);
        }
        match b.m_stop {
            Some(0) => self.emit(Canon::ProgramStop),
            Some(1) => self.emit(Canon::OptionalProgramStop),
            Some(m) => self.program_end(m == 30),
            None => {}
        }
        Ok(())
    }

    /// LinuxCNC's check that every P, Q, R, L and H word has a code in the block that uses
    /// it (the motion: the block's own, or the modal one when the block has axis words).
    fn check_words(&self, b: &Block, io: IoCodes) -> KResult<()> {
        let code = |grp: usize| b.g.get(grp).copied().flatten().map(|(c, _)| c);
        let motion = code(1).or_else(|| {
            if !b.has_axes() {
                return None;
            }
            self.motion.map(|m| match m {
                Motion::Rapid => g::G0,
                Motion::Feed => g::G1,
                Motion::Cw => g::G2,
                Motion::Ccw => g::G3,
                Motion::Cycle(c) => c.code(),
            })
        });
        let cycle = motion.and_then(Cycle::from_code).is_some();
        let arc = matches!(motion, Some(g::G2 | g::G3));
        let (modal0, path, tool) = (code(0), code(13), code(8));
        // The seed's M-functions may take parameters, as LinuxCNC's user M codes do.
        let user_m = !b.m_user.is_empty();
        let missing = |ok: bool, letter: char, users: &'static str| -> KResult<()> {
            if ok {
                Ok(())
            } else {
                Err((b.first_col, ErrorKind::WordWithoutCode(letter, users)))
            }
        };
        if b.p.is_some() {
            let ok = arc
                || matches!(motion, Some(g::G82 | g::G89))
                || matches!(modal0, Some(g::G4 | g::G10))
                || path == Some(g::G64)
                || user_m
                || io.uses_p();
            missing(ok, 'P', "G2, G3, G4, G10, G64, G82, G89 or M-function")?;
        }
        if b.q.is_some() {
            let ok = matches!(motion, Some(g::G73 | g::G83)) || path == Some(g::G64) || user_m || io.uses_q();
            missing(ok, 'Q', "G64, G73, G83 or M-function")?;
        }
        if b.r.is_some() {
            missing(arc || cycle || modal0 == Some(g::G10), 'R', "G2, G3, G10 or canned cycle")?;
        }
        if b.l.is_some() {
            let comp_l = matches!(code(7), Some(g::G41_1 | g::G42_1));
            missing(
                cycle || comp_l || modal0 == Some(g::G10) || io.uses_l(),
                'L',
                "G10, canned cycle or M66",
            )?;
        }
        if b.e.is_some() {
            if self.config.m_codes == MCodeDialect::Seed {
                return Err((b.e_col, ErrorKind::UnsupportedLetter('E')));
            }
            missing(io.uses_e(), 'E', "M66, M67 or M68")?;
        }
        if b.h.is_some() {
            missing(tool == Some(g::G43), 'H', "G43")?;
        }
        if b.d.is_some() {
            let comp = matches!(code(7), Some(g::G41 | g::G41_1 | g::G42 | g::G42_1));
            missing(
                comp || code(14) == Some(g::G96),
                'D',
                "G41, G41.1, G42, G42.1, G71, G71.1, G71.2 or G96",
            )?;
        }
        if b.has_polar() {
            for (k, letter) in [(0, 'X'), (1, 'Y')] {
                if b.axes.get(k).copied().flatten().is_some() {
                    return Err((b.first_col, ErrorKind::PolarWithAxis(letter)));
                }
            }
            let straight_or_arc = matches!(motion, Some(g::G0 | g::G1 | g::G2 | g::G3));
            if !straight_or_arc || modal0.is_some_and(|c| c != g::G53) {
                return Err((b.first_col, ErrorKind::PolarWithoutStraightOrArc));
            }
        }
        Ok(())
    }

    /// G10 L2 (origin and rotation of a system) and G10 L20 (origin such that the
    /// current point has the given coordinates), with LinuxCNC's `convert_setup`.
    fn g10(&mut self, b: &Block, col: u32) -> KResult<()> {
        let l = b.l.ok_or((col, ErrorKind::BadG10("L word missing")))?;
        let p = b.p.ok_or((col, ErrorKind::BadG10("P word missing")))?;
        if b.ijk.iter().take(2).any(Option::is_some) {
            return Err((col, ErrorKind::BadG10("I J words not allowed with G10 L2")));
        }
        let pi = p.round();
        if (p - pi).abs() > 0.0001 || !(0.0..=9.0).contains(&pi) {
            return Err((col, ErrorKind::BadG10("P must be 0..=9")));
        }
        // 0..=9 checked above; P0 = the active system.
        let k = if pi == 0.0 { self.coord } else { pi as usize - 1 };
        if k == self.coord && self.comp.on() {
            return Err(comp_err(col, CompError::ActiveSystemChange));
        }
        let l20 = match l.round() as i64 {
            2 => false,
            20 => true,
            _ => return Err((col, ErrorKind::BadG10("only L2 and L20 are supported"))),
        };
        let mut new = self.origins.get(k).copied().unwrap_or([0.0; 6]);
        let cur = self.current_in_system(k);
        let r = match b.r {
            Some(_) if l20 => return Err((col, ErrorKind::BadG10("R not allowed in G10 L20"))),
            Some(r) => {
                self.params.set(rotation_param(k), r);
                r
            }
            None => self.rotation_of(k),
        };
        let word = |a: usize| b.axes.get(a).copied().flatten();
        let at = |p: &Pose, a: usize| p.get(a).copied().unwrap_or(0.0);
        if l20 {
            // X and Y in the target system's rotated frame (LinuxCNC writes both).
            let (ox, oy) = rotate(at(&cur, 0), at(&cur, 1), r);
            let (tx, ty) = rotate(word(0).unwrap_or(at(&cur, 0)), word(1).unwrap_or(at(&cur, 1)), r);
            let xy = (ox + at(&new, 0) - tx, oy + at(&new, 1) - ty);
            rotation::set_xy(&mut new, xy);
        }
        let first = if l20 { 2 } else { 0 };
        for a in first..6 {
            if let (Some(v), Some(slot)) = (word(a), new.get_mut(a)) {
                *slot = if l20 { at(&cur, a) + *slot - v } else { v };
            }
        }
        if k == self.coord {
            self.rebase_current(&new, r);
        }
        if let Some(slot) = self.origins.get_mut(k) {
            *slot = new;
        }
        for (a, v) in new.iter().enumerate() {
            self.params.set(origin_param(k) + a, *v);
        }
        if k == self.coord {
            self.emit(Canon::SetG5xOffset { index: u8::try_from(k + 1).unwrap_or(1), offset: new });
            self.emit(Canon::SetXyRotation { degrees: r });
        }
        Ok(())
    }

    fn program_end(&mut self, pallet: bool) {
        self.comp.side = super::cutter_comp::Side::Off;
        // LinuxCNC: back to G54 (the current point moved without the G92 offset).
        let g54 = self.origins.first().copied().unwrap_or([0.0; 6]);
        self.rebase_current(&g54, self.rotation_of(0));
        self.coord = 0;
        self.params.set(5220, 1.0);
        self.emit(Canon::SetG5xOffset { index: 1, offset: g54 });
        self.emit(Canon::SetXyRotation { degrees: self.rot });
        if self.plane != Plane::Xy {
            self.plane = Plane::Xy;
            self.emit(Canon::SelectPlane { plane: Plane::Xy });
        }
        self.absolute = true;
        self.set_motion_mode(Some(Motion::Feed));
        self.set_feed_mode(g::G94);
        self.spindle = 0;
        self.emit(Canon::StopSpindleTurning);
        self.css_max_rpm = None;
        self.emit(Canon::SetSpindleMode { max_rpm: 0.0 });
        // Coolant that is on is turned off (LinuxCNC: mist, then flood).
        if std::mem::take(&mut self.mist) {
            self.emit(Canon::MistOff);
        }
        if std::mem::take(&mut self.flood) {
            self.emit(Canon::FloodOff);
        }
        if pallet {
            self.emit(Canon::PalletShuttle);
        }
        self.emit(Canon::ProgramEnd);
        self.done = true;
    }

    /// Sets the G92 offsets to `new` (program units) and the saved offsets #5211-#5216 and
    /// their flag #5210 as LinuxCNC does for the code that asked (`params`).
    pub(super) fn set_g92(&mut self, new: Pose, params: G92Params) {
        // Keep the machine position: pos + g92 is invariant.
        for k in 0..6 {
            if let (Some(p), Some(o), Some(n)) = (self.pos.get_mut(k), self.g92.get(k), new.get(k)) {
                *p += o - n;
            }
        }
        self.g92 = new;
        match params {
            G92Params::Save => {
                for (k, v) in new.iter().enumerate() {
                    self.params.set(5211 + k, v * self.user_units_per_program_unit(k));
                }
            }
            G92Params::Clear => {
                for k in 0..6 {
                    self.params.set(5211 + k, 0.0);
                }
            }
            G92Params::Suspend | G92Params::Restore => {}
        }
        let applied = matches!(params, G92Params::Save | G92Params::Restore);
        self.params.set(5210, if applied { 1.0 } else { 0.0 });
        self.emit(Canon::SetG92Offset { offset: new });
    }

    /// Saved offsets are kept in the machine's (user) units, millimetres and degrees, as
    /// LinuxCNC keeps them in its configured units: the factor from program units for axis `k`.
    pub(super) fn user_units_per_program_unit(&self, k: usize) -> f64 {
        if k < 3 {
            self.units.mm_per_unit()
        } else {
            1.0
        }
    }

    /// G54..G59.3: the current point moves into system `k` (LinuxCNC's
    /// `find_current_in_system`), whose rotation becomes active.
    fn select_coord(&mut self, k: usize) {
        self.pos = self.current_in_system(k);
        self.coord = k;
        self.rot = self.rotation_of(k);
        let new = self.origin();
        self.params.set(5220, (k + 1) as f64);
        self.emit(Canon::SetG5xOffset { index: u8::try_from(k + 1).unwrap_or(1), offset: new });
    }

    fn set_units(&mut self, u: Units) {
        if u != self.units {
            let factor = match u {
                Units::Inch => 1.0 / 25.4,
                Units::Mm => 25.4,
            };
            let scale = |p: &mut Pose| {
                for v in p.iter_mut().take(3) {
                    *v *= factor;
                }
            };
            scale(&mut self.pos);
            scale(&mut self.g92);
            for o in self.origins.iter_mut() {
                scale(o);
            }
            self.units = u;
        }
        self.emit(Canon::UseLengthUnits { units: u });
    }
}

/// A cutter compensation error at `col`.
fn comp_err(col: u32, e: CompError) -> (u32, ErrorKind) {
    (col, ErrorKind::CutterComp(e))
}

/// What a G92-family code does with the saved offsets #5211-#5216 and their flag #5210.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum G92Params {
    /// G92: the new offsets are saved, the flag set.
    Save,
    /// G92.1: offsets and saved values zero, the flag cleared.
    Clear,
    /// G92.2: offsets zero, the saved values kept for G92.3, the flag cleared.
    Suspend,
    /// G92.3: the saved values applied again, the flag set.
    Restore,
}
