//! The interpreter: executes blocks in LinuxCNC's order of execution and yields
//! canonical calls one by one (a pull-based, sans-IO iterator).
//!
//! Order within a block: O-word, comment/message, parameter assignments (all values on a
//! line are read first, as in LinuxCNC), `EX` writes, feed mode (G94), F, S, M3/M4/M5,
//! M7/M8/M9, the seed's M-functions, G4, G17-G19, G20/G21, G54-G59.3, G90/G91,
//! G90.1/G91.1, G10/G92.x, motion (G0-G3, with G53), M0/M1/M2/M30.

use std::collections::{HashMap, VecDeque};

use crate::arc;
use crate::block::{g, read_block, Block};
use crate::canon::{ArcFeed, Canon, CanonCall, ExArray, ExValue, MSync, MachineMove, Plane, Pose, Units};
use crate::error::{ErrorKind, GcodeError, KResult};
use crate::expr::{eval_at, param_index, Params};
use crate::parse::{parse_line, Line, OKind, Remark};

/// Interpreter settings.
#[derive(Debug, Clone, PartialEq)]
pub struct InterpreterConfig {
    /// Seed M-functions that are asynchronous (all others are synchronous).
    pub async_m_functions: Vec<u16>,
    /// Block-delete switch: when on, lines starting with `/` are skipped.
    pub block_delete: bool,
    /// Error out when the text ends without M2/M30 or a closing `%` (as `rs274` does).
    pub require_program_end: bool,
    /// Maximum number of lines executed (guard against endless O-word loops).
    pub max_steps: u64,
    /// Maximum subroutine nesting.
    pub max_call_depth: usize,
}

impl Default for InterpreterConfig {
    fn default() -> Self {
        Self {
            async_m_functions: Vec::new(),
            block_delete: false,
            require_program_end: true,
            max_steps: 100_000_000,
            max_call_depth: 64,
        }
    }
}

/// Modal motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Motion {
    Rapid,
    Feed,
    Cw,
    Ccw,
}

/// The work-offset parameter base for coordinate system `k` (0 = G54): 5221 + 20 k.
fn origin_param(k: usize) -> usize {
    5221 + 20 * k
}

/// A line's parse result (error = column and kind).
type ParsedLine = Result<Line, (u32, ErrorKind)>;

struct CallFrame {
    return_pc: usize,
}

/// A pull-based interpreter over one program text.
pub struct Interpreter<'a> {
    lines: Vec<&'a str>,
    /// Cached parses (O-word lines, and lines re-run inside loops/subroutines).
    parsed: Vec<Option<Box<ParsedLine>>>,
    onext: Vec<Option<usize>>,
    oprev: Vec<Option<usize>>,
    okind: Vec<Option<OKind>>,
    subs: HashMap<String, usize>,
    config: InterpreterConfig,
    out: VecDeque<CanonCall>,
    pc: usize,
    steps: u64,
    done: bool,
    percent_open: bool,
    seen_content: bool,
    calls: Vec<CallFrame>,
    params: Params,
    // Modal state (program units, like LinuxCNC).
    units: Units,
    absolute: bool,
    arc_absolute: bool,
    plane: Plane,
    feed: f64,
    feed_mm: f64,
    motion: Option<Motion>,
    pos: Pose,
    coord: usize,
    origins: [Pose; 9],
    g92: Pose,
    cur_line: u32,
    cur_n: Option<u32>,
}

impl<'a> Interpreter<'a> {
    /// An interpreter over `src` with the default configuration.
    pub fn new(src: &'a str) -> Self {
        Self::with_config(src, InterpreterConfig::default())
    }

