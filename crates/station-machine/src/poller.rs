//! The poller: reads every axis, refreshes the HMI's view, records one sample row, and
//! follows the robot's pose.

use std::sync::atomic::Ordering;
use std::sync::PoisonError;
use std::time::{Duration, Instant};

use crate::{lock, Shared, SAMPLE_ROWS};

/// Robot path points kept.
const PATH_POINTS: usize = 2000;

pub(crate) fn run(s: &Shared, period: Duration) {
    let mut next = Instant::now();
    while !s.stop.load(Ordering::Relaxed) {
        let mut row = Vec::with_capacity(s.axes.len());
        let mut views = Vec::with_capacity(s.axes.len());
        for a in &s.axes {
            let mut v = a.view.clone();
            // Copied out: the lock is not held while the axis is read over its link.
            let params = s.overrides.read().unwrap_or_else(PoisonError::into_inner).get(&v.id).copied();
            if let Some(p) = params {
                crate::backend::apply_parameters(&mut v, &p);
            }
            let state = lock(&a.axis).read_state();
            match state {
                Ok(st) => {
                    v.position = st.position;
                    v.velocity = st.velocity.unwrap_or(0.0);
                    v.enabled = st.flags.enabled;
                    v.homed = st.flags.homed;
                    v.moving = st.flags.moving;
                    v.fault = st.faults.first().map(|f| f.reason.clone());
                }
                Err(e) => {
                    // Keep the last known position; say why it is not fresh.
                    if let Some(old) =
                        s.views.read().unwrap_or_else(PoisonError::into_inner).iter().find(|o| o.id == v.id)
                    {
                        v.position = old.position;
                    }
                    v.fault = Some(e.to_string());
                    v.moving = false;
                }
            }
            if let Some(reason) = s.faults.fault_of(&v.id) {
                v.fault = Some(reason);
            }
            row.push(v.position);
            views.push(v);
        }
        update_robot_estimate(s, &views);
        *s.views.write().unwrap_or_else(PoisonError::into_inner) = views;
        // The cyclic traces' latest values (their full rate is in the recorder: trace.csv).
        if let Some(rec) = s.recorder.get() {
            let rec = lock(rec);
            row.extend(rec.signals().iter().map(|sig| rec.latest(sig.id).map_or(f64::NAN, |x| x.value)));
        }
        if let Some(cnc) = s.cnc_status.get() {
            row.push(cnc.feed());
        }
        {
            let t = s.epoch.elapsed().as_secs_f64();
            let mut smp = lock(&s.samples);
            smp.rows.push_back((t, row));
            while smp.rows.len() > SAMPLE_ROWS {
                smp.rows.pop_front();
                smp.first += 1;
            }
        }
        if let Some(pose) = s.groups.iter().find_map(|g| match &g.handle {
            motus_cell::GroupHandle::Omni(o) => o.true_pose(),
            _ => None,
        }) {
            let mut path = lock(&s.robot_path);
            let p = [pose.x, pose.y];
            if path.back().is_none_or(|q| (q[0] - p[0]).hypot(q[1] - p[1]) > 0.001) {
                path.push_back(p);
                while path.len() > PATH_POINTS {
                    path.pop_front();
                }
            }
        }
        next += period;
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        } else {
            next = now;
        }
    }
}

/// Feeds the omni group's wheel positions to its pose estimate.
fn update_robot_estimate(s: &Shared, views: &[motus_station_web::AxisView]) {
    let Some(estimate) = &s.robot else { return };
    let Some(g) = s.groups.iter().find(|g| matches!(g.handle, motus_cell::GroupHandle::Omni(_))) else {
        return;
    };
    let mut positions = [0.0; 3];
    for (p, name) in positions.iter_mut().zip(&g.axes) {
        match views.iter().find(|v| &v.id == name) {
            // A wheel that cannot be read is not integrated as motion.
            Some(v) if v.fault.is_none() => *p = v.position,
            _ => return,
        }
    }
    lock(estimate).update(positions, s.epoch.elapsed().as_secs_f64());
}
