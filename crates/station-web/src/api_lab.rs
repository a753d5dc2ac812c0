//! Laboratory routes: login/logout/session, reservations, ending a user's session, audit,
//! alarms, users; and the end-of-slot cleanup loop.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::{ConnectInfo, Path, Query, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use motus_lab::{
    AckOutcome, Action, AuditEntry, AuditOutcome, AuditQuery, Command, LoginError, ReservationFilter, Role,
    UnixMs,
};
use serde::Deserialize;
use serde_json::{json, Value};

use crate::auth::{Auth, Body, Csrf};
use crate::error::ApiError;
use crate::server::{AppState, Inner};

type ApiResult = Result<Json<Value>, ApiError>;

/// Body of `POST /api/login`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoginBody {
    /// User name.
    pub user: String,
    /// Password.
    pub password: String,
}

fn with_cookie(mut r: Response, cookie: &str) -> Response {
    if let Ok(v) = HeaderValue::from_str(cookie) {
        r.headers_mut().append(header::SET_COOKIE, v);
    }
    r
}

/// `POST /api/login`: sets the session cookie, returns the CSRF token.
pub async fn login(
    State(state): State<AppState>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    Body(b): Body<LoginBody>,
) -> Result<Response, ApiError> {
    let now = state.now();
    let lab = Arc::clone(&state.lab);
    let r = tokio::task::spawn_blocking(move || lab.login(&b.user, &b.password, peer.ip(), now))
        .await
        .map_err(|e| ApiError::internal(e.to_string()))?;
    match r {
        Ok(ok) => {
            let body = json!({
                "user": ok.user.name,
                "role": ok.user.role,
                "csrf_token": ok.session.csrf_token,
            });
            Ok(with_cookie(Json(body).into_response(), &ok.session.set_cookie))
        }
        Err(LoginError::RateLimited(l)) => Err(ApiError {
            retry_after: Some(l.retry_after.as_secs().max(1)),
            ..ApiError::new(StatusCode::TOO_MANY_REQUESTS, "rate_limited", l.to_string())
        }),
        Err(LoginError::BadCredentials) => {
            Err(ApiError::new(StatusCode::UNAUTHORIZED, "bad_credentials", "wrong user name or password"))
        }
        // The password-hashing pool is full: nothing was checked or counted; retry soon.
        Err(e @ LoginError::Busy) => Err(ApiError {
            retry_after: Some(1),
            ..ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "busy", e.to_string())
        }),
        Err(e) => Err(ApiError::internal(e.to_string())),
    }
}

/// `POST /api/logout`.
pub async fn logout(State(state): State<AppState>, Csrf(auth): Csrf) -> Result<Response, ApiError> {
    state.lab.logout(&auth.session, state.now()).map_err(|e| ApiError::internal(e.to_string()))?;
    let clear = state.lab.sessions().policy().cookie.clear_cookie();
    Ok(with_cookie(Json(json!({ "ok": true })).into_response(), &clear))
}

/// `GET /api/session`: who I am, my CSRF token, the whole-cell slot in force, the slots
/// running on the machines, mine among them, the machines (bookable one by one) and whether I
/// may command.
pub async fn session(State(state): State<AppState>, auth: Auth) -> ApiResult {
    let now = state.now();
    let slot = state.lab.reservations().active_at(&state.config.station, now)?;
    let s = &auth.session;
    let mine: Vec<String> =
        crate::machines::held_now(&state, &s.user, now).into_iter().map(|r| r.station).collect();
    Ok(Json(json!({
        "user": s.user,
        "role": s.role,
        "csrf_token": s.csrf_token,
        "idle_expires": s.idle_expires,
        "absolute_expires": s.absolute_expires,
        "station": state.config.station,
        "machines": crate::machines::machines(&state),
        "slot": slot,
        "slots": crate::machines::running_slots(&state, now),
        "my_slots": mine,
        "can_command": state.can_command(&auth),
        "now": now,
    })))
}

