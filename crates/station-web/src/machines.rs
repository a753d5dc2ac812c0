//! Machines as bookable resources: each group of the cell (robot, arm, head, CNC, juggler,
//! a bench of axes) is a machine that a student books on its own, so several students work
//! on different machines of one cell at the same time. A reservation names a machine (its
//! group id) or the whole cell (the station's name): a whole-cell slot covers every machine,
//! and a machine's slots never overlap a whole-cell slot.
//!
//! Which reservation a command needs ([`resource_for`]):
//! - an axis command: the axis's machine (an axis in no group needs the whole cell);
//! - running a program: the one machine of every axis it moves (several machines: the whole
//!   cell);
//! - a command on the station as a whole (stop, E-stop, reset, trace, files, alarms): any
//!   slot the user holds now; stopping is always safe, so a student stops the station from
//!   any machine they hold.
//!
//! Admins command at any time and E-stop is everyone's (the rules of `motus_lab::authz`).

use std::collections::BTreeSet;

use motus_lab::{Command, Reservation, ReservationFilter, UnixMs};

use crate::server::Inner;

/// What a command acts on.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Scope {
    /// One machine (a group id).
    Machine(String),
    /// Several machines, or axes in no machine: the whole cell.
    Cell,
    /// The station as a whole: any slot held now will do.
    Station,
}

/// The machine (group id) of `axis`, if it belongs to one.
#[must_use]
pub fn machine_of_axis(state: &Inner, axis: &str) -> Option<String> {
    state.backend.axes().into_iter().find(|a| a.id == axis).and_then(|a| a.group)
}

/// The machines of the cell (group ids).
#[must_use]
pub fn machines(state: &Inner) -> Vec<String> {
    state.backend.groups().into_iter().map(|g| g.id).collect()
}

/// What `command` acts on (see the module documentation).
#[must_use]
pub fn scope_of(state: &Inner, command: &Command) -> Scope {
    let axes: Vec<&str> = match command {
        Command::Axis { axis, .. } => vec![axis.as_str()],
        Command::RunProgram { demands, .. } => demands.iter().map(|(a, _)| a.as_str()).collect(),
        _ => return Scope::Station,
    };
    let mut set = BTreeSet::new();
    for axis in axes {
        match machine_of_axis(state, axis) {
            Some(m) => {
                set.insert(m);
            }
            None => return Scope::Cell,
        }
    }
    match (set.len(), set.into_iter().next()) {
        (1, Some(m)) => Scope::Machine(m),
        _ => Scope::Cell,
    }
}

/// The slots running at `now` held by `user` on this station (the whole cell or its
/// machines). A storage error reads as none: the command is then refused (fail closed).
#[must_use]
pub fn held_now(state: &Inner, user: &str, now: UnixMs) -> Vec<Reservation> {
    let filter = ReservationFilter {
        user: Some(user.to_string()),
        window: Some((now, now.plus(std::time::Duration::from_millis(1)))),
        ..ReservationFilter::default()
    };
    let ours = resources(state);
    match state.lab.reservations().list(&filter) {
        Ok(list) => list.into_iter().filter(|r| ours.contains(&r.station)).collect(),
        Err(e) => {
            tracing::error!(error = %e, "cannot read the reservations");
            Vec::new()
        }
    }
}

/// The slots running at `now` on this station's resources (the whole cell's and each
/// machine's), by anyone.
#[must_use]
pub fn running_slots(state: &Inner, now: UnixMs) -> Vec<Reservation> {
    let ours = resources(state);
    let filter = ReservationFilter {
        window: Some((now, now.plus(std::time::Duration::from_millis(1)))),
        ..ReservationFilter::default()
    };
    match state.lab.reservations().list(&filter) {
        Ok(list) => list.into_iter().filter(|r| ours.contains(&r.station)).collect(),
        Err(e) => {
            tracing::error!(error = %e, "cannot read the reservations");
            Vec::new()
        }
    }
}

/// Every bookable resource of this station: the whole cell (the station's name) and each
/// machine.
#[must_use]
pub fn resources(state: &Inner) -> Vec<String> {
    let mut v = vec![state.config.station.clone()];
    v.extend(machines(state));
    v
}

/// True while `machine` is booked on its own now: a slot of it runs, or a finished one
/// awaits its clean-up.
#[must_use]
pub fn machine_in_use(state: &Inner, machine: &str, now: UnixMs) -> bool {
    let reservations = state.lab.reservations();
    let running = reservations.active_at(machine, now);
    let cleaning = reservations.list(&ReservationFilter {
        station: Some(machine.to_string()),
        pending_cleanup_at: Some(now),
        ..ReservationFilter::default()
    });
    match (running, cleaning) {
        (Ok(r), Ok(c)) => r.is_some() || !c.is_empty(),
        // Unknown: the machine's own slot decides (no slot of it: refused; fail closed).
        _ => true,
    }
}

/// The reservation resource a student needs for `command` now, the one the authorisation
/// checks the slot of:
/// - a command on one machine: that machine while it is booked on its own (a slot of it
///   runs, or its clean-up is pending), else the whole cell (whose slot covers it);
/// - on several machines, or axes in none: the whole cell;
/// - on the station as a whole: the whole cell's slot if the student holds it, else any
///   machine they hold now (else the whole cell: refused without a slot).
#[must_use]
pub fn resource_for(state: &Inner, user: &str, command: &Command, now: UnixMs) -> String {
    let station = &state.config.station;
    match scope_of(state, command) {
        Scope::Machine(m) if machine_in_use(state, &m, now) => m,
        Scope::Machine(_) | Scope::Cell => station.clone(),
        Scope::Station => {
            let held = held_now(state, user, now);
            if held.iter().any(|r| &r.station == station) {
                return station.clone();
            }
            held.into_iter().next().map_or_else(|| station.clone(), |r| r.station)
        }
    }
}

/// The slots of this station's other resources that overlap `[start, end)` and conflict with
/// a booking of `resource`: whole-cell bookings conflict with every machine's, a machine's
/// with the whole cell's (slots of one resource are checked by the store itself).
///
/// # Errors
/// A storage failure.
pub fn conflicts(
    state: &Inner,
    resource: &str,
    start: UnixMs,
    end: UnixMs,
) -> Result<Vec<Reservation>, motus_lab::ReservationError> {
    let station = &state.config.station;
    let others: Vec<String> = if resource == station { machines(state) } else { vec![station.clone()] };
    let mut out = Vec::new();
    for other in others {
        out.extend(state.lab.reservations().list(&ReservationFilter {
            station: Some(other),
            window: Some((start, end)),
            ..ReservationFilter::default()
        })?);
    }
    Ok(out)
}
