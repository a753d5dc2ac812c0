//! Motion along the path: the continuous-time integrator, piece transitions, single-block
//! stops and the limits for backward motion.

use super::{Event, Executor, MarkerState, Mode, Wait, BLOCK_STOP_SCAN, EPS_V, EPS_X, MAX_SUBSTEPS, SNAP};

impl<const N: usize> Executor<N> {
    /// Continuous-time motion over `dt`: within the cycle the path speed follows a
    /// piecewise-constant acceleration (speed up at the piece's limit towards the cap, cruise,
    /// or slow down at the piece's limit along the braking curve `v² = vx² + 2 a d` to the
    /// piece's exit limit), sub-stepped exactly at every event (piece boundary, cap reached,
    /// braking curve met). Set-points are samples of this profile, so their finite
    /// differences stay within the limits the profile respects at every instant.
    pub(super) fn integrate(&mut self, dt: f64) {
        let ovr = self.planner.feed_override();
        let running = self.mode == Mode::Run;
        let mut left = dt;
        for _ in 0..MAX_SUBSTEPS {
            if left <= 1e-12 {
                break;
            }
            let Some(p) = self.piece(self.cur).copied() else {
                self.v = 0.0;
                break;
            };
            let (d, vx) = if self.reverse {
                (self.x, self.rev_vx.get(self.cur).copied().unwrap_or(0.0))
            } else if running {
                (p.length - self.x, p.vx_hard.min(p.vx_soft))
            } else {
                (p.length - self.x, p.vx_hard)
            };
            if d <= EPS_X || p.marker().is_some() {
                let moved = if self.reverse { self.next_reverse() } else { self.next_forward() };
                if !moved {
                    break;
                }
                continue;
            }
            let a = p.accel;
            let target = if running { p.soft_cap(ovr) } else { 0.0 };
            let v = self.v;
            let curve = (vx * vx + 2.0 * a * d).sqrt();
            let on_curve = v >= curve - 1e-9 * (1.0 + curve);
            // Time until the braking curve is met, when speeding up or cruising.
            let meet = if v < target - 1e-12 {
                (-v + (0.5 * (v * v + vx * vx + 2.0 * a * d)).sqrt()) / a
            } else if target > 0.0 {
                (d - (target * target - vx * vx) / (2.0 * a)) / target
            } else {
                f64::INFINITY
            };
            let mut tau = left;
            let mut hits_end = false;
            let acc;
            if on_curve || v > target + 1e-12 || meet <= 1e-12 {
                acc = -a;
                if v > target {
                    tau = tau.min((v - target) / a);
                }
                let stop_d = v * v / (2.0 * a);
                if stop_d >= d {
                    let t_end = (v - (v * v - 2.0 * a * d).max(0.0).sqrt()) / a;
                    if t_end <= tau {
                        tau = t_end;
                        hits_end = true;
                    }
                } else if vx <= 0.0 && d - stop_d < SNAP && v / a <= tau {
                    // Arrives at rest (to rounding) at the end: snap onto it.
                    tau = v / a;
                    hits_end = true;
                }
            } else if v < target - 1e-12 {
                acc = a;
                tau = tau.min((target - v) / a).min(meet);
                let t_end = (-v + (v * v + 2.0 * a * d).sqrt()) / a;
                if t_end <= tau {
                    tau = t_end;
                    hits_end = true;
                }
            } else {
                acc = 0.0;
                self.v = target;
                if target <= 0.0 {
                    break; // at rest and told to stay
                }
                tau = tau.min(meet);
                let t_end = d / target;
                if t_end <= tau {
                    tau = t_end;
                    hits_end = true;
                }
            }
            let v0 = self.v;
            let dx = (v0 * tau + 0.5 * acc * tau * tau).clamp(0.0, d);
            self.v = (v0 + acc * tau).max(0.0);
            let step = if hits_end { d } else { dx };
            if self.reverse {
                self.x = (self.x - step).max(0.0);
            } else {
                self.x = (self.x + step).min(p.length);
            }
            left -= tau;
            if hits_end && vx <= 0.0 {
                self.v = 0.0; // arrived at a planned stop (rounding aside)
            }
            if self.v < EPS_V && acc < 0.0 {
                self.v = 0.0;
                if !hits_end && target <= 0.0 {
                    break; // held
                }
            }
        }
    }

