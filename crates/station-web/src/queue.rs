//! Queues and instant access: a student joins a machine's queue and, when the machine is
//! free (no slot of it or of the whole cell runs, no clean-up pending), the first in line
//! gets it at once for [`WebConfig::instant_slot`](crate::WebConfig::instant_slot) (shortened
//! to the next booked slot; not granted when less than [`MIN_GRANT`] is left), besides the
//! calendar slots.
//!
//! Routes: `GET /api/queues` (every machine's line), `POST /api/machines/{id}/queue` (join;
//! students for themselves, as when booking), `DELETE /api/machines/{id}/queue` (leave).
//! Bounded: [`MAX_WAITING`] per machine. Joining, leaving and each grant are audited. The
//! lines live in the station's memory: a restart empties them (the calendar is in the
//! database).

use std::collections::{BTreeMap, VecDeque};
use std::sync::atomic::Ordering;
use std::sync::{Mutex, PoisonError};
use std::time::Duration;

use axum::extract::{Path, State};
use axum::Json;
use motus_lab::{Action, Actor, AuditEntry, AuditOutcome, ReservationFilter, Role, UnixMs};
use serde_json::{json, Value};

use crate::auth::{Auth, Csrf};
use crate::error::ApiError;
use crate::machines::{machine_in_use, machines};
use crate::server::{AppState, Inner};

/// Most students waiting for one machine.
pub const MAX_WAITING: usize = 64;
/// The shortest instant slot granted (less time before the next booked slot: wait).
pub const MIN_GRANT: Duration = Duration::from_secs(5 * 60);

/// One student in a line.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Waiting {
    /// Who.
    pub user: String,
    /// Since when (ms since the epoch).
    pub since: UnixMs,
}

/// Every machine's line.
#[derive(Debug, Default)]
pub struct Queues {
    lines: Mutex<BTreeMap<String, VecDeque<Waiting>>>,
}

impl Queues {
    fn lines(&self) -> std::sync::MutexGuard<'_, BTreeMap<String, VecDeque<Waiting>>> {
        self.lines.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Every line, by machine.
    #[must_use]
    pub fn snapshot(&self) -> BTreeMap<String, Vec<Waiting>> {
        self.lines().iter().map(|(m, l)| (m.clone(), l.iter().cloned().collect())).collect()
    }
}

fn audit(state: &Inner, user: &str, action: &str, target: String, outcome: AuditOutcome) {
    let entry = AuditEntry { time: state.now(), user: user.into(), action: action.into(), target, outcome };
    if let Err(e) = state.lab.audit().append(&entry) {
        tracing::error!(error = %e, "audit write failed");
    }
}

fn known_machine(state: &Inner, machine: &str) -> Result<(), ApiError> {
    if machines(state).iter().any(|m| m == machine) {
        Ok(())
    } else {
        Err(ApiError::not_found(format!("no machine {machine:?} on this station")))
    }
}

/// `GET /api/queues`: who waits for which machine, in order.
///
/// # Errors
/// 401 without a session.
pub async fn queues(State(state): State<AppState>, _auth: Auth) -> Result<Json<Value>, ApiError> {
    Ok(Json(json!(state.queues.snapshot())))
}

/// `POST /api/machines/{id}/queue`: joins the machine's line (again: the same place);
/// answers the place (1: next).
///
/// # Errors
/// 403 for viewers, 404 for an unknown machine, 503 when the line is full.
pub async fn join(
    State(state): State<AppState>,
    Path(machine): Path<String>,
    Csrf(auth): Csrf,
) -> Result<Json<Value>, ApiError> {
    known_machine(&state, &machine)?;
    let user = auth.session.user.clone();
    let action = Action::Reserve { station: machine.clone(), for_user: user.clone() };
    state.check(&auth, &action)?;
    if auth.session.role == Role::Viewer {
        return Err(ApiError::forbidden("viewers cannot hold a slot"));
    }
    let place = {
        let mut lines = state.queues.lines();
        let line = lines.entry(machine.clone()).or_default();
        match line.iter().position(|w| w.user == user) {
            Some(i) => i + 1,
            None if line.len() >= MAX_WAITING => {
                drop(lines);
                let why = format!("{MAX_WAITING} students wait for {machine} already: book a slot instead");
                audit(&state, &user, "queue.join", machine.clone(), AuditOutcome::Denied(why.clone()));
                return Err(
                    ApiError::new(axum::http::StatusCode::SERVICE_UNAVAILABLE, "busy", why).mark_audited()
                );
            }
            None => {
                line.push_back(Waiting { user: user.clone(), since: state.now() });
                line.len()
            }
        }
    };
    audit(&state, &user, "queue.join", format!("{machine} place {place}"), AuditOutcome::Ok);
    state.lab_changed.store(true, Ordering::SeqCst);
    // Free now: granted at once.
    grant_queues(&state);
    Ok(Json(json!({ "machine": machine, "place": place, "queues": state.queues.snapshot() })))
}