    /// An interpreter over `src`.
    pub fn with_config(src: &'a str, config: InterpreterConfig) -> Self {
        let lines: Vec<&str> = src.lines().collect();
        let mut it = Self {
            parsed: Vec::new(),
            onext: vec![None; lines.len()],
            oprev: vec![None; lines.len()],
            okind: vec![None; lines.len()],
            subs: HashMap::new(),
            lines,
            config,
            out: VecDeque::new(),
            pc: 0,
            steps: 0,
            done: false,
            percent_open: false,
            seen_content: false,
            calls: Vec::new(),
            params: Params::default(),
            units: Units::Mm,
            absolute: true,
            arc_absolute: false,
            plane: Plane::Xy,
            feed: 0.0,
            feed_mm: 0.0,
            motion: None,
            pos: [0.0; 6],
            coord: 0,
            origins: [[0.0; 6]; 9],
            g92: [0.0; 6],
            cur_line: 0,
            cur_n: None,
        };
        it.index_owords();
        it.emit(Canon::UseLengthUnits { units: Units::Mm });
        it.emit(Canon::SetG5xOffset { index: 1, offset: [0.0; 6] });
        it.emit(Canon::SetG92Offset { offset: [0.0; 6] });
        it.emit(Canon::SetXyRotation { degrees: 0.0 });
        it.emit(Canon::SetFeedReference);
        it
    }

    /// Pre-scan: parse O-word lines, link lines of the same O name, find subroutines.
    fn index_owords(&mut self) {
        self.parsed = vec![None; self.lines.len()];
        let mut last: HashMap<String, usize> = HashMap::new();
        for (i, text) in self.lines.iter().enumerate() {
            let t = text.trim_start().trim_start_matches('/').trim_start();
            let t = t.trim_start_matches(|c: char| {
                c == 'n' || c == 'N' || c.is_ascii_digit() || c == ' ' || c == '\t'
            });
            if !t.starts_with(['o', 'O']) {
                continue;
            }
            let parsed = parse_line(text);
            if let Ok(Line { oword: Some(o), .. }) = &parsed {
                if let Some(k) = self.okind.get_mut(i) {
                    *k = Some(o.kind);
                }
                if let Some(&j) = last.get(&o.name) {
                    if let Some(slot) = self.onext.get_mut(j) {
                        *slot = Some(i);
                    }
                    if let Some(slot) = self.oprev.get_mut(i) {
                        *slot = Some(j);
                    }
                }
                last.insert(o.name.clone(), i);
                if o.kind == OKind::Sub {
                    self.subs.entry(o.name.clone()).or_insert(i);
                }
            }
            if let Some(slot) = self.parsed.get_mut(i) {
                *slot = Some(Box::new(parsed));
            }
        }
    }

    fn emit(&mut self, canon: Canon) {
        self.out.push_back(CanonCall { line: self.cur_line, n: self.cur_n, canon, machine: None });
    }

    fn emit_move(&mut self, canon: Canon, m: MachineMove) {
        self.out.push_back(CanonCall { line: self.cur_line, n: self.cur_n, canon, machine: Some(m) });
    }

    fn err(&self, (column, kind): (u32, ErrorKind)) -> GcodeError {
        GcodeError::new(self.cur_line, column, kind)
    }

    /// Machine millimetres of a program-units pose under the current offsets.
    fn to_machine(&self, p: &Pose) -> Pose {
        let f = self.units.mm_per_unit();
        let o = self.origins.get(self.coord).copied().unwrap_or([0.0; 6]);
        let mut m = [0.0; 6];
        for (k, slot) in m.iter_mut().enumerate() {
            let v = p.get(k).copied().unwrap_or(0.0)
                + o.get(k).copied().unwrap_or(0.0)
                + self.g92.get(k).copied().unwrap_or(0.0);
            *slot = if k < 3 { v * f } else { v };
        }
        m
    }

    fn origin(&self) -> Pose {
        self.origins.get(self.coord).copied().unwrap_or([0.0; 6])
    }

    fn set_g92(&mut self, new: Pose) {
        // Keep the machine position: pos + g92 is invariant.
        for k in 0..6 {
            if let (Some(p), Some(o), Some(n)) = (self.pos.get_mut(k), self.g92.get(k), new.get(k)) {
                *p += o - n;
            }
        }
        self.g92 = new;
        for (k, v) in new.iter().enumerate() {
            self.params.set(5211 + k, *v);
        }
        self.params.set(5210, if new.iter().any(|v| *v != 0.0) { 1.0 } else { 0.0 });
        self.emit(Canon::SetG92Offset { offset: new });
    }

