//! Request authentication: the session cookie ([`Auth`]), the CSRF header for mutating
//! requests ([`Csrf`]), JSON bodies with JSON errors ([`Body`]), the authorise-run-audit
//! helper every command goes through ([`Inner::command`]), and the middleware that audits
//! every refusal no handler audited ([`audit_refusals`]).

use axum::async_trait;
use axum::extract::rejection::JsonRejection;
use axum::extract::{FromRequest, FromRequestParts, Request, State};
use axum::http::request::Parts;
use axum::http::{header, HeaderMap, Method, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use axum::Json;
use motus_lab::{Action, Actor, AuditEntry, AuditOutcome, Command, Role, SessionError, SessionInfo};
use serde::de::DeserializeOwned;

use crate::backend::{BackendError, Caller};
use crate::error::ApiError;
use crate::server::{AppState, Inner};

/// Header carrying the CSRF token on every mutating request.
pub const CSRF_HEADER: &str = "x-csrf-token";

/// A logged-in user (valid session cookie).
#[derive(Debug, Clone)]
pub struct Auth {
    /// The session.
    pub session: SessionInfo,
}

impl Auth {
    /// The lab actor.
    #[must_use]
    pub fn actor(&self) -> Actor {
        Actor::new(&self.session.user, self.session.role)
    }

    /// The backend caller.
    #[must_use]
    pub fn caller(&self) -> Caller {
        Caller::new(&self.session.user, self.session.role)
    }
}

/// A logged-in user whose request carries the right `X-CSRF-Token`.
#[derive(Debug, Clone)]
pub struct Csrf(pub Auth);

/// The session token from the request's cookies.
#[must_use]
pub fn session_token(state: &Inner, headers: &HeaderMap) -> Option<String> {
    let cookie = &state.lab.sessions().policy().cookie;
    headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .find_map(|h| cookie.token_from_header(h).map(str::to_string))
}

/// Looks up the session of `headers`.
///
/// # Errors
/// 401 without a valid session, 500 on a storage failure.
pub fn authenticate(state: &Inner, headers: &HeaderMap) -> Result<Auth, ApiError> {
    let token =
        session_token(state, headers).ok_or_else(|| ApiError::unauthenticated("no session cookie"))?;
    match state.lab.sessions().lookup(&token, state.now()) {
        Ok(session) => Ok(Auth { session }),
        Err(e @ (SessionError::Unknown | SessionError::Expired(_) | SessionError::UserGone(_))) => {
            Err(ApiError::unauthenticated(e.to_string()))
        }
        Err(e) => Err(ApiError::internal(e.to_string())),
    }
}

#[async_trait]
impl FromRequestParts<AppState> for Auth {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &AppState) -> Result<Self, Self::Rejection> {
        authenticate(state, &parts.headers)
    }
}

#[async_trait]
impl FromRequestParts<AppState> for Csrf {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &AppState) -> Result<Self, Self::Rejection> {
        let auth = authenticate(state, &parts.headers)?;
        let presented = parts.headers.get(CSRF_HEADER).and_then(|v| v.to_str().ok());
        if state.lab.sessions().check_csrf(&auth.session, presented).is_err() {
            let entry = AuditEntry {
                time: state.now(),
                user: auth.session.user.clone(),
                action: "csrf".into(),
                target: format!("{} {}", parts.method, parts.uri.path()),
                outcome: AuditOutcome::Denied("CSRF token missing or wrong".into()),
            };
            if let Err(e) = state.lab.audit().append(&entry) {
                tracing::error!(error = %e, "audit write failed");
            }
            return Err(ApiError::new(StatusCode::FORBIDDEN, "csrf", "X-CSRF-Token header missing or wrong")
                .mark_audited());
        }
        Ok(Csrf(auth))
    }
}

/// A JSON body whose parse errors are answered as 400 `{ "error": "invalid" }`.
#[derive(Debug, Clone)]
pub struct Body<T>(pub T);

#[async_trait]
impl<S, T> FromRequest<S> for Body<T>
where
    T: DeserializeOwned,
    S: Send + Sync,
{
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &S) -> Result<Self, Self::Rejection> {
        match Json::<T>::from_request(req, state).await {
            Ok(Json(v)) => Ok(Body(v)),
            Err(e @ JsonRejection::MissingJsonContentType(_)) => Err(ApiError::invalid(e.body_text())),
            Err(e) => Err(ApiError::invalid(e.body_text())),
        }
    }
}

