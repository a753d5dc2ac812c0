//! The program the simulated juggler's controller runs: what a student loads onto the
//! machine. The simulated MN asks the [`ProgramSelector`] every cycle: a new program is
//! blended in from the present set-points over [`RAMP_IN`], and the supervisor judges the
//! result like any other motion. Like a real controller watching its drives, the program
//! holds while a drive is stopped by the safety function and blends in again afterwards.

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Arc;
use std::time::Duration;

use motus_epl::sim::pdo::{Actual, STATUS_LEASE_STOP, STATUS_QUICK_STOP};
use motus_epl::sim::{CamProgram, MotionProgram};
use motus_safety::RuleSet;
use motus_safety_epl::juggler::{self, Pattern};

/// Which [`Pattern`] the simulated juggler runs; shared by the station (which selects) and
/// the simulated controller (which follows).
#[derive(Debug)]
pub struct ProgramSelector(AtomicU8);

fn index(p: Pattern) -> u8 {
    Pattern::ALL.iter().position(|q| *q == p).and_then(|i| u8::try_from(i).ok()).unwrap_or(0)
}

impl ProgramSelector {
    /// A selector starting with `pattern`.
    #[must_use]
    pub fn new(pattern: Pattern) -> Self {
        Self(AtomicU8::new(index(pattern)))
    }

    /// The selected pattern.
    #[must_use]
    pub fn get(&self) -> Pattern {
        Pattern::ALL.get(usize::from(self.0.load(Ordering::Relaxed))).copied().unwrap_or(Pattern::Juggle)
    }

    /// Selects `pattern` from the next cycle on.
    pub fn set(&self, pattern: Pattern) {
        self.0.store(index(pattern), Ordering::Relaxed);
    }
}

/// How long the controller blends from where the drives are into a cam: after a new program
/// is selected, and when the drives come back from a safety stop.
pub const RAMP_IN: Duration = Duration::from_secs(2);

/// What the controller does.
#[derive(Debug, Clone, PartialEq)]
enum Phase {
    /// Following the cam.
    Run,
    /// A drive stopped on its own (safety lease revoked or expired, quick stop): the
    /// set-points are the drives' actual positions, so nothing chases the cam when the lease
    /// comes back.
    Hold,
    /// Blending into the cam since `since`: from the previous pattern, still running, after
    /// a new selection; from fixed set-points (the drives at rest) after a hold.
    Ramp { since: Duration, from: RampStart },
}

/// Where a ramp starts.
#[derive(Debug, Clone, PartialEq)]
enum RampStart {
    Pattern(Pattern),
    Fixed(Vec<f64>),
}

/// The simulated juggler controller's program: the cam of the selected pattern, held while
/// any drive is stopped by the safety function and blended in again ([`RAMP_IN`]) when they
/// are released or a new pattern is selected, as a machine controller watching its drives
/// does.
pub(crate) struct SelectedCam {
    cams: Vec<CamProgram>,
    selector: Arc<ProgramSelector>,
    running: Pattern,
    phase: Phase,
    actual: Vec<Option<Actual>>,
    last: Vec<i32>,
    cam: Vec<i32>,
    old: Vec<i32>,
}

impl SelectedCam {
    pub(crate) fn new(rules: &RuleSet, selector: Arc<ProgramSelector>) -> Self {
        let running = selector.get();
        Self {
            cams: Pattern::ALL.iter().map(|p| juggler::program(rules, *p)).collect(),
            selector,
            running,
            phase: Phase::Run,
            actual: Vec::new(),
            last: Vec::new(),
            cam: Vec::new(),
            old: Vec::new(),
        }
    }

    fn drives_stopped(&self) -> bool {
        self.actual.iter().flatten().any(|a| a.status & (STATUS_LEASE_STOP | STATUS_QUICK_STOP) != 0)
    }
}

fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