    fn set_origin(&mut self, k: usize, new: Pose) {
        if k == self.coord {
            let old = self.origin();
            for a in 0..6 {
                if let (Some(p), Some(o), Some(n)) = (self.pos.get_mut(a), old.get(a), new.get(a)) {
                    *p += o - n;
                }
            }
        }
        if let Some(slot) = self.origins.get_mut(k) {
            *slot = new;
        }
        for (a, v) in new.iter().enumerate() {
            self.params.set(origin_param(k) + a, *v);
        }
    }

    fn select_coord(&mut self, k: usize) {
        let old = self.origin();
        self.coord = k;
        let new = self.origin();
        for a in 0..6 {
            if let (Some(p), Some(o), Some(n)) = (self.pos.get_mut(a), old.get(a), new.get(a)) {
                *p += o - n;
            }
        }
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

    /// Runs lines until at least one call is queued, the program ends, or an error occurs.
    fn step(&mut self) -> Result<(), GcodeError> {
        while self.out.is_empty() && !self.done {
            let Some(text) = self.lines.get(self.pc).copied() else {
                self.done = true;
                if self.config.require_program_end && !self.percent_open {
                    self.cur_line = u32::try_from(self.lines.len()).unwrap_or(u32::MAX);
                    return Err(self.err((1, ErrorKind::NoProgramEnd)));
                }
                if self.config.require_program_end && self.percent_open {
                    self.cur_line = u32::try_from(self.lines.len()).unwrap_or(u32::MAX);
                    return Err(self.err((1, ErrorKind::NoProgramEnd)));
                }
                return Ok(());
            };
            self.steps += 1;
            if self.steps > self.config.max_steps {
                self.done = true;
                return Err(self.err((1, ErrorKind::StepLimit(self.config.max_steps))));
            }
            self.cur_line = u32::try_from(self.pc + 1).unwrap_or(u32::MAX);
            let line = match self.parsed.get_mut(self.pc).and_then(Option::take) {
                Some(l) => *l,
                None => parse_line(text),
            };
            let line = match line {
                Ok(l) => l,
                Err(e) => {
                    self.done = true;
                    return Err(self.err(e));
                }
            };
            let r = self.execute(&line);
            // Keep O-word lines (loops come back to them); plain lines are not revisited
            // unless inside a loop or subroutine, where they are re-parsed.
            if line.oword.is_some() || !self.calls.is_empty() {
                if let Some(slot) = self.parsed.get_mut(self.cur_line as usize - 1) {
                    *slot = Some(Box::new(Ok(line)));
                }
            }
            if let Err(e) = r {
                self.done = true;
                return Err(self.err(e));
            }
        }
        Ok(())
    }

    fn execute(&mut self, line: &Line) -> KResult<()> {
        let here = self.pc;
        self.pc += 1;
        if line.percent {
            if self.seen_content || self.percent_open {
                self.done = true;
                self.percent_open = true;
            } else {
                self.percent_open = true;
                self.seen_content = true;
            }
            return Ok(());
        }
        let empty = line.oword.is_none()
            && line.words.is_empty()
            && line.assigns.is_empty()
            && line.ex.is_empty()
            && line.remark.is_none();
        if !empty {
            self.seen_content = true;
        }
        if line.block_delete && self.config.block_delete {
            return Ok(());
        }
        self.cur_n = line.n;
        if let Some(o) = &line.oword {
            return self.execute_oword(here, o);
        }
        let block = read_block(line, &self.params)?;
        // Values of assignments and EX writes are read before any is applied.
        let mut assigns = Vec::with_capacity(line.assigns.len());
        for a in &line.assigns {
            let v = eval_at(&self.params, &a.value, a.col)?;
            let target = match &a.target {
                crate::expr::ParamRef::Numbered(e) => {
                    let ix = eval_at(&self.params, e, a.col)?;
                    Ok(param_index(ix).map_err(|k| (a.col, k))?)
                }
                crate::expr::ParamRef::Named(n) => Err(n.clone()),
            };
            assigns.push((target, v));
        }
        let mut ex = Vec::with_capacity(line.ex.len());
        for w in &line.ex {
            let v = eval_at(&self.params, &w.value, w.col)?;
            ex.push((w, v));
        }
        for (t, v) in assigns {
            match t {
                Ok(i) => self.params.set(i, v),
                Err(n) => self.params.set_named(&n, v),
            }
        }
        match &line.remark {
            Some(Remark::Comment(t)) => self.emit(Canon::Comment { text: t.clone() }),
            Some(Remark::Message(t)) => self.emit(Canon::Message { text: t.clone() }),
            None => {}
        }
        for (w, v) in ex {
            let c = ex_value(w.array, w.index, v).map_err(|k| (w.col, k))?;
            self.emit(c);
        }
        self.execute_block(&block)
    }

    fn execute_block(&mut self, b: &Block) -> KResult<()> {
        let gcode = |grp: usize| b.g.get(grp).copied().flatten();
        if let Some((code, col)) = gcode(5) {
            if code != g::G94 {
                return Err((col, ErrorKind::UnsupportedFeedMode(f64::from(code) / 10.0)));
            }
            self.emit(Canon::SetFeedMode);
            self.emit(Canon::SetFeedRate { rate: 0.0 });
            self.feed = 0.0;
            self.feed_mm = 0.0;
        }
        if let Some(f) = b.f {
            if f < 0.0 {
                return Err((b.first_col, ErrorKind::NegativeFeed));
            }
            self.feed = f;
            self.feed_mm = f * self.units.mm_per_unit();
            self.emit(Canon::SetFeedRate { rate: f });
        }
        if let Some(s) = b.s {
            if s < 0.0 {
                return Err((b.first_col, ErrorKind::NegativeSpindle));
            }
            self.emit(Canon::SetSpindleSpeed { rpm: s });
        }
        match b.m_spindle {
            Some(3) => self.emit(Canon::StartSpindleClockwise),
            Some(4) => self.emit(Canon::StartSpindleCounterclockwise),
            Some(_) => self.emit(Canon::StopSpindleTurning),
            None => {}
        }
        match b.m_coolant {
            Some(7) => self.emit(Canon::MistOn),
            Some(8) => self.emit(Canon::FloodOn),
            Some(_) => {
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
        if let Some((code, _)) = gcode(2) {
            self.plane = match code {
                g::G17 => Plane::Xy,
                g::G18 => Plane::Xz,
                _ => Plane::Yz,
            };
            self.emit(Canon::SelectPlane { plane: self.plane });
        }
        if let Some((code, _)) = gcode(6) {
            self.set_units(if code == g::G20 { Units::Inch } else { Units::Mm });
        }
        if let Some((code, _)) = gcode(12) {
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
                self.emit(Canon::SetXyRotation { degrees: 0.0 });
            }
        }
        if let Some((code, _)) = gcode(3) {
            self.absolute = code == g::G90;
        }
        if let Some((code, _)) = gcode(4) {
            self.arc_absolute = code == g::G90_1;
        }
        let nonmodal = gcode(0);
        let mut axes_used = false;
        if let Some((code, col)) = nonmodal {
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
                    self.set_g92(new);
                }
                g::G92_1 | g::G92_2 => self.set_g92([0.0; 6]),
                g::G92_3 => {
                    let mut new = [0.0; 6];
                    for (k, slot) in new.iter_mut().enumerate() {
                        *slot = self.params.get(5211 + k);
                    }
                    self.set_g92(new);
                }
                _ => {}
            }
        }
        let explicit_motion = gcode(1);
        if axes_used && explicit_motion.is_some_and(|(c, _)| c != g::G80) {
            return Err((b.first_col, ErrorKind::TwoAxisUsers));
        }
        if let Some((code, _)) = explicit_motion {
            self.motion = match code {
                g::G0 => Some(Motion::Rapid),
                g::G1 => Some(Motion::Feed),
                g::G2 => Some(Motion::Cw),
                g::G3 => Some(Motion::Ccw),
                _ => None,
            };
        }
        let g53 = nonmodal.filter(|(c, _)| *c == g::G53);
        if !axes_used {
            let arc_words = explicit_motion.is_some_and(|(c, _)| c == g::G2 || c == g::G3)
                && (b.r.is_some() || b.ijk.iter().any(Option::is_some));
            // LinuxCNC: an explicit G0/G1 without axis words still moves (to where it is).
            let bare_straight = explicit_motion.is_some_and(|(c, _)| c == g::G0 || c == g::G1);
            if b.has_axes() || arc_words || bare_straight {
                let Some(m) = self.motion else {
                    return Err((b.axis_col.unwrap_or(b.first_col), ErrorKind::AxisWithoutMotion));
                };
                let mcol = explicit_motion.map_or(b.first_col, |(_, c)| c);
                self.motion(m, b, g53.map(|(_, c)| c), mcol)?;
            } else if let Some((_, col)) = g53 {
                return Err((col, ErrorKind::G53WithoutStraight));
            }
        }
        match b.m_stop {
            Some(0) => self.emit(Canon::ProgramStop),
            Some(1) => self.emit(Canon::OptionalProgramStop),
            Some(m) => self.program_end(m == 30),
            None => {}
        }
        Ok(())
    }