impl Inner {
    /// A station command: authorise with lab (denials audited), run `f` on a blocking
    /// thread, audit its result.
    ///
    /// # Errors
    /// 403 when refused, the backend's error mapped to its status otherwise.
    pub async fn command<T, F>(&self, auth: &Auth, command: Command, f: F) -> Result<T, ApiError>
    where
        T: Send + 'static,
        F: FnOnce(Caller) -> Result<T, BackendError> + Send + 'static,
    {
        let action = self.command_action(auth, command);
        self.authorized(auth, &action, f).await
    }

    /// The lab action of `command` by `auth`, on the reservation a student needs: the
    /// machine of its axes, the whole cell, or any slot held now for a command on the whole
    /// station ([`crate::machines::resource_for`]). Admins (any time), viewers (never) and
    /// the E-stop (everyone's, at any time) need no slot: the station's name, without
    /// reading a reservation.
    #[must_use]
    pub fn command_action(&self, auth: &Auth, command: Command) -> Action {
        let station = if auth.session.role == Role::Student && !matches!(command, Command::EStop) {
            crate::machines::resource_for(self, &auth.session.user, &command, self.now())
        } else {
            self.config.station.clone()
        };
        Action::Command { station, command }
    }

    /// [`Inner::command`] for any lab action.
    ///
    /// # Errors
    /// 403 when refused, the backend's error mapped to its status otherwise.
    pub async fn authorized<T, F>(&self, auth: &Auth, action: &Action, f: F) -> Result<T, ApiError>
    where
        T: Send + 'static,
        F: FnOnce(Caller) -> Result<T, BackendError> + Send + 'static,
    {
        self.check(auth, action)?;
        self.run_and_record(auth, action, f).await
    }

    /// Runs `f` on a blocking thread and audits its result as `action` (the caller has
    /// authorised it already): `ok`, `denied` when the backend refuses this caller (403:
    /// e.g. a student resetting an E-stop an administrator pressed, or homing an axis without
    /// student limits; 404), `error` otherwise.
    ///
    /// # Errors
    /// The backend's error mapped to its status.
    pub async fn run_and_record<T, F>(&self, auth: &Auth, action: &Action, f: F) -> Result<T, ApiError>
    where
        T: Send + 'static,
        F: FnOnce(Caller) -> Result<T, BackendError> + Send + 'static,
    {
        let actor = auth.actor();
        let caller = auth.caller();
        let result = tokio::task::spawn_blocking(move || f(caller))
            .await
            .map_err(|e| ApiError::internal(format!("backend task failed: {e}")))?;
        let outcome = match &result {
            Ok(_) => AuditOutcome::Ok,
            Err(e @ (BackendError::Forbidden(_) | BackendError::NotFound { .. })) => {
                AuditOutcome::Denied(e.to_string())
            }
            Err(e) => AuditOutcome::Error(e.to_string()),
        };
        if let Err(e) = self.lab.audit().record(&actor, action, outcome, self.now()) {
            tracing::error!(error = %e, "audit write failed");
        }
        result.map_err(|e| ApiError::from(e).mark_audited())
    }

    /// Authorises `action` (denials audited) without running anything.
    ///
    /// # Errors
    /// 403 when refused.
    pub fn check(&self, auth: &Auth, action: &Action) -> Result<(), ApiError> {
        self.lab.authorize(&auth.actor(), action, self.now()).map_err(|e| ApiError::from(e).mark_audited())
    }

    /// Audits an admin action that has no lab [`Action`] of its own.
    pub fn audit(&self, auth: &Auth, action: &str, target: &str, result: Result<(), String>) {
        let outcome = match result {
            Ok(()) => AuditOutcome::Ok,
            Err(m) => AuditOutcome::Error(m),
        };
        let entry = AuditEntry {
            time: self.now(),
            user: auth.session.user.clone(),
            action: action.into(),
            target: target.into(),
            outcome,
        };
        if let Err(e) = self.lab.audit().append(&entry) {
            tracing::error!(error = %e, "audit write failed");
        }
    }

    /// True if `auth` may command the station now (admin, or student holding the slot).
    #[must_use]
    pub fn can_command(&self, auth: &Auth) -> bool {
        match auth.session.role {
            Role::Admin => true,
            Role::Viewer => false,
            Role::Student => {
                let probe = self.command_action(auth, Command::Stop);
                self.lab.authorizer().authorize(&auth.session.user, Role::Student, &probe, self.now()).is_ok()
            }
        }
    }
}