impl MotionProgram for SelectedCam {
    fn setpoints(&mut self, t: Duration, out: &mut [i32]) {
        let n = out.len();
        self.last.resize(n, 0);
        self.actual.resize(n, None);
        if self.drives_stopped() {
            if self.phase != Phase::Hold {
                tracing::info!("juggler controller: drives stopped by the safety function, program held");
            }
            self.phase = Phase::Hold;
            for ((o, last), a) in out.iter_mut().zip(&self.last).zip(&self.actual) {
                *o = a.map_or(*last, |a| a.position);
            }
            self.last.copy_from_slice(out);
            return;
        }
        let selected = self.selector.get();
        if self.phase == Phase::Hold {
            let from = RampStart::Fixed(self.last.iter().map(|p| f64::from(*p)).collect());
            self.phase = Phase::Ramp { since: t, from };
        } else if selected != self.running {
            self.phase = Phase::Ramp { since: t, from: RampStart::Pattern(self.running) };
        }
        self.running = selected;
        let cam = |cams: &mut Vec<CamProgram>, p: Pattern, out: &mut Vec<i32>| {
            out.resize(n, 0);
            if let Some(c) = cams.get_mut(usize::from(index(p))) {
                c.setpoints(t, out);
            }
        };
        cam(&mut self.cams, self.running, &mut self.cam);
        match &self.phase {
            Phase::Ramp { since, from } => {
                let w = smoothstep(t.saturating_sub(*since).as_secs_f64() / RAMP_IN.as_secs_f64());
                let blend = |o: &mut i32, c: i32, f: f64| *o = (f + (f64::from(c) - f) * w).round() as i32;
                match from {
                    RampStart::Fixed(f) => {
                        for ((o, c), f) in out.iter_mut().zip(&self.cam).zip(f) {
                            blend(o, *c, *f);
                        }
                    }
                    RampStart::Pattern(p) => {
                        cam(&mut self.cams, *p, &mut self.old);
                        for ((o, c), f) in out.iter_mut().zip(&self.cam).zip(&self.old) {
                            blend(o, *c, f64::from(*f));
                        }
                    }
                }
                if w >= 1.0 {
                    self.phase = Phase::Run;
                }
            }
            _ => out.copy_from_slice(&self.cam),
        }
        self.last.copy_from_slice(out);
    }

    fn actual(&mut self, drive: usize, actual: &Actual) {
        if drive >= self.actual.len() {
            self.actual.resize(drive + 1, None);
        }
        if let Some(slot) = self.actual.get_mut(drive) {
            *slot = Some(*actual);
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    fn run(cam: &mut SelectedCam, ms: u64) -> [i32; 5] {
        let mut out = [0; 5];
        cam.setpoints(Duration::from_millis(ms), &mut out);
        out
    }

    fn cam_at(rules: &RuleSet, p: Pattern, ms: u64) -> [i32; 5] {
        let mut out = [0; 5];
        juggler::program(rules, p).setpoints(Duration::from_millis(ms), &mut out);
        out
    }

    #[test]
    fn a_new_pattern_is_blended_in_and_then_followed() {
        let rules = RuleSet::from_toml(motus_safety::JUGGLER_TOML).unwrap();
        let selector = Arc::new(ProgramSelector::new(Pattern::Juggle));
        let mut cam = SelectedCam::new(&rules, Arc::clone(&selector));
        assert_eq!(run(&mut cam, 1000), cam_at(&rules, Pattern::Juggle, 1000));
        let before = run(&mut cam, 1001);
        selector.set(Pattern::Limit);
        assert_eq!(selector.get(), Pattern::Limit);
        // The first cycle of the new program is where the old one goes: no jump.
        assert_eq!(run(&mut cam, 1002), cam_at(&rules, Pattern::Juggle, 1002));
        assert_ne!(before, cam_at(&rules, Pattern::Limit, 1002));
        // Half-way: between the two.
        let mid = run(&mut cam, 2002);
        let (old, new) = (cam_at(&rules, Pattern::Juggle, 2002), cam_at(&rules, Pattern::Limit, 2002));
        assert_ne!(old, new);
        for i in 0..5 {
            let (lo, hi) = (old[i].min(new[i]), old[i].max(new[i]));
            assert!(mid[i] >= lo - 2 && mid[i] <= hi + 2, "drive {i}: {} not in {lo}..{hi}", mid[i]);
        }
        // After the ramp: the new cam exactly.
        run(&mut cam, 3002);
        assert_eq!(run(&mut cam, 3500), cam_at(&rules, Pattern::Limit, 3500));
    }

    #[test]
    fn a_safety_stop_holds_the_program_at_the_drives_and_it_ramps_in_again() {
        let rules = RuleSet::from_toml(motus_safety::JUGGLER_TOML).unwrap();
        let mut cam = SelectedCam::new(&rules, Arc::new(ProgramSelector::new(Pattern::Juggle)));
        run(&mut cam, 500);
        let stopped = |p| Actual { status: STATUS_LEASE_STOP, position: p, speed: 0 };
        for d in 0..5 {
            cam.actual(d, &stopped(100 * d as i32));
        }
        // Held at the drives' positions, however the cam goes on.
        assert_eq!(run(&mut cam, 600), [0, 100, 200, 300, 400]);
        assert_eq!(run(&mut cam, 900), [0, 100, 200, 300, 400]);
        // Released: it starts where the drives are and reaches the cam after RAMP_IN.
        for d in 0..5 {
            cam.actual(d, &Actual { status: 0, position: 100 * d as i32, speed: 0 });
        }
        assert_eq!(run(&mut cam, 1000), [0, 100, 200, 300, 400]);
        run(&mut cam, 3000);
        assert_eq!(run(&mut cam, 3100), cam_at(&rules, Pattern::Juggle, 3100));
    }
}