    fn g10(&mut self, b: &Block, col: u32) -> KResult<()> {
        let l = b.l.ok_or((col, ErrorKind::BadG10("L word missing")))?;
        let p = b.p.ok_or((col, ErrorKind::BadG10("P word missing")))?;
        if b.r.is_some() {
            return Err((col, ErrorKind::BadG10("R (rotation) is not supported")));
        }
        let pi = p.round();
        if (p - pi).abs() > 0.0001 || !(0.0..=9.0).contains(&pi) {
            return Err((col, ErrorKind::BadG10("P must be 0..=9")));
        }
        // 0..=9 checked above; P0 = the active system.
        let k = if pi == 0.0 { self.coord } else { pi as usize - 1 };
        let mut new = self.origins.get(k).copied().unwrap_or([0.0; 6]);
        let cur = self.origin();
        let l20 = match l.round() as i64 {
            2 => false,
            20 => true,
            _ => return Err((col, ErrorKind::BadG10("only L2 and L20 are supported"))),
        };
        for a in 0..6 {
            if let (Some(v), Some(slot)) = (b.axes.get(a).copied().flatten(), new.get_mut(a)) {
                *slot = if l20 {
                    self.pos.get(a).copied().unwrap_or(0.0) + cur.get(a).copied().unwrap_or(0.0) - v
                } else {
                    v
                };
            }
        }
        self.set_origin(k, new);
        if k == self.coord {
            self.emit(Canon::SetG5xOffset { index: u8::try_from(k + 1).unwrap_or(1), offset: new });
            self.emit(Canon::SetXyRotation { degrees: 0.0 });
        }
        Ok(())
    }

