//! Machine routes: axes, E-stop, safety, groups, programs, signals, scene, camera.
//! Every command is authorised by lab and audited (see [`crate::server::Inner::command`]).

use std::collections::HashMap;

use axum::extract::{Path, Query, State};
use axum::http::StatusCode;
use axum::Json;
use motus_lab::{
    Action, AuditEntry, AuditOutcome, AxisOp, Command, MotionDemand, ProgramKind, ProgramMeta, Role,
};
use serde::Deserialize;
use serde_json::{json, Value};

use crate::auth::{Auth, Body, Csrf};
use crate::backend::{
    AxisAction, AxisParameters, AxisView, BackendError, GroupAction, GroupKind, ProgramCheck,
};
use crate::error::ApiError;
use crate::server::AppState;

type ApiResult = Result<Json<Value>, ApiError>;

pub(crate) fn ok() -> Json<Value> {
    Json(json!({ "ok": true }))
}

fn find_axis(state: &AppState, id: &str) -> Result<AxisView, ApiError> {
    state
        .backend
        .axes()
        .into_iter()
        .find(|a| a.id == id)
        .ok_or_else(|| ApiError::not_found(format!("no axis {id:?}")))
}

/// `GET /api/axes`.
pub async fn axes(State(state): State<AppState>, _auth: Auth) -> ApiResult {
    Ok(Json(json!(state.backend.axes())))
}

async fn axis_command(state: AppState, auth: Auth, id: String, action: AxisAction) -> ApiResult {
    let view = find_axis(&state, &id)?;
    let command = Command::Axis { axis: id.clone(), op: action.op(), demand: action.demand(&view) };
    let backend = std::sync::Arc::clone(&state.backend);
    state.command(&auth, command, move |caller| backend.command(&caller, &id, action)).await?;
    Ok(ok())
}

/// Body of `POST /api/axes/{id}/jog`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JogBody {
    /// +1 or -1.
    pub direction: f64,
    /// Speed (> 0).
    pub speed: f64,
    /// Acceleration (default: the axis's).
    #[serde(default)]
    pub acceleration: Option<f64>,
}

/// Body of `POST /api/axes/{id}/move`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MoveBody {
    /// Target position.
    pub target: f64,
    /// Speed (> 0).
    pub speed: f64,
    /// Acceleration (default: the axis's).
    #[serde(default)]
    pub acceleration: Option<f64>,
}

/// `POST /api/axes/{id}/jog`.
pub async fn jog(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Csrf(auth): Csrf,
    Body(b): Body<JogBody>,
) -> ApiResult {
    axis_command(
        state,
        auth,
        id,
        AxisAction::Jog { direction: b.direction, speed: b.speed, acceleration: b.acceleration },
    )
    .await
}

/// `POST /api/axes/{id}/move`.
pub async fn move_to(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Csrf(auth): Csrf,
    Body(b): Body<MoveBody>,
) -> ApiResult {
    axis_command(
        state,
        auth,
        id,
        AxisAction::Move { target: b.target, speed: b.speed, acceleration: b.acceleration },
    )
    .await
}

/// `POST /api/axes/{id}/home`.
pub async fn home(State(state): State<AppState>, Path(id): Path<String>, Csrf(auth): Csrf) -> ApiResult {
    axis_command(state, auth, id, AxisAction::Home).await
}

/// `POST /api/axes/{id}/stop`.
pub async fn stop(State(state): State<AppState>, Path(id): Path<String>, Csrf(auth): Csrf) -> ApiResult {
    axis_command(state, auth, id, AxisAction::Stop).await
}

/// `PUT /api/axes/{id}/parameters` (admin only).
pub async fn parameters(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Csrf(auth): Csrf,
    Body(p): Body<AxisParameters>,
) -> ApiResult {
    find_axis(&state, &id)?;
    let action = Action::ChangeAxisParameters { station: state.config.station.clone(), axis: id.clone() };
    admin_only(&state, &auth, &action)?;
    let backend = std::sync::Arc::clone(&state.backend);
    state.authorized(&auth, &action, move |c| backend.set_axis_parameters(&c, &id, p)).await?;
    Ok(ok())
}

