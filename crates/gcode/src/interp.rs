//! The interpreter: executes blocks in LinuxCNC's order of execution and yields
//! canonical calls one by one (a pull-based, sans-IO iterator).
//!
//! Order within a block: O-word, comment/message, parameter assignments (all values on a
//! line are read first, as in LinuxCNC), `EX` writes, feed mode (G93-G95), F, G96/G97, S, T,
//! M62-M68 (LinuxCNC dialect), M6/M61,
//! M3/M4/M5, M7/M8/M9, the seed's M-functions, G4, G17-G19, G20/G21, G40-G42, G43/G43.1/G49,
//! G54-G59.3, G61/G61.1/G64,
//! G90/G91, G90.1/G91.1, G98/G99, G10/G28/G30/G52/G92.x, motion (G0-G3 with G53, canned cycles
//! G73/G81/G82/G83/G85/G89, G80), M60 (LinuxCNC dialect), M0/M1/M2/M30.
//!
//! Submodules: `modal` (a block's modal changes), `motion` (moves and arcs),
//! `cutter_comp` (G40-G42 and its queue of held-back moves), `cycles`
//! (canned cycles and path control), `drilling_technology` (canned cycles as the seed's
//! drilling jobs), `feed` (G93-G97), `io` (LinuxCNC's M60-M68),
//! `reference` (G28/G30, G52), `rotation` (G10 L2 R), `tooling` (T, M6, G43/G49), `oword`
//! (O-word control flow), `system_params` (LinuxCNC's read-only parameters and the
//! `(DEBUG,...)` text). One line at a time is parsed into a reused [`Line`]; only
//! O-word lines keep their parse (loops and calls come back to them).

mod cutter_comp;
mod cycles;
mod drilling_technology;
mod feed;
mod io;
mod modal;
mod motion;
mod oword;
mod reference;
mod rotation;
mod system_params;
mod tooling;

use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

pub use self::drilling_technology::CycleOutput;
pub use self::io::MCodeDialect;
use self::motion::Motion;
use self::oword::{index_owords, is_oword_line, CallFrame, OLine};
use crate::block::{read_block, Block};
use crate::canon::{Canon, CanonCall, ExArray, ExValue, MachineMove, Plane, Pose, Units};
use crate::error::{ErrorKind, GcodeError, KResult};
use crate::params::{self, param_index, Params};
use crate::parse::{Line, Remark, Target};

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
    /// The tool table (T, M6, G43 H look tools up in it; empty: only T0).
    pub tools: Vec<crate::tools::Tool>,
    /// A flag another thread (a timer, a user) sets to stop the interpreter: it is read
    /// before every line (one relaxed atomic load), and the interpreter then ends with
    /// [`ErrorKind::Cancelled`] at the line it was about to execute. `None`: not
    /// cancellable.
    pub cancel: Option<CancelFlag>,
    /// What M60-M68 mean: the seed's M-functions (the default) or LinuxCNC's pallet,
    /// tool and I/O codes (see [`MCodeDialect`]).
    pub m_codes: MCodeDialect,
    /// How canned cycles reach the machine: LinuxCNC's moves (the default) or the seed's
    /// drilling technology (see [`CycleOutput`]).
    pub cycles: CycleOutput,
}

/// A shared cancellation flag for [`InterpreterConfig::cancel`] (the interpreter only reads
/// it: it stays sans-IO, with no clock or thread of its own).
#[derive(Debug, Clone, Default)]
pub struct CancelFlag(Arc<AtomicBool>);

