//! CNC runner routes beyond run/hold/resume/stop: feed override, single block, the preview
//! of a checked program, the executed path, and MDI (one line executed as a program).
//!
//! Override and single block change the program in progress, so they are authorised like
//! hold (whoever may command the station now: the booked user or an administrator); the
//! backend holds students to 100 % (their programs were checked against the student limits
//! at 100 %). An MDI line is checked like a program (machine travel for everyone, the student
//! limits for students, by lab with its demands), then run. Every command and refusal is
//! audited.

use axum::extract::{Path, Query, State};
use axum::Json;
use motus_lab::{AuditOutcome, Command};
use serde::Deserialize;
use serde_json::json;

use crate::api_machine::{
    audit_program, authorize_and_run, blocking, no_viewers, ok, program_target, refusal,
};
use crate::auth::{Auth, Body, Csrf};
use crate::backend::{BackendError, ProgramCheck};
use crate::error::ApiError;
use crate::server::AppState;

type ApiResult = Result<Json<serde_json::Value>, ApiError>;

/// Longest MDI line, bytes.
pub const MDI_MAX_LEN: usize = 256;

/// The audit target of the runner's settings.
fn runner_target(state: &AppState, what: String) -> String {
    format!("{}/program runner: {what}", state.config.station)
}

/// Authorises a runner setting like hold, runs it, audits it as `action`.
async fn runner_setting<F>(state: &AppState, auth: &Auth, action: &str, what: String, f: F) -> ApiResult
where
    F: FnOnce(crate::backend::Caller) -> Result<(), BackendError> + Send + 'static,
{
    let target = runner_target(state, what);
    let lab_action = state.command_action(auth, Command::Stop);
    if let Err(e) = state.check(auth, &lab_action) {
        audit_program(state, auth, action, target, refusal(&e));
        return Err(e);
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

/// Body of `POST /api/programs/override`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OverrideBody {
    /// Percent, 0-200 (students: at most 100).
    pub percent: f64,
}

/// `POST /api/programs/override`: the feed override of the running program and later runs.
pub async fn set_override(
    State(state): State<AppState>,
    Csrf(auth): Csrf,
    Body(b): Body<OverrideBody>,
) -> ApiResult {
    let backend = std::sync::Arc::clone(&state.backend);
    let what = format!("feed override {} %", b.percent);
    runner_setting(&state, &auth, "command.program_override", what, move |c| {
        backend.set_program_override(&c, b.percent)
    })
    .await
}

/// Body of `POST /api/programs/single-block`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SingleBlockBody {
    /// On or off.
    pub on: bool,
}

/// `POST /api/programs/single-block`: stop after each block (resume = cycle start).
pub async fn set_single_block(
    State(state): State<AppState>,
    Csrf(auth): Csrf,
    Body(b): Body<SingleBlockBody>,
) -> ApiResult {
    let backend = std::sync::Arc::clone(&state.backend);
    let what = format!("single block {}", if b.on { "on" } else { "off" });
    runner_setting(&state, &auth, "command.program_single_block", what, move |c| {
        backend.set_single_block(&c, b.on)
    })
    .await
}

/// `GET /api/programs/{id}/preview`: the tool path of a program the caller may check (its
/// cached check; viewers: refused).
pub async fn preview(State(state): State<AppState>, Path(id): Path<String>, auth: Auth) -> ApiResult {
    let backend = std::sync::Arc::clone(&state.backend);
    let caller = auth.caller();
    let p = blocking(move || backend.program_preview(&caller, &id)).await.map_err(ApiError::from)?;
    Ok(Json(json!(p)))
}

/// Query of `GET /api/programs/path`.
#[derive(Debug, Deserialize)]
pub struct PathQuery {
    /// The run the cursor belongs to (0: none yet).
    #[serde(default)]
    pub run: u64,
    /// Cursor (0: from the run's start).
    #[serde(default)]
    pub cursor: u64,
}

/// `GET /api/programs/path?run=R&cursor=N`: the executed path since a cursor (bounded batch).
pub async fn executed_path(
    State(state): State<AppState>,
    _auth: Auth,
    Query(q): Query<PathQuery>,
) -> ApiResult {
    Ok(Json(json!(state.backend.executed_path(q.run, q.cursor))))
}

/// Body of `POST /api/mdi`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MdiBody {
    /// One G-code line.
    pub line: String,
}

/// The lab command that runs MDI `line` with its demands, and its audit target: the line
/// checked as a program (viewers, errors and a busy checker refused here, audited as
/// `action`).
pub(crate) async fn mdi_command(
    state: &AppState,
    auth: &Auth,
    line: &str,
    action: &str,
) -> Result<(Command, String), ApiError> {
    let shown: String = line.chars().take(MDI_MAX_LEN).collect();
    let target = |demands: &[(String, motus_lab::MotionDemand)]| {
        program_target(state, "mdi", Some(&format!("MDI {shown:?}")), demands)
    };
    no_viewers(state, auth, action, "mdi")?;
    let backend = std::sync::Arc::clone(&state.backend);
    let caller = auth.caller();
    let owned = line.to_owned();
    let check: Result<ProgramCheck, ApiError> =
        blocking(move || backend.check_mdi(&caller, &owned)).await.map_err(ApiError::from);
    let check = match check {
        Ok(c) => c,
        Err(e) => {
            audit_program(state, auth, action, target(&[]), refusal(&e));
            return Err(e.mark_audited());
        }
    };
    if let Some(e) = check.errors.first() {
        let message = format!("{}:{}: {}", e.line, e.col, e.message);
        audit_program(state, auth, action, target(&check.demands), AuditOutcome::Error(message.clone()));
        return Err(ApiError::invalid(json!({ "message": message, "errors": check.errors })).mark_audited());
    }
    let t = target(&check.demands);
    Ok((Command::RunProgram { name: format!("MDI {shown}"), demands: check.demands }, t))
}

/// `POST /api/mdi`: one line checked as a program (errors, travel, demands authorised by lab,
/// the student limits), then executed on the machine; audited as `command.mdi`.
pub async fn mdi(State(state): State<AppState>, Csrf(auth): Csrf, Body(b): Body<MdiBody>) -> ApiResult {
    const ACTION: &str = "command.mdi";
    let (command, target) = mdi_command(&state, &auth, &b.line, ACTION).await?;
    let backend = std::sync::Arc::clone(&state.backend);
    authorize_and_run(&state, &auth, ACTION, command, target, move |c| backend.run_mdi(&c, &b.line)).await
}