/// Lab's decision (audited) and, in addition, the web layer's own role check.
fn admin_only(state: &AppState, auth: &Auth, action: &Action) -> Result<(), ApiError> {
    state.check(auth, action)?;
    if auth.session.role != Role::Admin {
        return Err(ApiError::forbidden("admin only"));
    }
    Ok(())
}

/// `POST /api/estop`: every student and admin, at any time.
pub async fn estop(State(state): State<AppState>, Csrf(auth): Csrf) -> ApiResult {
    let backend = std::sync::Arc::clone(&state.backend);
    state
        .command(&auth, Command::EStop, move |c| {
            backend.estop(&c);
            Ok(())
        })
        .await?;
    Ok(ok())
}

/// `POST /api/reset`: resets the E-stop and the supervisor latch (if SafeToRun allows).
pub async fn reset(State(state): State<AppState>, Csrf(auth): Csrf) -> ApiResult {
    let backend = std::sync::Arc::clone(&state.backend);
    state.command(&auth, Command::ResetFault, move |c| backend.reset(&c)).await?;
    Ok(ok())
}

/// `GET /api/safety`.
pub async fn safety(State(state): State<AppState>, _auth: Auth) -> ApiResult {
    Ok(Json(json!(state.backend.safety())))
}

/// Body of `PUT /api/safety/rules`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RulesBody {
    /// The rule file (TOML).
    pub toml: String,
}

/// `PUT /api/safety/rules` (admin only; lab refuses students and viewers, audited).
pub async fn safety_rules(
    State(state): State<AppState>,
    Csrf(auth): Csrf,
    Body(b): Body<RulesBody>,
) -> ApiResult {
    let action = Action::ChangeSafetyConfig { station: state.config.station.clone() };
    admin_only(&state, &auth, &action)?;
    let backend = std::sync::Arc::clone(&state.backend);
    let fp = state.authorized(&auth, &action, move |c| backend.set_safety_rules(&c, &b.toml)).await?;
    Ok(Json(json!({ "ok": true, "fingerprint": fp })))
}

/// `GET /api/groups`.
pub async fn groups(State(state): State<AppState>, _auth: Auth) -> ApiResult {
    Ok(Json(json!(state.backend.groups())))
}

/// `POST /api/groups/{id}`: robot go-to, pan-tilt target, arm joints. Authorised as a move
/// of every member axis at its default speed and acceleration: to its target for groups
/// whose targets are member positions (pan-tilt, arm, gantry), anywhere within its machine
/// limits otherwise (the robot's targets are a pose; a juggler program stays within its
/// drives' limits), so the lab checks students' position ranges as well as the speeds.
pub async fn group_command(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Csrf(auth): Csrf,
    Body(action): Body<GroupAction>,
) -> ApiResult {
    let group = state
        .backend
        .groups()
        .into_iter()
        .find(|g| g.id == id)
        .ok_or_else(|| ApiError::not_found(format!("no group {id:?}")))?;
    let axes = state.backend.axes();
    let op = if matches!(action, GroupAction::Stop) { AxisOp::Stop } else { AxisOp::Move };
    let positions = match &action {
        GroupAction::GoTo { targets } if group.kind != GroupKind::Robot => Some(targets.as_slice()),
        _ => None,
    };
    for (i, member) in group.axes.iter().enumerate() {
        let view = axes.iter().find(|a| a.id == *member);
        let demand = match (op, view) {
            (AxisOp::Move, Some(v)) => Some(match positions {
                Some(targets) => match targets.get(i) {
                    Some(&t) => MotionDemand::within(v.default_speed, v.acceleration, t, t),
                    // Too few targets: the backend refuses the command; state no position.
                    None => MotionDemand::new(v.default_speed, v.acceleration),
                },
                None => MotionDemand::within(v.default_speed, v.acceleration, v.limits.min, v.limits.max),
            }),
            _ => None,
        };
        let cmd = Command::Axis { axis: member.clone(), op, demand };
        state.check(&auth, &state.command_action(&auth, cmd))?;
    }
    // Every member was authorised above (denials audited); audit the group command once.
    let command = Command::Axis { axis: format!("group:{id}"), op, demand: None };
    let audited = Action::Command { station: id.clone(), command };
    let backend = std::sync::Arc::clone(&state.backend);
    state.run_and_record(&auth, &audited, move |c| backend.group_command(&c, &id, action)).await?;
    Ok(ok())
}