impl CancelFlag {
    /// A new, unset flag.
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets the flag: interpreters holding it stop at their next read.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    /// True once [`CancelFlag::cancel`] was called.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

impl PartialEq for CancelFlag {
    /// Two flags are equal when they are the same flag.
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

impl Default for InterpreterConfig {
    fn default() -> Self {
        Self {
            async_m_functions: Vec::new(),
            block_delete: false,
            require_program_end: true,
            max_steps: 100_000_000,
            max_call_depth: 64,
            tools: Vec::new(),
            cancel: None,
            m_codes: MCodeDialect::Seed,
            cycles: CycleOutput::Motion,
        }
    }
}

/// The work-offset parameter base for coordinate system `k` (0 = G54): 5221 + 20 k.
fn origin_param(k: usize) -> usize {
    5221 + 20 * k
}

/// A pull-based interpreter over one program text.
pub struct Interpreter<'a> {
    lines: Vec<&'a str>,
    /// The O-word lines, by line index (pre-scanned).
    olines: HashMap<usize, OLine>,
    subs: HashMap<String, usize>,
    config: InterpreterConfig,
    out: VecDeque<CanonCall>,
    pc: usize,
    steps: u64,
    done: bool,
    percent_open: bool,
    seen_content: bool,
    calls: Vec<CallFrame>,
    /// Iterations left of each running `repeat` loop, by its line and call depth.
    repeats: HashMap<(usize, usize), u64>,
    params: Params,
    /// Reused buffers: the line being executed, the expression stack, the values of the
    /// line's assignments (target index, `None` for a named one) and EX writes.
    scratch: Option<Box<Line>>,
    stack: Vec<f64>,
    assigned: Vec<(Option<usize>, f64)>,
    ex_values: Vec<f64>,
    // Modal state (program units, like LinuxCNC).
    units: Units,
    absolute: bool,
    arc_absolute: bool,
    plane: Plane,
    /// The feed rate (program units per minute or per revolution), the feed mode, the
    /// last F under G93, and the rpm limit under G96.
    feed: f64,
    feed_mode: feed::FeedMode,
    inverse_f: f64,
    css_max_rpm: Option<f64>,
    motion: Option<Motion>,
    pos: Pose,
    coord: usize,
    origins: [Pose; 9],
    g92: Pose,
    /// The active system's XY rotation, degrees (`rotation.rs`).
    rot: f64,
    /// Canned cycles' sticky words and levels, and the path control in force.
    cycles: cycles::CycleState,
    tool: tooling::ToolState,
    /// Cutter radius compensation (G40-G42) and its queue of held-back calls.
    comp: cutter_comp::CompState,
    path: cycles::PathControl,
    /// The last S word, and the spindle (1 clockwise, -1 counter-clockwise, 0 stopped) and
    /// coolant states, for LinuxCNC's `#<_rpm>`, `#<_spindle_on>`, `#<_mist>`...
    rpm: f64,
    spindle: i8,
    mist: bool,
    flood: bool,
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
        let (olines, subs) = index_owords(&lines);
        let mut it = Self {
            olines,
            subs,
            lines,
            config,
            out: VecDeque::new(),
            pc: 0,
            steps: 0,
            done: false,
            percent_open: false,
            seen_content: false,
            calls: Vec::new(),
            repeats: HashMap::new(),
            params: Params::default(),
            scratch: None,
            stack: Vec::new(),
            assigned: Vec::new(),
            ex_values: Vec::new(),
            units: Units::Mm,
            absolute: true,
            arc_absolute: false,
            plane: Plane::Xy,
            feed: 0.0,
            feed_mode: feed::FeedMode::PerMinute,
            inverse_f: 0.0,
            css_max_rpm: None,
            motion: None,
            pos: [0.0; 6],
            coord: 0,
            origins: [[0.0; 6]; 9],
            g92: [0.0; 6],
            rot: 0.0,
            cycles: cycles::CycleState::default(),
            tool: tooling::ToolState::default(),
            comp: cutter_comp::CompState::new(),
            path: cycles::PathControl::default(),
            rpm: 0.0,
            spindle: 0,
            mist: false,
            flood: false,
            cur_line: 0,
            cur_n: None,
        };
        // G54 is active from the start (#5220 = 1, as in LinuxCNC).
        it.params.set(5220, 1.0);
        it.emit(Canon::UseLengthUnits { units: Units::Mm });
        it.emit(Canon::SetG5xOffset { index: 1, offset: [0.0; 6] });
        it.emit(Canon::SetG92Offset { offset: [0.0; 6] });
        it.emit(Canon::SetXyRotation { degrees: 0.0 });
        it.emit(Canon::SetFeedReference);
        it
    }

    /// Lines executed so far (what [`InterpreterConfig::max_steps`] bounds).
    pub fn steps(&self) -> u64 {
        self.steps
    }

    fn emit(&mut self, canon: Canon) {
        let call = CanonCall { line: self.cur_line, n: self.cur_n, canon, machine: None };
        if !self.comp.queue.is_empty() && cutter_comp::is_queued(&call.canon) {
            self.comp.hold(call);
        } else {
            self.out.push_back(call);
        }
    }

    fn emit_move(&mut self, canon: Canon, mut m: MachineMove) {
        // The first move after G40 starts where the compensated tool is.
        if let Some(at) = self.comp.exit_start.take() {
            match &mut m {
                MachineMove::Traverse { start, .. }
                | MachineMove::Feed { start, .. }
                | MachineMove::Arc { start, .. } => *start = at,
            }
        }
        self.out.push_back(CanonCall { line: self.cur_line, n: self.cur_n, canon, machine: Some(m) });
    }

    fn err(&self, (column, kind): (u32, ErrorKind)) -> GcodeError {
        GcodeError::new(self.cur_line, column, kind)
    }

    /// Runs lines until at least one call is queued, the program ends, or an error occurs.
    fn step(&mut self) -> Result<(), GcodeError> {
        while self.out.is_empty() && !self.done {
            self.run_line()?;
        }
        Ok(())
    }

    /// Runs lines until the program ends or an error occurs, queueing every call.
    fn run_to_end(&mut self) -> Result<(), GcodeError> {
        while !self.done {
            self.run_line()?;
        }
        Ok(())
    }