    fn program_end(&mut self, pallet: bool) {
        self.select_coord(0);
        self.emit(Canon::SetXyRotation { degrees: 0.0 });
        if self.plane != Plane::Xy {
            self.plane = Plane::Xy;
            self.emit(Canon::SelectPlane { plane: Plane::Xy });
        }
        self.absolute = true;
        self.motion = Some(Motion::Feed);
        self.emit(Canon::SetFeedMode);
        self.emit(Canon::SetFeedRate { rate: 0.0 });
        self.feed = 0.0;
        self.feed_mm = 0.0;
        self.emit(Canon::StopSpindleTurning);
        self.emit(Canon::SetSpindleMode);
        if pallet {
            self.emit(Canon::PalletShuttle);
        }
        self.emit(Canon::ProgramEnd);
        self.done = true;
    }

    fn motion(&mut self, m: Motion, b: &Block, g53: Option<u32>, mcol: u32) -> KResult<()> {
        let start = self.pos;
        let mut end = start;
        if let Some(col) = g53 {
            if !self.absolute {
                return Err((col, ErrorKind::G53Incremental));
            }
            if !matches!(m, Motion::Rapid | Motion::Feed) {
                return Err((col, ErrorKind::G53WithoutStraight));
            }
        }
        let origin = self.origin();
        for k in 0..6 {
            let (Some(v), Some(slot)) = (b.axes.get(k).copied().flatten(), end.get_mut(k)) else {
                continue;
            };
            *slot = if g53.is_some() {
                v - origin.get(k).copied().unwrap_or(0.0) - self.g92.get(k).copied().unwrap_or(0.0)
            } else if self.absolute {
                v
            } else {
                *slot + v
            };
        }
        let ms = self.to_machine(&start);
        let me = self.to_machine(&end);
        match m {
            Motion::Rapid => {
                self.emit_move(Canon::StraightTraverse { end }, MachineMove::Traverse { start: ms, end: me });
            }
            Motion::Feed => {
                if self.feed == 0.0 {
                    return Err((mcol, ErrorKind::ZeroFeed(1)));
                }
                self.emit_move(
                    Canon::StraightFeed { end },
                    MachineMove::Feed { start: ms, end: me, feed: self.feed_mm },
                );
            }
            Motion::Cw | Motion::Ccw => {
                let cw = m == Motion::Cw;
                if self.feed == 0.0 {
                    return Err((mcol, ErrorKind::ZeroFeed(if cw { 2 } else { 3 })));
                }
                let (f, s, ax) = self.plane.axes();
                let get = |p: &Pose, k: usize| p.get(k).copied().unwrap_or(0.0);
                let turns = match b.p {
                    None => 1,
                    Some(p) => {
                        let r = p.round();
                        if (p - r).abs() > 0.0001 || !(1.0..=1e6).contains(&r) {
                            return Err((mcol, ErrorKind::ArcBadTurns));
                        }
                        // 1..=1e6, exact.
                        r as i32
                    }
                };
                let st = (get(&start, f), get(&start, s));
                let en = (get(&end, f), get(&end, s));
                let centre = if let Some(r) = b.r {
                    if b.ijk.iter().any(Option::is_some) {
                        return Err((mcol, ErrorKind::ArcMixedFormat));
                    }
                    arc::centre_r(self.units, st, en, r, cw).map_err(|k| (mcol, k))?
                } else {
                    // I, J, K index = X, Y, Z index.
                    if let Some(bad) = (0..3).find(|&k| k == ax && b.ijk.get(k).copied().flatten().is_some())
                    {
                        let name = match self.plane {
                            Plane::Xy => "XY",
                            Plane::Xz => "XZ",
                            Plane::Yz => "YZ",
                        };
                        return Err((
                            mcol,
                            ErrorKind::ArcWrongCentreWord(char::from(b'I' + bad as u8), name),
                        ));
                    }
                    if !b.ijk.iter().any(Option::is_some) {
                        return Err((mcol, ErrorKind::ArcMissingCentre));
                    }
                    let ci = b.ijk.get(f).copied().flatten().unwrap_or(0.0);
                    let cj = b.ijk.get(s).copied().flatten().unwrap_or(0.0);
                    arc::centre_ijk(self.units, st, en, (ci, cj), self.arc_absolute).map_err(|k| (mcol, k))?
                };
                let rotation = if cw { -turns } else { turns };
                let arcf = ArcFeed {
                    first_end: en.0,
                    second_end: en.1,
                    first_centre: centre.0,
                    second_centre: centre.1,
                    rotation,
                    axis_end: get(&end, ax),
                    a: get(&end, 3),
                    b: get(&end, 4),
                    c: get(&end, 5),
                };
                let mut cpose = start;
                if let Some(v) = cpose.get_mut(f) {
                    *v = centre.0;
                }
                if let Some(v) = cpose.get_mut(s) {
                    *v = centre.1;
                }
                let mc = self.to_machine(&cpose);
                self.emit_move(
                    Canon::ArcFeed(arcf),
                    MachineMove::Arc {
                        start: ms,
                        end: me,
                        centre: [get(&mc, 0), get(&mc, 1), get(&mc, 2)],
                        plane: self.plane,
                        rotation,
                        feed: self.feed_mm,
                    },
                );
            }
        }
        self.pos = end;
        Ok(())
    }