/// Runs a backend program function on a blocking thread: checking may take up to the
/// backend's check budget, and the async runtime (E-stop, login, the WebSocket) never waits
/// on program work.
pub(crate) async fn blocking<T, F>(f: F) -> Result<T, BackendError>
where
    T: Send + 'static,
    F: FnOnce() -> Result<T, BackendError> + Send + 'static,
{
    tokio::task::spawn_blocking(f)
        .await
        .unwrap_or_else(|e| Err(BackendError::Failed(format!("backend task failed: {e}"))))
}

/// `GET /api/programs`: the programs the caller may see (admins: every program; students:
/// their own and the published ones; viewers: the published ones).
pub async fn programs(State(state): State<AppState>, auth: Auth) -> ApiResult {
    let backend = std::sync::Arc::clone(&state.backend);
    let caller = auth.caller();
    let list = blocking(move || Ok(backend.programs(&caller))).await?;
    Ok(Json(json!(list)))
}

/// Body of `POST /api/programs`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UploadBody {
    /// File name.
    pub name: String,
    /// Program text.
    pub text: String,
}

/// One line per axis demand, for the audit log: `x [0, 0.5] m 0.1/s 1/s²`.
fn demands_text(demands: &[(String, MotionDemand)]) -> String {
    demands
        .iter()
        .map(|(axis, d)| match d.range {
            Some([lo, hi]) => format!("{axis} [{lo}, {hi}] v {} a {}", d.speed, d.acceleration),
            None => format!("{axis} v {} a {}", d.speed, d.acceleration),
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// The audit target of a program: `station/name (id)`, with its demands when known.
pub(crate) fn program_target(
    state: &AppState,
    id: &str,
    name: Option<&str>,
    demands: &[(String, MotionDemand)],
) -> String {
    let mut t = format!("{}/{} ({id})", state.config.station, name.unwrap_or(id));
    if !demands.is_empty() {
        t.push_str(" demands: ");
        t.push_str(&demands_text(demands));
    }
    t
}

/// Appends one audit entry about a program.
pub(crate) fn audit_program(
    state: &AppState,
    auth: &Auth,
    action: &str,
    target: String,
    outcome: AuditOutcome,
) {
    let entry = AuditEntry {
        time: state.now(),
        user: auth.session.user.clone(),
        action: action.into(),
        target,
        outcome,
    };
    if let Err(e) = state.lab.audit().append(&entry) {
        tracing::error!(error = %e, "audit write failed");
    }
}

/// The audit outcome of a backend refusal (`denied` for 403/404, `error` otherwise).
pub(crate) fn refusal(e: &ApiError) -> AuditOutcome {
    let message = format!("{} {}: {}", e.status.as_u16(), e.error, e.detail_text());
    if matches!(e.status, StatusCode::FORBIDDEN | StatusCode::NOT_FOUND) {
        AuditOutcome::Denied(message)
    } else {
        AuditOutcome::Error(message)
    }
}

/// Viewers neither check nor run programs (refused before any program work, audited as
/// `action`).
pub(crate) fn no_viewers(state: &AppState, auth: &Auth, action: &str, id: &str) -> Result<(), ApiError> {
    if auth.session.role == Role::Viewer {
        let e = ApiError::forbidden("viewers cannot check or run programs");
        audit_program(state, auth, action, program_target(state, id, None, &[]), refusal(&e));
        return Err(e.mark_audited());
    }
    Ok(())
}

/// The program's name and its check, on a blocking thread (not audited).
async fn check_for(
    state: &AppState,
    auth: &Auth,
    id: &str,
) -> (Option<String>, Result<ProgramCheck, ApiError>) {
    let backend = std::sync::Arc::clone(&state.backend);
    let caller = auth.caller();
    let id = id.to_owned();
    let r = blocking(move || {
        let name = backend.programs(&caller).into_iter().find(|p| p.id == id).map(|p| p.name);
        Ok((name, backend.check_program(&caller, &id)))
    })
    .await;
    match r {
        Ok((name, check)) => (name, check.map_err(ApiError::from)),
        Err(e) => (None, Err(ApiError::from(e))),
    }
}

/// Checks a program for `auth` and audits the check as `command.check_program`, with the
/// program, its demands or its first error.
async fn audited_check(state: &AppState, auth: &Auth, id: &str) -> Result<ProgramCheck, ApiError> {
    const ACTION: &str = "command.check_program";
    no_viewers(state, auth, ACTION, id)?;
    let (name, check) = check_for(state, auth, id).await;
    match check {
        Ok(check) => {
            let target = program_target(state, id, name.as_deref(), &check.demands);
            let outcome = match check.errors.first() {
                None => AuditOutcome::Ok,
                Some(e) => AuditOutcome::Error(format!("{}:{}: {}", e.line, e.col, e.message)),
            };
            audit_program(state, auth, ACTION, target, outcome);
            Ok(check)
        }
        Err(e) => {
            audit_program(state, auth, ACTION, program_target(state, id, name.as_deref(), &[]), refusal(&e));
            Err(e.mark_audited())
        }
    }
}

/// `POST /api/programs`: upload (registered with lab so it is removed at the end of the
/// slot), then checked within the station's budget; when every checker is busy the upload
/// stands and its check says so (check it again with `POST /api/programs/{id}/check`).
pub async fn upload_program(
    State(state): State<AppState>,
    Csrf(auth): Csrf,
    Body(b): Body<UploadBody>,
) -> ApiResult {
    let backend = std::sync::Arc::clone(&state.backend);
    let name = b.name.clone();
    let info = state
        .command(&auth, Command::Upload { name: b.name.clone() }, move |c| {
            backend.upload_program(&c, &name, &b.text)
        })
        .await?;
    // Kept with the slot it was uploaded in (a machine's or the whole cell's): removed with
    // that slot's clean-up unless exported.
    let meta = ProgramMeta {
        station: crate::machines::resource_for(&state, &auth.session.user, &Command::Trace, state.now()),
        owner: auth.session.user.clone(),
        kind: ProgramKind::Program,
        name: info.name.clone(),
        exported: false,
        size_bytes: info.size,
        created: state.now(),
    };
    state.lab.programs().register(&meta)?;
    let check = match audited_check(&state, &auth, &info.id).await {
        Ok(check) => json!(check),
        Err(e) => json!({
            "errors": [{ "line": 0, "col": 0, "message": format!(
                "not checked: {}; check it again with POST /api/programs/{}/check", e.detail_text(), info.id
            ) }],
            "demands": [],
        }),
    };
    Ok(Json(json!({ "program": info, "check": check })))
}

/// `POST /api/programs/{id}/check`: errors with line:col and per-axis demands (students:
/// their own and published programs; viewers: refused). Busy checkers: 503 at once.
pub async fn check_program(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Csrf(auth): Csrf,
) -> ApiResult {
    Ok(Json(json!(audited_check(&state, &auth, &id).await?)))
}

/// The lab command that runs program `id` with its per-axis demands, and its audit target.
/// A program `auth` may not see, one with errors (e.g. leaving the machine travel) or a
/// busy checker refuses it here, audited as `action` with the program and the error.
async fn program_command(
    state: &AppState,
    auth: &Auth,
    id: &str,
    action: &str,
) -> Result<(Command, String), ApiError> {
    no_viewers(state, auth, action, id)?;
    let (name, check) = check_for(state, auth, id).await;
    let check = match check {
        Ok(c) => c,
        Err(e) => {
            audit_program(state, auth, action, program_target(state, id, name.as_deref(), &[]), refusal(&e));
            return Err(e.mark_audited());
        }
    };
    let target = program_target(state, id, name.as_deref(), &check.demands);
    if let Some(e) = check.errors.first() {
        let message = format!("{}:{}: {}", e.line, e.col, e.message);
        audit_program(state, auth, action, target, AuditOutcome::Error(message.clone()));
        return Err(ApiError::invalid(json!({ "message": message, "errors": check.errors })).mark_audited());
    }
    Ok((Command::RunProgram { name: name.unwrap_or_else(|| id.to_string()), demands: check.demands }, target))
}

/// `POST /api/programs/{id}/run`: authorised by lab with the program's per-axis demands
/// (position range, peak speed and acceleration: students stay within their limits); the
/// run, or its refusal, is audited with the program and its demands.
pub async fn run_program(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Csrf(auth): Csrf,
) -> ApiResult {
    const ACTION: &str = "command.run_program";
    let (command, target) = program_command(&state, &auth, &id, ACTION).await?;
    let backend = std::sync::Arc::clone(&state.backend);
    authorize_and_run(&state, &auth, ACTION, command, target, move |c| backend.run_program(&c, &id)).await
}

/// Authorises `command` with lab (a denial audited as `action` with `target`), runs `f` on a
/// blocking thread, audits its result: the path of every program-like run (a stored
/// program, an MDI line).
pub(crate) async fn authorize_and_run<F>(
    state: &AppState,
    auth: &Auth,
    action: &str,
    command: Command,
    target: String,
    f: F,
) -> ApiResult
where
    F: FnOnce(crate::backend::Caller) -> Result<(), BackendError> + Send + 'static,
{
    let lab_action = state.command_action(auth, command);
    if let Err(e) =
        state.lab.authorizer().authorize(&auth.session.user, auth.session.role, &lab_action, state.now())
    {
        let outcome = match &e {
            motus_lab::AuthzError::Denied(d) => AuditOutcome::Denied(d.reason.to_string()),
            other => AuditOutcome::Error(other.to_string()),
        };
        audit_program(state, auth, action, target, outcome);
        return Err(ApiError::from(e).mark_audited());
    }
    let caller = auth.caller();
    let result = blocking(move || f(caller)).await;
    let outcome = match &result {
        Ok(()) => AuditOutcome::Ok,
        Err(e) => refusal(&ApiError::from(e.clone())),
    };
    audit_program(state, auth, action, target, outcome);
    result.map_err(|e| ApiError::from(e).mark_audited())?;
    Ok(ok())
}

async fn publish(state: AppState, auth: Auth, id: String, published: bool) -> ApiResult {
    let action = if published { "publish_program" } else { "unpublish_program" };
    if auth.session.role != Role::Admin {
        let e = ApiError::forbidden("admin only");
        audit_program(&state, &auth, action, program_target(&state, &id, None, &[]), refusal(&e));
        return Err(e.mark_audited());
    }
    let backend = std::sync::Arc::clone(&state.backend);
    let caller = auth.caller();
    let pid = id.clone();
    let result = blocking(move || backend.publish_program(&caller, &pid, published)).await;
    let name = result.as_ref().ok().map(|i| i.name.clone());
    let outcome = match &result {
        Ok(_) => AuditOutcome::Ok,
        Err(e) => refusal(&ApiError::from(e.clone())),
    };
    audit_program(&state, &auth, action, program_target(&state, &id, name.as_deref(), &[]), outcome);
    let info = result.map_err(|e| ApiError::from(e).mark_audited())?;
    Ok(Json(json!(info)))
}

/// `POST /api/programs/{id}/publish` (admin, audited): every student may see, check and run
/// the program, and it stays after its owner's slot.
pub async fn publish_program(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Csrf(auth): Csrf,
) -> ApiResult {
    publish(state, auth, id, true).await
}

/// `DELETE /api/programs/{id}/publish` (admin, audited): withdraws a publication.
pub async fn unpublish_program(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Csrf(auth): Csrf,
) -> ApiResult {
    publish(state, auth, id, false).await
}

/// `POST /api/programs/hold`.
pub async fn hold_program(State(state): State<AppState>, Csrf(auth): Csrf) -> ApiResult {
    let backend = std::sync::Arc::clone(&state.backend);
    state.command(&auth, Command::Stop, move |c| backend.hold_program(&c)).await?;
    Ok(ok())
}

/// `POST /api/programs/resume`: authorised like running the held program (or MDI line).
pub async fn resume_program(State(state): State<AppState>, Csrf(auth): Csrf) -> ApiResult {
    const ACTION: &str = "command.resume_program";
    let (command, _) = match state.backend.running_mdi() {
        Some(line) => crate::api_cnc::mdi_command(&state, &auth, &line, ACTION).await?,
        None => {
            let id = state
                .backend
                .program_status()
                .program
                .ok_or_else(|| ApiError::from(BackendError::State("no program to resume".into())))?;
            program_command(&state, &auth, &id, ACTION).await?
        }
    };
    let backend = std::sync::Arc::clone(&state.backend);
    state.command(&auth, command, move |c| backend.resume_program(&c)).await?;
    Ok(ok())
}

/// `POST /api/programs/stop`.
pub async fn stop_program(State(state): State<AppState>, Csrf(auth): Csrf) -> ApiResult {
    let backend = std::sync::Arc::clone(&state.backend);
    state.command(&auth, Command::Stop, move |c| backend.stop_program(&c)).await?;
    Ok(ok())
}

/// `GET /api/programs/status`.
pub async fn program_status(State(state): State<AppState>, _auth: Auth) -> ApiResult {
    Ok(Json(json!(state.backend.program_status())))
}

/// `GET /api/signals`.
pub async fn signals(State(state): State<AppState>, _auth: Auth) -> ApiResult {
    Ok(Json(json!(state.backend.signals())))
}

/// `GET /api/samples?cursor=N`.
pub async fn samples(
    State(state): State<AppState>,
    _auth: Auth,
    Query(q): Query<HashMap<String, String>>,
) -> ApiResult {
    let cursor = match q.get("cursor") {
        Some(c) => c.parse::<u64>().map_err(|_| ApiError::invalid("cursor must be an unsigned integer"))?,
        None => 0,
    };
    Ok(Json(json!(state.backend.samples_since(cursor))))
}

/// `GET /api/samples.csv`: the traced signals held by the station, as CSV (`t_s` and one
/// column per signal, named with its unit), for a spreadsheet or a plotting tool.
pub async fn samples_csv(
    State(state): State<AppState>,
    _auth: Auth,
) -> Result<axum::response::Response, ApiError> {
    use axum::response::IntoResponse;
    let signals = state.backend.signals();
    let batch = state.backend.samples_since(0);
    let mut csv = String::from("t_s");
    for s in &signals {
        csv.push_str(&format!(",{} [{}]", s.id, s.unit));
    }
    csv.push('\n');
    for row in &batch.samples {
        csv.push_str(&format!("{:.6}", row.t));
        for v in &row.values {
            csv.push_str(&format!(",{v}"));
        }
        csv.push('\n');
    }
    let headers = [
        (axum::http::header::CONTENT_TYPE, "text/csv; charset=utf-8"),
        (axum::http::header::CONTENT_DISPOSITION, "attachment; filename=\"motus-trace.csv\""),
    ];
    Ok((headers, csv).into_response())
}

/// `GET /api/trace.csv`: the cyclic tasks' signals at their full rate (e.g. 1 kHz), as CSV.
pub async fn trace_csv(
    State(state): State<AppState>,
    _auth: Auth,
) -> Result<axum::response::Response, ApiError> {
    use axum::response::IntoResponse;
    let csv = state
        .backend
        .trace_csv()
        .ok_or_else(|| ApiError::not_found("this station traces no cyclic signals"))?;
    let headers = [
        (axum::http::header::CONTENT_TYPE, "text/csv; charset=utf-8"),
        (axum::http::header::CONTENT_DISPOSITION, "attachment; filename=\"motus-cyclic-trace.csv\""),
    ];
    Ok((headers, csv).into_response())
}

/// `GET /api/tasks`: the cyclic task classes (cycle time, jitter, overruns, CPU).
pub async fn tasks(State(state): State<AppState>, _auth: Auth) -> ApiResult {
    Ok(Json(json!(state.backend.tasks())))
}

/// `GET /api/scene`.
pub async fn scene(State(state): State<AppState>, _auth: Auth) -> ApiResult {
    Ok(Json(json!(state.backend.scene())))
}

/// `GET /api/camera`.
pub async fn camera(State(state): State<AppState>, _auth: Auth) -> ApiResult {
    Ok(Json(json!({ "url": state.backend.camera_url() })))
}