    /// Moves to the next piece forwards; false when the path must stay here.
    pub(super) fn next_forward(&mut self) -> bool {
        let len = self.planner.pieces().len();
        if let Some(p) = self.piece(self.cur).copied() {
            if p.stop_after && p.marker().is_none() && self.v <= EPS_V {
                // Single-block stop at the end of this block.
                self.v = 0.0;
                self.planner.set_stop_after(self.cur, false);
                self.sb_stop = None;
                self.wait = Some(Wait::CycleStart);
                self.events.push_back(Event::BlockStop { line: p.line });
                tracing::debug!(line = p.line, "single-block stop");
                return false;
            }
            if let Some(m) = p.marker() {
                if self.marker != MarkerState::Passed(self.global(self.cur)) {
                    if m.stops() {
                        self.v = 0.0;
                        return false;
                    }
                    self.announce_passing(m, p.line);
                    self.marker = MarkerState::Passed(self.global(self.cur));
                }
            } else {
                self.x = p.length;
            }
        }
        if self.cur + 1 >= len {
            self.v = 0.0;
            return false;
        }
        self.cur += 1;
        self.x = 0.0;
        true
    }

    /// Moves to the previous piece backwards; false when backward motion ends here.
    pub(super) fn next_reverse(&mut self) -> bool {
        if self.cur == 0 {
            self.x = 0.0;
            self.v = 0.0;
            self.mode = Mode::Hold;
            return false;
        }
        let prev = self.cur - 1;
        let Some(q) = self.piece(prev).copied() else { return false };
        self.cur = prev;
        match q.marker() {
            None => {
                self.x = q.length;
                true
            }
            Some(m) => {
                self.events.push_back(Event::Reversed { marker: m, line: q.line });
                self.marker = MarkerState::Passed(self.global(prev));
                self.x = 0.0;
                if m.stops() {
                    self.v = 0.0;
                    self.mode = Mode::Hold;
                    false
                } else {
                    true
                }
            }
        }
    }

    /// Plans a single-block stop at the first block end still reachable at rest.
    pub(super) fn plan_block_stop(&mut self) {
        let Some(p) = self.piece(self.cur) else { return };
        let mut amin = p.accel;
        let mut dist = p.length - self.x;
        let mut prev_block = p.block;
        let len = self.planner.pieces().len().min(self.cur + BLOCK_STOP_SCAN);
        for j in self.cur + 1..len {
            let Some(q) = self.piece(j) else { return };
            if q.block != prev_block && dist > SNAP && self.v * self.v <= 2.0 * amin * dist {
                // A block that ends in markers (an exact stop at a reversal, M-functions, a
                // dwell) stops before the first of them: after its last motion piece.
                let mut end = j - 1;
                while end > self.cur && self.piece(end).is_some_and(|e| e.marker().is_some()) {
                    end -= 1;
                }
                if self.piece(end).is_some_and(|e| e.marker().is_none()) {
                    self.planner.set_stop_after(end, true);
                    self.sb_stop = Some(self.global(end));
                    return;
                }
            }
            prev_block = q.block;
            amin = amin.min(q.accel);
            dist += q.length;
        }
    }

    pub(super) fn clear_block_stop(&mut self) {
        if let Some(g) = self.sb_stop.take() {
            if let Some(local) = g.checked_sub(self.planner.base()) {
                self.planner.set_stop_after(local as usize, false);
            }
        }
    }

    /// Exit limits for backward motion: `rev_vx[j]` bounds the speed at the start of piece
    /// `j`, with rest at the oldest piece and at every stopping marker.
    pub(super) fn compute_reverse_limits(&mut self) {
        let ovr = self.planner.feed_override();
        self.rev_vx.clear();
        let mut exit = 0.0_f64;
        for j in 0..=self.cur {
            self.rev_vx.push(exit);
            if let Some(p) = self.piece(j) {
                let cap = if p.marker().is_some_and(|m| m.stops()) { 0.0 } else { p.soft_cap(ovr) };
                exit = p.entry_limit(exit, cap);
            }
        }
    }
}