    fn chain_next(&self, mut i: usize, stop: &[OKind]) -> Option<usize> {
        loop {
            i = self.onext.get(i).copied().flatten()?;
            if self.okind.get(i).copied().flatten().is_some_and(|k| stop.contains(&k)) {
                return Some(i);
            }
        }
    }

    fn chain_prev(&self, mut i: usize, stop: &[OKind]) -> Option<usize> {
        loop {
            i = self.oprev.get(i).copied().flatten()?;
            if self.okind.get(i).copied().flatten().is_some_and(|k| stop.contains(&k)) {
                return Some(i);
            }
        }
    }

    fn cond(&self, o: &crate::parse::OWord) -> KResult<bool> {
        let e = o.args.first().ok_or((o.col, ErrorKind::OWord("condition missing".into())))?;
        Ok(eval_at(&self.params, e, o.col)? != 0.0)
    }

    fn oerr(col: u32, msg: &str) -> (u32, ErrorKind) {
        (col, ErrorKind::OWord(msg.to_owned()))
    }

    /// Is the `while` at `i` the tail of a do-while loop?
    fn is_do_tail(&self, i: usize) -> Option<usize> {
        self.chain_prev(i, &[OKind::Do, OKind::While, OKind::EndWhile, OKind::Sub, OKind::If])
            .filter(|&j| self.okind.get(j).copied().flatten() == Some(OKind::Do))
    }

