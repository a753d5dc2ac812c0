//! Shared helpers of the integration tests: machine, checks computed independently of the
//! library (finite differences, distance to the programmed path, time-optimal bound).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, dead_code)]

use motus_cnc_planner::{AxisLimits, Config, ExecState, Executor, Piece, Setpoint};

/// Cycle time (s).
pub const DT: f64 = 0.001;
/// Axis speed limits (mm/s).
pub const VMAX: [f64; 3] = [200.0, 150.0, 50.0];
/// Axis acceleration limits (mm/s²).
pub const AMAX: [f64; 3] = [2000.0, 1500.0, 500.0];
/// Numerical allowance on finite-difference accelerations (relative, plus absolute mm/s²):
/// the executor integrates a continuous piecewise-constant-acceleration profile, so the
/// second differences of its samples stay within the limits up to rounding (positions of
/// ~2000 mm carry ~4e-13 mm of rounding, i.e. ~1e-6 mm/s² after dividing by dt²).
/// Relative allowance.
pub const ACC_REL: f64 = 1e-6;
/// Absolute allowance (mm/s²).
pub const ACC_ABS: f64 = 1e-3;

/// The test machine: X 200 mm/s 2000 mm/s², Y 150/1500, Z 50/500.
pub fn config() -> Config<3> {
    let mut c = Config::new([
        AxisLimits { velocity: VMAX[0], acceleration: AMAX[0] },
        AxisLimits { velocity: VMAX[1], acceleration: AMAX[1] },
        AxisLimits { velocity: VMAX[2], acceleration: AMAX[2] },
    ]);
    c.buffer_capacity = 1_000_000;
    c.history = 1_000_000;
    c
}

/// Runs until `done` or `max` cycles, returning every set-point (the first is the start).
pub fn run_until(
    ex: &mut Executor<3>,
    max: usize,
    mut each: impl FnMut(usize, &mut Executor<3>, &Setpoint<3>),
    done: impl Fn(&Setpoint<3>) -> bool,
) -> Vec<Setpoint<3>> {
    let mut out = Vec::new();
    for k in 0..max {
        let sp = ex.tick(DT);
        each(k, ex, &sp);
        let stop = done(&sp);
        out.push(sp);
        if stop {
            break;
        }
    }
    out
}

/// True when the executor has nothing left to do.
pub fn idle(sp: &Setpoint<3>) -> bool {
    sp.state == ExecState::Idle
}

/// Largest |v_i| / vmax_i and |a_i| / amax_i over the set-points by finite differences
/// (with the acceleration allowance subtracted first).
pub fn limit_ratios(pos: &[[f64; 3]]) -> (f64, f64) {
    let mut vr: f64 = 0.0;
    let mut ar: f64 = 0.0;
    for w in pos.windows(2) {
        for i in 0..3 {
            vr = vr.max(((w[1][i] - w[0][i]) / DT).abs() / VMAX[i]);
        }
    }
    for w in pos.windows(3) {
        for i in 0..3 {
            let a = ((w[2][i] - 2.0 * w[1][i] + w[0][i]) / (DT * DT)).abs();
            ar = ar.max((a - ACC_ABS).max(0.0) / (AMAX[i] * (1.0 + ACC_REL)));
        }
    }
    (vr, ar)
}