/// `POST /api/sessions/{user}/end` (admin): ends the user's login sessions and running slot.
pub async fn end_session(
    State(state): State<AppState>,
    Path(user): Path<String>,
    Csrf(auth): Csrf,
) -> ApiResult {
    let ended = state.lab.end_user_session(&auth.actor(), &user, state.now()).map_err(|e| match e {
        motus_lab::EndSessionError::Authz(a) => ApiError::from(a).mark_audited(),
        other => ApiError::internal(other.to_string()),
    })?;
    state.lab_changed.store(true, Ordering::SeqCst);
    run_cleanups(&state);
    Ok(Json(json!({ "sessions": ended.sessions, "slots": ended.slots })))
}

fn parse_ms(q: &HashMap<String, String>, key: &str) -> Result<Option<UnixMs>, ApiError> {
    q.get(key)
        .map(|v| {
            v.parse::<i64>()
                .map(UnixMs)
                .map_err(|_| ApiError::invalid(format!("{key} must be ms since the epoch")))
        })
        .transpose()
}

/// `GET /api/reservations?from=ms&until=ms`: this station's reservations, of the whole cell
/// and of each machine, by start (default: from an hour ago for 14 days).
pub async fn reservations(
    State(state): State<AppState>,
    _auth: Auth,
    Query(q): Query<HashMap<String, String>>,
) -> ApiResult {
    let now = state.now();
    let from = parse_ms(&q, "from")?.unwrap_or_else(|| now.minus(Duration::from_secs(3600)));
    let until = parse_ms(&q, "until")?.unwrap_or_else(|| now.plus(Duration::from_secs(14 * 24 * 3600)));
    let mut list = Vec::new();
    for resource in crate::machines::resources(&state) {
        list.extend(state.lab.reservations().list(&ReservationFilter {
            station: Some(resource),
            window: Some((from, until)),
            ..ReservationFilter::default()
        })?);
    }
    list.sort_by_key(|r| (r.start, r.id));
    Ok(Json(json!(list)))
}

/// Body of `POST /api/reservations`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BookBody {
    /// Slot start, ms since the epoch.
    pub start: i64,
    /// Slot end, ms since the epoch.
    pub end: i64,
    /// For whom (admins only; default: yourself).
    #[serde(default)]
    pub user: Option<String>,
    /// Which machine (a group id of `GET /api/groups`); default: the whole cell.
    #[serde(default)]
    pub machine: Option<String>,
}

/// `POST /api/reservations`: books a slot of one machine, or of the whole cell (409 when it
/// overlaps another slot of that machine, or a whole-cell slot overlaps a machine's).
pub async fn book(State(state): State<AppState>, Csrf(auth): Csrf, Body(b): Body<BookBody>) -> ApiResult {
    let for_user = b.user.unwrap_or_else(|| auth.session.user.clone());
    let resource = match b.machine {
        None => state.config.station.clone(),
        Some(m) if crate::machines::machines(&state).contains(&m) => m,
        Some(m) => {
            let known = crate::machines::machines(&state).join(", ");
            return Err(ApiError::invalid(format!("no machine {m:?} on this station (machines: {known})")));
        }
    };
    let action = Action::Reserve { station: resource.clone(), for_user: for_user.clone() };
    state.check(&auth, &action)?;
    // One booking at a time: the store checks the overlap of one resource atomically, this
    // lock the overlap of a machine's slot with the whole cell's.
    let _booking = state.booking.lock().await;
    let (start, end) = (UnixMs(b.start), UnixMs(b.end));
    let r = match crate::machines::conflicts(&state, &resource, start, end)?.into_iter().next() {
        Some(other) => Err(motus_lab::ReservationError::Overlap(Box::new(other))),
        None => state.lab.reservations().book(&auth.actor(), &resource, &for_user, start, end, state.now()),
    };
    let audit = r.as_ref().map(|_| ()).map_err(ToString::to_string);
    if let Err(e) = state.lab.record(&auth.actor(), &action, audit, state.now()) {
        tracing::error!(error = %e, "audit write failed");
    }
    state.lab_changed.store(true, Ordering::SeqCst);
    Ok(Json(json!(r.map_err(|e| ApiError::from(e).mark_audited())?)))
}