    fn execute_oword(&mut self, here: usize, o: &crate::parse::OWord) -> KResult<()> {
        let col = o.col;
        match o.kind {
            OKind::Sub => {
                let end = self
                    .chain_next(here, &[OKind::EndSub])
                    .ok_or_else(|| Self::oerr(col, "sub without endsub"))?;
                self.pc = end + 1;
            }
            OKind::EndSub | OKind::Return => {
                if let Some(e) = o.args.first() {
                    let v = eval_at(&self.params, e, col)?;
                    self.params.set_named("_value", v);
                }
                let frame = self
                    .calls
                    .pop()
                    .ok_or_else(|| Self::oerr(col, "endsub/return outside a subroutine call"))?;
                self.params.frames.pop();
                self.pc = frame.return_pc;
            }
            OKind::Call => {
                let sub = *self.subs.get(&o.name).ok_or((col, ErrorKind::UnknownSub(o.name.clone())))?;
                if self.calls.len() >= self.config.max_call_depth {
                    return Err((col, ErrorKind::CallDepth(self.config.max_call_depth)));
                }
                let mut frame = crate::expr::Frame::default();
                for (k, a) in o.args.iter().enumerate() {
                    let v = eval_at(&self.params, a, col)?;
                    match frame.locals.get_mut(k) {
                        Some(slot) => *slot = v,
                        None => return Err(Self::oerr(col, "more than 30 call arguments")),
                    }
                }
                self.params.frames.push(frame);
                self.calls.push(CallFrame { return_pc: here + 1 });
                self.pc = sub + 1;
            }
            OKind::If => {
                if !self.cond(o)? {
                    let mut j = here;
                    loop {
                        j = self
                            .chain_next(j, &[OKind::ElseIf, OKind::Else, OKind::EndIf])
                            .ok_or_else(|| Self::oerr(col, "if without endif"))?;
                        match self.okind.get(j).copied().flatten() {
                            Some(OKind::ElseIf) => {
                                let taken = match self.parsed.get(j).and_then(|p| p.as_deref()) {
                                    Some(Ok(Line { oword: Some(eo), .. })) => self.cond(eo)?,
                                    _ => false,
                                };
                                if taken {
                                    break;
                                }
                            }
                            _ => break,
                        }
                    }
                    self.pc = j + 1;
                }
            }
            OKind::ElseIf | OKind::Else => {
                let end = self
                    .chain_next(here, &[OKind::EndIf])
                    .ok_or_else(|| Self::oerr(col, "else without endif"))?;
                self.pc = end + 1;
            }
            OKind::EndIf | OKind::Do => {}
            OKind::While => {
                if let Some(d) = self.is_do_tail(here) {
                    if self.cond(o)? {
                        self.pc = d + 1;
                    }
                } else if !self.cond(o)? {
                    let end = self
                        .chain_next(here, &[OKind::EndWhile])
                        .ok_or_else(|| Self::oerr(col, "while without endwhile"))?;
                    self.pc = end + 1;
                }
            }
            OKind::EndWhile => {
                let head = self
                    .chain_prev(here, &[OKind::While])
                    .ok_or_else(|| Self::oerr(col, "endwhile without while"))?;
                self.pc = head;
            }
            OKind::Break => {
                let end = self
                    .chain_next(here, &[OKind::EndWhile, OKind::While])
                    .ok_or_else(|| Self::oerr(col, "break outside a loop"))?;
                self.pc = end + 1;
            }
            OKind::Continue => {
                let back = self
                    .chain_prev(here, &[OKind::While, OKind::Do])
                    .ok_or_else(|| Self::oerr(col, "continue outside a loop"))?;
                if self.okind.get(back).copied().flatten() == Some(OKind::Do) {
                    let tail = self
                        .chain_next(here, &[OKind::While])
                        .ok_or_else(|| Self::oerr(col, "do without while"))?;
                    self.pc = tail;
                } else {
                    self.pc = back;
                }
            }
        }
        Ok(())
    }
}