/// Longest refusal message written to the audit log.
const MAX_AUDIT_MESSAGE: usize = 300;

/// The refusal as one line: `status error: detail`, from the [`ApiError`] the response
/// carries, else from its (small) body. Returns the response rebuilt.
async fn refusal_text(response: Response, known: Option<&ApiError>) -> (Response, String) {
    let status = response.status();
    if let Some(e) = known {
        return (response, format!("{} {}: {}", status.as_u16(), e.error, e.detail_text()));
    }
    let (mut parts, body) = response.into_parts();
    match axum::body::to_bytes(body, 16 * 1024).await {
        Ok(bytes) => {
            let text = String::from_utf8_lossy(&bytes).trim().to_string();
            let text = if text.is_empty() {
                status.canonical_reason().unwrap_or_default().to_string()
            } else {
                text
            };
            (
                Response::from_parts(parts, axum::body::Body::from(bytes)),
                format!("{} {text}", status.as_u16()),
            )
        }
        Err(_) => {
            parts.headers.remove(header::CONTENT_LENGTH);
            (Response::from_parts(parts, axum::body::Body::empty()), status.to_string())
        }
    }
}

fn truncated(mut s: String) -> String {
    if s.len() > MAX_AUDIT_MESSAGE {
        let mut end = MAX_AUDIT_MESSAGE;
        while !s.is_char_boundary(end) {
            end -= 1;
        }
        s.truncate(end);
        s.push('…');
    }
    s
}

fn append_refusal(state: &Inner, user: &str, target: String, status: StatusCode, message: String) {
    let message = truncated(message);
    let outcome = if matches!(status, StatusCode::UNAUTHORIZED | StatusCode::FORBIDDEN) {
        AuditOutcome::Denied(message)
    } else {
        AuditOutcome::Error(message)
    };
    let entry =
        AuditEntry { time: state.now(), user: user.into(), action: "request".into(), target, outcome };
    if let Err(e) = state.lab.audit().append(&entry) {
        tracing::error!(error = %e, "audit write failed");
    }
}

/// Middleware: audits, as action `request` on `METHOD path`, every refusal no handler
/// audited (the handlers' own refusals carry [`ApiError::audited`]; the login's are audited
/// by lab):
///
/// - a mutating request (not GET, HEAD or OPTIONS) answered 4xx: a body the extractors
///   rejected (bad JSON, no JSON content type, too large), a missing or expired session,
///   an unknown route or method;
/// - an API route miss (404 or 405 under `/api/`) of a logged-in user.
///
/// The user is the session's, `anonymous` without one. An API route miss without a valid
/// session is answered 401, as every API route is: the API's shape is not shown before
/// authentication.
pub async fn audit_refusals(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let method = req.method().clone();
    let path = req.uri().path().to_string();
    let token = session_token(&state, req.headers());
    let response = next.run(req).await;
    let status = response.status();
    if !status.is_client_error() {
        return response;
    }
    let known = response.extensions().get::<ApiError>().cloned();
    if known.as_ref().is_some_and(|e| e.audited) {
        return response;
    }
    if path == "/api/login" && matches!(status, StatusCode::UNAUTHORIZED | StatusCode::TOO_MANY_REQUESTS) {
        return response; // lab's login audits its own refusals
    }
    let mutating = !matches!(method, Method::GET | Method::HEAD | Method::OPTIONS);
    let route_miss =
        path.starts_with("/api/") && matches!(status, StatusCode::NOT_FOUND | StatusCode::METHOD_NOT_ALLOWED);
    if !mutating && !route_miss {
        return response;
    }
    let user = token.and_then(|t| state.lab.sessions().lookup(&t, state.now()).ok()).map(|s| s.user);
    let target = format!("{method} {path}");
    if route_miss && user.is_none() {
        let e = ApiError::unauthenticated("log in first");
        if mutating {
            let message = format!("{} {}: {}", e.status.as_u16(), e.error, e.detail_text());
            append_refusal(&state, "anonymous", target, e.status, message);
        }
        return e.mark_audited().into_response();
    }
    let (response, message) = refusal_text(response, known.as_ref()).await;
    append_refusal(&state, user.as_deref().unwrap_or("anonymous"), target, status, message);
    response
}