    /// Parses and executes the line at `pc` (or ends the program at the end of the text).
    fn run_line(&mut self) -> Result<(), GcodeError> {
        let Some(text) = self.lines.get(self.pc).copied() else {
            self.done = true;
            if self.config.require_program_end {
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
        if self.config.cancel.as_ref().is_some_and(CancelFlag::is_cancelled) {
            self.done = true;
            self.cur_line = u32::try_from(self.pc + 1).unwrap_or(u32::MAX);
            return Err(self.err((1, ErrorKind::Cancelled(self.steps))));
        }
        let here = self.pc;
        self.cur_line = u32::try_from(here + 1).unwrap_or(u32::MAX);
        let cached =
            if is_oword_line(text) { self.olines.get_mut(&here).and_then(|o| o.parsed.take()) } else { None };
        let r = match cached {
            Some(parsed) => {
                let r = match parsed.as_ref() {
                    Ok(line) => self.execute(line, text),
                    Err(e) => Err(e.clone()),
                };
                // Keep the O-word line: loops and calls come back to it.
                if let Some(o) = self.olines.get_mut(&here) {
                    o.parsed = Some(parsed);
                }
                r
            }
            None => {
                let mut line = self.scratch.take().unwrap_or_default();
                let r = line.parse(text).and_then(|()| self.execute(&line, text));
                self.scratch = Some(line);
                r
            }
        };
        r.map_err(|e| {
            self.done = true;
            self.err(e)
        })
    }

    /// Executes one parsed line (`text` is its source).
    fn execute(&mut self, line: &Line, text: &str) -> KResult<()> {
        let here = self.pc;
        self.pc += 1;
        // Only a line that names a parameter can read them: the others skip the work.
        if text.as_bytes().contains(&b'#') {
            self.publish_system_params();
        }
        if line.percent {
            if self.seen_content || self.percent_open {
                self.done = true;
            } else {
                self.seen_content = true;
            }
            self.percent_open = true;
            return Ok(());
        }
        if line.has_content() {
            self.seen_content = true;
        }
        if line.block_delete && self.config.block_delete {
            return Ok(());
        }
        self.cur_n = line.n;
        if let Some(o) = &line.oword {
            return self.execute_oword(here, line, o);
        }
        let mut block = Block::default();
        read_block(&mut block, line, &self.params, &mut self.stack)?;
        // Values of assignments and EX writes are read before any is applied.
        self.assigned.clear();
        for a in &line.assigns {
            let v = line.eval(&self.params, &mut self.stack, a.value, a.col)?;
            let target = match a.target {
                Target::Numbered(ix) => {
                    let ix = line.eval(&self.params, &mut self.stack, ix, a.col)?;
                    let ix = param_index(ix).map_err(|k| (a.col, k))?;
                    if params::is_read_only(ix) {
                        return Err((a.col, ErrorKind::ReadOnlyParameter(ix)));
                    }
                    Some(ix)
                }
                Target::Named(s, e) => {
                    let name = line.name(s, e);
                    if params::system_index(name).is_some() {
                        return Err((a.col, ErrorKind::ReadOnlyNamedParameter(name.to_owned())));
                    }
                    None
                }
            };
            self.assigned.push((target, v));
        }
        self.ex_values.clear();
        for w in &line.ex {
            let v = line.eval(&self.params, &mut self.stack, w.value, w.col)?;
            self.ex_values.push(v);
        }
        for (a, &(target, v)) in line.assigns.iter().zip(&self.assigned) {
            match (target, a.target) {
                (Some(i), _) => self.params.set(i, v),
                (None, Target::Named(s, e)) => self.params.set_named(line.name(s, e), v),
                (None, Target::Numbered(_)) => {}
            }
        }
        match line.remark(text) {
            Some(Remark::Comment(t)) => self.emit(Canon::Comment { text: t.to_owned() }),
            Some(Remark::Message(t)) => self.emit(Canon::Message { text: t.to_owned() }),
            // LinuxCNC shows a DEBUG text as a message and prints a PRINT text on its
            // console: here a comment, both with the parameters' values in them.
            Some(Remark::Debug(t)) => {
                let text = self.substitute_params(t);
                self.emit(Canon::Message { text });
            }
            Some(Remark::Print(t)) => {
                let text = self.substitute_params(t);
                self.emit(Canon::Comment { text });
            }
            None => {}
        }
        for (k, w) in line.ex.iter().enumerate() {
            let v = self.ex_values.get(k).copied().unwrap_or(0.0);
            let c = ex_value(w.array, w.index, v).map_err(|e| (w.col, e))?;
            self.emit(c);
        }
        self.execute_block(&mut block)
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
    interpret_with(src, InterpreterConfig::default())
}

/// Interprets a whole program with `config` (the same calls as collecting an
/// [`Interpreter`], without the per-call hand-over).
pub fn interpret_with(src: &str, config: InterpreterConfig) -> Result<Vec<CanonCall>, GcodeError> {
    let mut it = Interpreter::with_config(src, config);
    // About one call per line (the reservation is capped: a long program with few calls
    // must not claim memory it will not use); the queue then becomes the result without
    // copying.
    it.out.reserve(it.lines.len().saturating_add(16).min(1 << 20));
    it.run_to_end()?;
    Ok(Vec::from(std::mem::take(&mut it.out)))
}