fn ex_value(array: u8, index: u8, v: f64) -> Result<Canon, ErrorKind> {
    let range = |lo: f64, hi: f64| -> Result<f64, ErrorKind> {
        let r = v.round();
        if (v - r).abs() > 0.0001 || r < lo || r > hi || !r.is_finite() {
            return Err(ErrorKind::ExternalRange { array: char::from(array), value: v });
        }
        Ok(r)
    };
    // Each cast is of a rounded value checked to lie in the target type's range.
    let (arr, value) = match array {
        b'B' => (ExArray::B, ExValue::B(range(-128.0, 127.0)? as i8)),
        b'W' => (ExArray::W, ExValue::W(range(-32768.0, 32767.0)? as i16)),
        b'L' => (ExArray::L, ExValue::L(range(-2_147_483_648.0, 2_147_483_647.0)? as i32)),
        _ => {
            if !v.is_finite() || v.abs() > f64::from(f32::MAX) {
                return Err(ErrorKind::ExternalRange { array: 'F', value: v });
            }
            (ExArray::F, ExValue::F(v as f32))
        }
    };
    Ok(Canon::ExternalParameter { array: arr, index, value })
}

impl Iterator for Interpreter<'_> {
    type Item = Result<CanonCall, GcodeError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.out.is_empty() {
            if let Err(e) = self.step() {
                return Some(Err(e));
            }
        }
        self.out.pop_front().map(Ok)
    }
}

/// Interprets a whole program with the default configuration.
pub fn interpret(src: &str) -> Result<Vec<CanonCall>, GcodeError> {
    Interpreter::new(src).collect()
}

/// Interprets a whole program with `config`.
pub fn interpret_with(src: &str, config: InterpreterConfig) -> Result<Vec<CanonCall>, GcodeError> {
    Interpreter::with_config(src, config).collect()
}
