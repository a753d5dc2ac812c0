//! The executor: streams one set-point per cycle along the planned path.
//!
//! The forward pass of the look-ahead is done online, in continuous time: within each cycle
//! the path speed follows a piecewise-constant acceleration — speed up at the piece's
//! tangential limit towards the cap (feed × override, axis caps), cruise, or slow down at
//! that limit along the braking curve `v² = vx² + 2 a d` to the exit limit the planner
//! computed — sub-stepped exactly at every event (piece boundary, cap reached, braking curve
//! met). This is the bang-bang (trapezoidal) profile of the classic planners, while feed
//! hold, stop and override changes act at once. Set-points are exact samples of this
//! profile evaluated on the piece geometry, so each axis' velocity and acceleration are the
//! projections of the path's, and their finite differences stay within the limits the
//! profile respects at every instant.

use crate::config::Config;
use crate::coupling::{Coupling, CouplingState, Recouple};
use crate::error::{CommandError, ConfigError, PushError};
use crate::item::PathItem;
use crate::piece::{Marker, Piece};
use crate::planner::{Planner, MAX_OVERRIDE};
use crate::vector::scale;
use std::collections::VecDeque;

mod motion;
mod types;

pub use types::{Event, ExecState, Setpoint};

/// Distance (units) under which a stop point counts as reached.
const SNAP: f64 = 1e-7;
/// Distance (units) under which the end of a piece counts as reached.
const EPS_X: f64 = 1e-12;
/// Speed (units/s) under which the path counts as at rest.
const EPS_V: f64 = 1e-6;
/// Pieces searched ahead for a reachable block end in single-block mode.
const BLOCK_STOP_SCAN: usize = 4096;
/// Bound on the sub-steps of one cycle.
const MAX_SUBSTEPS: usize = 10_000;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Mode {
    Run,
    Hold,
    Stop,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Wait {
    Ack(u16),
    Dwell(f64),
    CycleStart,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum MarkerState {
    None,
    Announced(u64),
    Passed(u64),
}

/// Block buffer, planner and executor of one CNC system.
#[derive(Debug, Clone)]
pub struct Executor<const N: usize> {
    planner: Planner<N>,
    coupling: Coupling<N>,
    cur: usize,
    x: f64,
    v: f64,
    mode: Mode,
    reverse: bool,
    wait: Option<Wait>,
    marker: MarkerState,
    single_block: bool,
    sb_stop: Option<u64>,
    rev_vx: Vec<f64>,
    events: VecDeque<Event>,
    rest: [f64; N],
    time: f64,
}

impl<const N: usize> Executor<N> {
    /// Executor at rest at `start` (virtual and real axes).
    pub fn new(cfg: Config<N>, start: [f64; N]) -> Result<Self, ConfigError> {
        let planner = Planner::new(cfg, start)?;
        Ok(Self {
            coupling: Coupling::new(cfg.axes, start),
            planner,
            cur: 0,
            x: 0.0,
            v: 0.0,
            mode: Mode::Run,
            reverse: false,
            wait: None,
            marker: MarkerState::None,
            single_block: false,
            sb_stop: None,
            rev_vx: Vec::new(),
            events: VecDeque::new(),
            rest: start,
            time: 0.0,
        })
    }

    /// The planner (block buffer).
    pub fn planner(&self) -> &Planner<N> {
        &self.planner
    }

    /// The coupling.
    pub fn coupling(&self) -> &Coupling<N> {
        &self.coupling
    }

    /// Appends an item (see [`Planner::push`]).
    pub fn push(&mut self, line: u32, item: PathItem<N>) -> Result<(), PushError> {
        if self.mode == Mode::Stop {
            return Err(PushError::Stopping);
        }
        self.planner.push(line, item)
    }

    /// Ends the program: the last line is planned to stop at its end.
    pub fn finish(&mut self) {
        self.planner.finish();
    }

    /// True while the decoder must wait for a decoder synchronisation point.
    pub fn decoder_blocked(&self) -> bool {
        self.planner.awaiting_sync().is_some()
    }

    /// Next event, oldest first.
    pub fn poll_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    /// Current path position (virtual axes).
    pub fn path_position(&self) -> [f64; N] {
        match self.piece(self.cur) {
            Some(p) => p.position(self.x),
            None => self.rest,
        }
    }

    /// Current path speed.
    pub fn path_speed(&self) -> f64 {
        self.v
    }

    /// Feed hold: decelerate along the path within the limits and stay there.
    pub fn feed_hold(&mut self) {
        if self.mode == Mode::Run {
            self.mode = Mode::Hold;
            if self.v == 0.0 {
                self.reverse = false;
                self.events.push_back(Event::Held);
            }
        }
    }

    /// Cycle start: resume after a hold, a single-block stop or backward motion (forwards).
    pub fn cycle_start(&mut self) -> Result<(), CommandError> {
        self.require_coupled("cycle_start")?;
        if self.mode == Mode::Stop {
            return Err(CommandError::NotAtRest { command: "cycle_start", state: "stopping" });
        }
        if self.wait == Some(Wait::CycleStart) {
            self.wait = None;
        }
        if self.reverse {
            if self.v > 0.0 {
                return Err(CommandError::NotAtRest { command: "cycle_start", state: "reversing" });
            }
            self.reverse = false;
        }
        if self.v == 0.0 {
            // After backward motion the pieces ahead were planned long ago: plan them again.
            self.planner.set_cursor(self.cur);
            self.planner.replan_all();
        }
        self.mode = Mode::Run;
        Ok(())
    }

    /// Stop: decelerate along the path, then flush the buffer (the decoder starts again
    /// from the stop position).
    pub fn stop(&mut self) {
        self.mode = Mode::Stop;
    }

    /// Feed override, `0.0..=2.0` (1.0 = 100 %); rapids are not scaled.
    pub fn set_override(&mut self, ovr: f64) -> Result<(), CommandError> {
        if !(ovr.is_finite() && (0.0..=MAX_OVERRIDE).contains(&ovr)) {
            return Err(CommandError::Value { what: "feed override", value: ovr });
        }
        self.planner.set_override(ovr);
        tracing::debug!(ovr, "feed override");
        Ok(())
    }

    /// Single-block mode: stop at the end of every block (the first one that can still be
    /// reached within the deceleration limits when switched on while moving).
    pub fn set_single_block(&mut self, on: bool) {
        self.single_block = on;
        if !on {
            self.clear_block_stop();
        }
    }

    /// Acknowledges M-function `number`; true if the path was waiting for it.
    pub fn acknowledge(&mut self, number: u16) -> bool {
        if self.wait == Some(Wait::Ack(number)) {
            self.wait = None;
            if let MarkerState::Announced(g) = self.marker {
                self.marker = MarkerState::Passed(g);
            }
            true
        } else {
            false
        }
    }

    /// Backward motion along the executed path (from a hold or block stop), down to the
    /// oldest retained piece or the previous stopping marker; `feed_hold` stops it and
    /// `cycle_start` continues forwards.
    pub fn backward(&mut self) -> Result<(), CommandError> {
        self.require_coupled("backward")?;
        if self.v > 0.0 || self.mode == Mode::Stop || matches!(self.wait, Some(Wait::Ack(_) | Wait::Dwell(_)))
        {
            return Err(CommandError::NotAtRest { command: "backward", state: self.state().name() });
        }
        self.wait = None;
        self.clear_block_stop();
        self.compute_reverse_limits();
        self.reverse = true;
        self.mode = Mode::Run;
        Ok(())
    }

    /// Releases the virtual/real coupling (path at rest).
    pub fn release_coupling(&mut self) -> Result<(), CommandError> {
        if self.v > 0.0 || (self.mode == Mode::Run && self.wait.is_none() && !self.at_end()) {
            return Err(CommandError::NotAtRest { command: "release_coupling", state: self.state().name() });
        }
        self.coupling.release()
    }

    /// Jogs real axis `axis` at `velocity` while the coupling is released.
    pub fn jog(&mut self, axis: usize, velocity: f64) -> Result<(), CommandError> {
        self.coupling.jog(axis, velocity)
    }

    /// Recouples the real axes (see [`Recouple`]).
    pub fn recouple(&mut self, how: Recouple) -> Result<(), CommandError> {
        let at = self.path_position();
        self.coupling.recouple(how, &at)
    }

    /// Executor state.
    pub fn state(&self) -> ExecState {
        if self.coupling.state() == CouplingState::Recoupling {
            return ExecState::Recoupling;
        }
        match self.mode {
            Mode::Stop => ExecState::Stopping,
            Mode::Hold if self.v > 0.0 => ExecState::Holding,
            Mode::Hold => ExecState::Held,
            Mode::Run => match self.wait {
                Some(Wait::Ack(m)) => ExecState::WaitingAck(m),
                Some(Wait::Dwell(_)) => ExecState::Dwelling,
                Some(Wait::CycleStart) => ExecState::BlockStop,
                None if self.reverse => ExecState::Reversing,
                None if self.v > 0.0 || !self.at_end() => ExecState::Running,
                None => ExecState::Idle,
            },
        }
    }

    /// Advances one cycle of `dt` seconds and returns its set-point.
    pub fn tick(&mut self, dt: f64) -> Setpoint<N> {
        let dt = if dt.is_finite() && dt > 0.0 { dt } else { 0.0 };
        self.time += dt;
        if let Some(Wait::Dwell(t)) = self.wait {
            let left = t - dt;
            if left <= 1e-12 {
                self.wait = None;
                if let MarkerState::Announced(g) = self.marker {
                    self.marker = MarkerState::Passed(g);
                }
            } else {
                self.wait = Some(Wait::Dwell(left));
            }
        }
        if self.mode == Mode::Run && !self.reverse && self.wait.is_none() {
            self.process_markers();
        }
        let v_before = self.v;
        let moving_allowed = match self.mode {
            Mode::Run => self.wait.is_none(),
            Mode::Hold | Mode::Stop => true,
        };
        if self.single_block
            && self.mode == Mode::Run
            && !self.reverse
            && moving_allowed
            && self.sb_stop.is_none()
        {
            self.plan_block_stop();
        }
        if dt > 0.0 && moving_allowed && self.coupling.state() == CouplingState::Coupled {
            self.integrate(dt);
        }
        if self.v == 0.0 {
            match self.mode {
                Mode::Stop => self.flush(),
                Mode::Hold if v_before > 0.0 || self.reverse => {
                    self.reverse = false;
                    self.events.push_back(Event::Held);
                }
                _ => {}
            }
        }
        if !self.reverse {
            // (Not while reversing: the backward limits are indexed by piece.)
            let dropped = self.planner.trim_history();
            self.cur -= dropped.min(self.cur);
        }
        self.planner.set_cursor(self.cur);
        let (line, block, tangent) = match self.piece(self.cur) {
            Some(p) => (p.line, p.block, p.tangent(self.x)),
            None => (0, 0, [0.0; N]),
        };
        let path_positions = self.path_position();
        let signed = if self.reverse { -self.v } else { self.v };
        let path_vel = scale(signed, &tangent);
        let (positions, velocities) = self.coupling.tick(&path_positions, &path_vel, dt);
        Setpoint {
            positions,
            velocities,
            path_positions,
            path_speed: self.v,
            line,
            block,
            state: self.state(),
            coupling: self.coupling.state(),
            time: self.time,
        }
    }

    fn require_coupled(&self, command: &'static str) -> Result<(), CommandError> {
        match self.coupling.state() {
            CouplingState::Coupled => Ok(()),
            other => Err(CommandError::NotCoupled { command, coupling: other.name() }),
        }
    }

    fn piece(&self, j: usize) -> Option<&Piece<N>> {
        self.planner.pieces().get(j)
    }

    fn global(&self, j: usize) -> u64 {
        self.planner.base() + j as u64
    }

    /// True when no motion is left ahead.
    fn at_end(&self) -> bool {
        let len = self.planner.pieces().len();
        if len == 0 {
            return true;
        }
        if self.cur + 1 < len {
            return false;
        }
        match self.piece(self.cur) {
            Some(p) if p.marker().is_some() => self.marker == MarkerState::Passed(self.global(self.cur)),
            Some(p) => self.x >= p.length,
            None => true,
        }
    }

    /// Handles the markers at the current point (forward, at rest or passing).
    fn process_markers(&mut self) {
        loop {
            let g = self.global(self.cur);
            let Some(p) = self.piece(self.cur) else { return };
            let Some(marker) = p.marker() else { return };
            let line = p.line;
            if self.marker != MarkerState::Passed(g) {
                match marker {
                    Marker::MFunction { number, sync: true } => {
                        if self.marker != MarkerState::Announced(g) {
                            self.events.push_back(Event::MFunction { number, sync: true, line });
                            self.marker = MarkerState::Announced(g);
                            self.wait = Some(Wait::Ack(number));
                        }
                        return;
                    }
                    Marker::Dwell { seconds: t } => {
                        if self.marker != MarkerState::Announced(g) {
                            self.marker = MarkerState::Announced(g);
                            self.wait = Some(Wait::Dwell(t));
                        }
                        return;
                    }
                    other => {
                        self.announce_passing(other, line);
                        self.marker = MarkerState::Passed(g);
                    }
                }
            }
            if self.cur + 1 < self.planner.pieces().len() {
                self.cur += 1;
                self.x = 0.0;
            } else {
                return;
            }
        }
    }

    fn announce_passing(&mut self, marker: Marker, line: u32) {
        match marker {
            Marker::MFunction { number, sync } => {
                self.events.push_back(Event::MFunction { number, sync, line });
            }
            Marker::ExternalParameter { array, index, value } => {
                self.events.push_back(Event::ExternalParameter { array, index, value, line });
            }
            Marker::DecoderSync => {
                self.planner.sync_reached();
                self.events.push_back(Event::DecoderSyncReached { line });
            }
            Marker::Dwell { .. } | Marker::ExactStop => {}
        }
    }

    fn flush(&mut self) {
        let at = self.path_position();
        self.planner.clear(at);
        self.rest = at;
        self.cur = 0;
        self.x = 0.0;
        self.mode = Mode::Run;
        self.reverse = false;
        self.wait = None;
        self.sb_stop = None;
        self.marker = MarkerState::None;
        self.events.push_back(Event::Stopped);
        tracing::debug!(position = ?at, "stop completed, block buffer flushed");
    }
}