/// `DELETE /api/reservations/{id}`: cancels (or ends early) a reservation.
pub async fn cancel(State(state): State<AppState>, Path(id): Path<i64>, Csrf(auth): Csrf) -> ApiResult {
    let r = state
        .lab
        .reservations()
        .get(id)?
        .ok_or_else(|| ApiError::not_found(format!("no reservation {id}")))?;
    let action = Action::CancelReservation { station: r.station.clone(), owner: r.user.clone() };
    state.check(&auth, &action)?;
    let out = state.lab.reservations().cancel(&auth.actor(), id, state.now());
    let audit = out.as_ref().map(|_| ()).map_err(ToString::to_string);
    if let Err(e) = state.lab.record(&auth.actor(), &action, audit, state.now()) {
        tracing::error!(error = %e, "audit write failed");
    }
    let ended = out.map_err(|e| ApiError::from(e).mark_audited())?;
    state.lab_changed.store(true, Ordering::SeqCst);
    run_cleanups(&state);
    Ok(Json(json!({ "ok": true, "ended": ended })))
}

/// `GET /api/audit?user=&action_prefix=&outcome=&limit=` (admin).
pub async fn audit(
    State(state): State<AppState>,
    auth: Auth,
    Query(q): Query<HashMap<String, String>>,
) -> ApiResult {
    state.check(&auth, &Action::ViewAudit)?;
    let limit = match q.get("limit") {
        Some(l) => l.parse::<usize>().map_err(|_| ApiError::invalid("limit must be an unsigned integer"))?,
        None => 200,
    };
    let query = AuditQuery {
        user: q.get("user").cloned(),
        action_prefix: q.get("action_prefix").cloned(),
        outcome: q.get("outcome").cloned(),
        since: parse_ms(&q, "since")?,
        until: parse_ms(&q, "until")?,
        limit: limit.min(10_000),
    };
    Ok(Json(json!(state.lab.audit().query(&query)?)))
}

/// `GET /api/alarms`: active alarms and the recent history.
pub async fn alarms(State(state): State<AppState>, _auth: Auth) -> ApiResult {
    Ok(Json(json!({ "active": state.lab.alarms().active()?, "history": state.lab.alarms().history(100)? })))
}

/// `POST /api/alarms/{id}/ack`.
pub async fn ack_alarm(State(state): State<AppState>, Path(id): Path<i64>, Csrf(auth): Csrf) -> ApiResult {
    let action = state.command_action(&auth, Command::AcknowledgeAlarm { id });
    state.check(&auth, &action)?;
    let out = state.lab.alarms().acknowledge(id, &auth.session.user, state.now())?;
    let result = match &out {
        AckOutcome::NotFound => Err(format!("no alarm {id}")),
        _ => Ok(()),
    };
    if let Err(e) = state.lab.record(&auth.actor(), &action, result, state.now()) {
        tracing::error!(error = %e, "audit write failed");
    }
    state.lab_changed.store(true, Ordering::SeqCst);
    match out {
        AckOutcome::Acknowledged(a) | AckOutcome::AlreadyAcknowledged(a) => Ok(Json(json!(a))),
        AckOutcome::NotFound => Err(ApiError::not_found(format!("no alarm {id}")).mark_audited()),
    }
}

fn user_json(u: &motus_lab::User) -> Value {
    json!({ "name": u.name, "role": u.role, "created": u.created, "updated": u.updated })
}

/// `GET /api/users` (admin).
pub async fn users(State(state): State<AppState>, auth: Auth) -> ApiResult {
    state.check(&auth, &Action::ManageUsers)?;
    let list = state.lab.users().list()?;
    Ok(Json(Value::Array(list.iter().map(user_json).collect())))
}

/// Body of `POST /api/users`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NewUserBody {
    /// Login name.
    pub name: String,
    /// Password (policy applies).
    pub password: String,
    /// Role.
    pub role: Role,
}

