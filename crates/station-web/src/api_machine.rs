//! Machine routes: axes, E-stop, safety, groups, programs, signals, scene, camera.
//! Every command is authorised by lab and audited (see [`crate::server::Inner::command`]).

use std::collections::HashMap;

use axum::extract::{Path, Query, State};
use axum::Json;
use motus_lab::{Action, AxisOp, Command, MotionDemand, ProgramKind, ProgramMeta, Role};
use serde::Deserialize;
use serde_json::{json, Value};

use crate::auth::{Auth, Body, Csrf};
use crate::backend::{AxisAction, AxisParameters, AxisView, BackendError, GroupAction};
use crate::error::ApiError;
use crate::server::AppState;

type ApiResult = Result<Json<Value>, ApiError>;

fn ok() -> Json<Value> {
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
/// of every member axis at its default speed and acceleration.
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
    for member in &group.axes {
        let view = axes.iter().find(|a| a.id == *member);
        let demand = match (op, view) {
            (AxisOp::Move, Some(v)) => {
                Some(MotionDemand { speed: v.default_speed, acceleration: v.acceleration })
            }
            _ => None,
        };
        let cmd = Command::Axis { axis: member.clone(), op, demand };
        state.check(&auth, &Action::Command { station: state.config.station.clone(), command: cmd })?;
    }
    // Every member was authorised above (denials audited); audit the group command once.
    let command = Command::Axis { axis: format!("group:{id}"), op, demand: None };
    let audited = Action::Command { station: state.config.station.clone(), command };
    let backend = std::sync::Arc::clone(&state.backend);
    state.run_and_record(&auth, &audited, move |c| backend.group_command(&c, &id, action)).await?;
    Ok(ok())
}

/// `GET /api/programs`.
pub async fn programs(State(state): State<AppState>, _auth: Auth) -> ApiResult {
    Ok(Json(json!(state.backend.programs())))
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

/// `POST /api/programs`: upload (registered with lab so it is removed at the end of the slot).
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
    let meta = ProgramMeta {
        station: state.config.station.clone(),
        owner: auth.session.user.clone(),
        kind: ProgramKind::Program,
        name: info.name.clone(),
        exported: false,
        size_bytes: info.size,
        created: state.now(),
    };
    state.lab.programs().register(&meta)?;
    let check = state.backend.check_program(&info.id)?;
    Ok(Json(json!({ "program": info, "check": check })))
}

/// `POST /api/programs/{id}/check`.
pub async fn check_program(State(state): State<AppState>, Path(id): Path<String>, _auth: Csrf) -> ApiResult {
    Ok(Json(json!(state.backend.check_program(&id)?)))
}

fn program_command(state: &AppState, id: &str) -> Result<Command, ApiError> {
    let name = state.backend.programs().into_iter().find(|p| p.id == id).map(|p| p.name);
    let check = state.backend.check_program(id)?;
    if let Some(e) = check.errors.first() {
        return Err(ApiError::invalid(json!({
            "message": format!("{}:{}: {}", e.line, e.col, e.message),
            "errors": check.errors,
        })));
    }
    Ok(Command::RunProgram { name: name.unwrap_or_else(|| id.to_string()), demands: check.demands })
}

/// `POST /api/programs/{id}/run`: authorised with the program's per-axis peak demands.
pub async fn run_program(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Csrf(auth): Csrf,
) -> ApiResult {
    let command = program_command(&state, &id)?;
    let backend = std::sync::Arc::clone(&state.backend);
    state.command(&auth, command, move |c| backend.run_program(&c, &id)).await?;
    Ok(ok())
}

/// `POST /api/programs/hold`.
pub async fn hold_program(State(state): State<AppState>, Csrf(auth): Csrf) -> ApiResult {
    let backend = std::sync::Arc::clone(&state.backend);
    state.command(&auth, Command::Stop, move |c| backend.hold_program(&c)).await?;
    Ok(ok())
}

/// `POST /api/programs/resume`: authorised like running the held program.
pub async fn resume_program(State(state): State<AppState>, Csrf(auth): Csrf) -> ApiResult {
    let id = state
        .backend
        .program_status()
        .program
        .ok_or_else(|| ApiError::from(BackendError::State("no program to resume".into())))?;
    let command = program_command(&state, &id)?;
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