/// Distance from `p` to segment `a`-`b`.
pub fn dist_seg(p: &[f64; 3], a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let ap = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    let l2 = ab.iter().map(|x| x * x).sum::<f64>();
    let t = if l2 > 0.0 {
        (ab.iter().zip(&ap).map(|(x, y)| x * y).sum::<f64>() / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let d: Vec<f64> = (0..3).map(|i| ap[i] - t * ab[i]).collect();
    d.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Largest distance of the set-points from the polyline `prog`, searching a moving window
/// of segments (`behind`, `ahead` of the last nearest one), with a full search whenever the
/// window gives more than `tol` (so a pass never depends on the window; the printed value is
/// exact when the window holds the nearest segment).
pub fn max_deviation_window(
    pos: &[[f64; 3]],
    prog: &[[f64; 3]],
    tol: f64,
    behind: usize,
    ahead: usize,
) -> f64 {
    let mut idx = 0usize;
    let mut worst: f64 = 0.0;
    let n = prog.len() - 1;
    for p in pos {
        let lo = idx.saturating_sub(behind);
        let hi = (idx + ahead).min(n);
        let mut best = f64::INFINITY;
        let mut bi = idx;
        for k in lo..hi {
            let d = dist_seg(p, &prog[k], &prog[k + 1]);
            if d < best {
                best = d;
                bi = k;
            }
        }
        if best > tol {
            for k in 0..n {
                let d = dist_seg(p, &prog[k], &prog[k + 1]);
                if d < best {
                    best = d;
                    bi = k;
                }
            }
        }
        idx = bi;
        worst = worst.max(best);
    }
    worst
}

/// Time-optimal traversal time of the planned geometric path (lines and blend arcs, as
/// sampled from the pieces) under the exact per-axis box constraints |v t_i| <= vmax_i and
/// |a_t t_i + v² κ_i| <= amax_i at every point, and the programmed feed, at rest at both
/// ends and at every stopping marker: numerical phase-plane integration (forward and
/// backward passes with the speed-dependent acceleration bounds) at steps of at most `h`.
/// Independent of the library's planner: it uses only the geometry.
pub fn time_optimal(pieces: &[Piece<3>], h: f64) -> f64 {
    // samples: (ds from previous, vlim, tangent, curvature)
    let mut ds = Vec::new();
    let mut vlim = Vec::new();
    let mut tan = Vec::new();
    let mut curv = Vec::new();
    let mut first = true;
    for p in pieces {
        if let Some(m) = p.marker() {
            if m.stops() {
                if let Some(v) = vlim.last_mut() {
                    *v = 0.0;
                }
            }
            continue;
        }
        let n = (p.length / h).ceil().max(1.0) as usize;
        let step = p.length / n as f64;
        for k in 0..=n {
            if k == 0 && !first {
                continue; // shared with the previous piece's end
            }
            let x = k as f64 * step;
            let t = p.tangent(x);
            let c = p.curvature(x);
            let mut lim = if p.feed.is_finite() { p.feed } else { f64::INFINITY };
            for i in 0..3 {
                if t[i].abs() > 1e-12 {
                    lim = lim.min(VMAX[i] / t[i].abs());
                }
                if c[i].abs() > 1e-12 {
                    lim = lim.min((AMAX[i] / c[i].abs()).sqrt());
                }
            }
            ds.push(if first && k == 0 { 0.0 } else { step });
            vlim.push(lim);
            tan.push(t);
            curv.push(c);
        }
        first = false;
    }
    let m = vlim.len();
    vlim[0] = 0.0;
    vlim[m - 1] = 0.0;
    // acceleration bounds at (sample, speed)
    let bounds = |k: usize, v: f64| -> (f64, f64) {
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        for i in 0..3 {
            let t = tan[k][i];
            if t.abs() < 1e-12 {
                continue;
            }
            let cen = v * v * curv[k][i];
            let a = (-AMAX[i] - cen) / t;
            let b = (AMAX[i] - cen) / t;
            lo = lo.max(a.min(b));
            hi = hi.min(a.max(b));
        }
        (lo, hi)
    };
    let mut fwd = vec![0.0f64; m];
    for k in 1..m {
        let (_, hi) = bounds(k - 1, fwd[k - 1]);
        let v2 = fwd[k - 1] * fwd[k - 1] + 2.0 * ds[k] * hi.max(0.0);
        fwd[k] = v2.max(0.0).sqrt().min(vlim[k]);
    }
    let mut v = vec![0.0f64; m];
    v[m - 1] = 0.0;
    for k in (0..m - 1).rev() {
        let (lo, _) = bounds(k + 1, v[k + 1]);
        let v2 = v[k + 1] * v[k + 1] + 2.0 * ds[k + 1] * (-lo).max(0.0);
        v[k] = v2.sqrt().min(fwd[k]);
    }
    let mut t = 0.0;
    for k in 1..m {
        let avg = 0.5 * (v[k] + v[k - 1]);
        if ds[k] > 0.0 {
            t += ds[k] / avg.max(1e-9);
        }
    }
    t
}

/// [`max_deviation_window`] with a window of 20 segments behind and 200 ahead.
pub fn max_deviation(pos: &[[f64; 3]], prog: &[[f64; 3]], tol: f64) -> f64 {
    max_deviation_window(pos, prog, tol, 20, 200)
}