/// `POST /api/users` (admin).
pub async fn add_user(
    State(state): State<AppState>,
    Csrf(auth): Csrf,
    Body(b): Body<NewUserBody>,
) -> ApiResult {
    state.check(&auth, &Action::ManageUsers)?;
    let lab = Arc::clone(&state.lab);
    let now = state.now();
    let name = b.name.clone();
    let r = tokio::task::spawn_blocking(move || lab.users().add(&b.name, &b.password, b.role, now))
        .await
        .map_err(|e| ApiError::internal(e.to_string()))?;
    state.audit(
        &auth,
        "manage_users.add",
        &format!("user:{name}"),
        r.as_ref().map(|_| ()).map_err(ToString::to_string),
    );
    Ok(Json(user_json(&r.map_err(|e| ApiError::from(e).mark_audited())?)))
}

/// `DELETE /api/users/{name}` (admin).
pub async fn delete_user(
    State(state): State<AppState>,
    Path(name): Path<String>,
    Csrf(auth): Csrf,
) -> ApiResult {
    state.check(&auth, &Action::ManageUsers)?;
    let r = state.lab.users().delete(&name);
    state.audit(
        &auth,
        "manage_users.delete",
        &format!("user:{name}"),
        r.as_ref().map(|_| ()).map_err(ToString::to_string),
    );
    r.map_err(|e| ApiError::from(e).mark_audited())?;
    Ok(Json(json!({ "ok": true })))
}

/// Fallback: JSON 404 (under `/api/`, [`crate::auth::audit_refusals`] answers 401 instead
/// without a session and audits the miss with one).
pub async fn not_found() -> ApiError {
    ApiError::not_found("no such route")
}

/// Executes the end-of-slot cleanups due now for this station: the backend removes the
/// holder's programs and traces and brings the machine to a safe homed state; lab records
/// the cleanup (commands are allowed again) and the audit log gets a `cleanup` entry.
pub fn run_cleanups(state: &Inner) {
    let now = state.now();
    let due = match state.lab.reservations().due_cleanups(now) {
        Ok(d) => d,
        Err(e) => {
            tracing::error!(error = %e, "cannot read due cleanups");
            return;
        }
    };
    let machines = crate::machines::machines(state);
    for c in due.into_iter() {
        let r = &c.reservation;
        if r.station == state.config.station {
            state.backend.on_slot_end(&r.user);
        } else if machines.contains(&r.station) {
            // The user's files go with their last slot (they may hold another machine still).
            let last = crate::machines::held_now(state, &r.user, now).iter().all(|h| h.id == r.id);
            state.backend.on_machine_slot_end(&r.station, &r.user, last);
        } else {
            continue; // another station's
        }
        let r = state.lab.reservations().complete_cleanup(&c);
        let entry = AuditEntry {
            time: now,
            user: "station".into(),
            action: "cleanup".into(),
            target: format!(
                "{}/reservation:{}:{}",
                c.reservation.station, c.reservation.id, c.reservation.user
            ),
            outcome: match &r {
                Ok(()) => AuditOutcome::Ok,
                Err(e) => AuditOutcome::Error(e.to_string()),
            },
        };
        if let Err(e) = state.lab.audit().append(&entry) {
            tracing::error!(error = %e, "audit write failed");
        }
    }
}

/// Runs [`run_cleanups`] every `cleanup_interval` until shutdown.
pub async fn cleanup_loop(state: AppState) {
    let mut shutdown = state.shutdown.clone();
    let mut tick = tokio::time::interval(state.config.cleanup_interval.max(Duration::from_millis(10)));
    loop {
        tokio::select! {
            _ = tick.tick() => {
                let s = Arc::clone(&state);
                let _ = tokio::task::spawn_blocking(move || {
                    run_cleanups(&s);
                    crate::queue::grant_queues(&s);
                })
                .await;
            }
            _ = shutdown.changed() => return,
        }
    }
}