/// `DELETE /api/machines/{id}/queue`: leaves the machine's line.
///
/// # Errors
/// 404 for an unknown machine.
pub async fn leave(
    State(state): State<AppState>,
    Path(machine): Path<String>,
    Csrf(auth): Csrf,
) -> Result<Json<Value>, ApiError> {
    known_machine(&state, &machine)?;
    let user = auth.session.user.clone();
    let left = {
        let mut lines = state.queues.lines();
        let line = lines.entry(machine.clone()).or_default();
        let before = line.len();
        line.retain(|w| w.user != user);
        before != line.len()
    };
    if left {
        audit(&state, &user, "queue.leave", machine.clone(), AuditOutcome::Ok);
        state.lab_changed.store(true, Ordering::SeqCst);
    }
    Ok(Json(json!({ "machine": machine, "left": left })))
}

/// The end of an instant slot of `machine` starting `now`: the instant slot's length, cut
/// at the next slot of the machine or of the whole cell.
fn grant_end(state: &Inner, machine: &str, now: UnixMs) -> Option<UnixMs> {
    let mut end = now.plus(state.config.instant_slot);
    for resource in [machine, state.config.station.as_str()] {
        let next = state.lab.reservations().list(&ReservationFilter {
            station: Some(resource.to_string()),
            window: Some((now, end)),
            ..ReservationFilter::default()
        });
        match next {
            Ok(list) => {
                for r in list {
                    if r.start < now {
                        return None; // running (or not cleaned up): not free
                    }
                    end = end.min(r.start);
                }
            }
            Err(e) => {
                tracing::error!(error = %e, "cannot read the reservations");
                return None;
            }
        }
    }
    (end.since(now) >= MIN_GRANT).then_some(end)
}

/// Gives each free machine to the first student in its line (see the module
/// documentation); run by the station's clean-up loop and when someone joins.
pub fn grant_queues(state: &Inner) {
    // Not beside a booking in progress (a whole-cell slot could slip in between the check
    // and the grant): the next pass grants.
    let Ok(_booking) = state.booking.try_lock() else { return };
    let now = state.now();
    let station_busy =
        state.lab.reservations().active_at(&state.config.station, now).map_or(true, |r| r.is_some());
    if station_busy {
        return;
    }
    let waiting: Vec<(String, Waiting)> =
        state.queues.lines().iter().filter_map(|(m, l)| l.front().map(|w| (m.clone(), w.clone()))).collect();
    for (machine, first) in waiting {
        if machine_in_use(state, &machine, now) {
            continue;
        }
        let Some(end) = grant_end(state, &machine, now) else { continue };
        // The station books for the student: the policy's length and count rules are the
        // queue's own (the instant slot), overlaps are refused by the store as for everyone.
        let station = Actor::new("station", Role::Admin);
        match state.lab.reservations().book(&station, &machine, &first.user, now, end, now) {
            Ok(r) => {
                state.queues.lines().entry(machine.clone()).or_default().retain(|w| w.user != first.user);
                audit(
                    state,
                    "station",
                    "queue.granted",
                    format!("{machine} to {} until {} (reservation {})", first.user, end.0, r.id),
                    AuditOutcome::Ok,
                );
                state.lab_changed.store(true, Ordering::SeqCst);
            }
            Err(e) => {
                // A user deleted or made a viewer meanwhile: out of the line (audited);
                // anything else (a storage error): the next pass tries again.
                if matches!(
                    e,
                    motus_lab::ReservationError::UnknownUser(_)
                        | motus_lab::ReservationError::ViewerCannotHold(_)
                ) {
                    state.queues.lines().entry(machine.clone()).or_default().retain(|w| w.user != first.user);
                    audit(
                        state,
                        "station",
                        "queue.granted",
                        format!("{machine} to {}", first.user),
                        AuditOutcome::Error(e.to_string()),
                    );
                } else {
                    tracing::warn!(error = %e, machine, user = first.user, "queue: slot not granted yet");
                }
            }
        }
    }
}
