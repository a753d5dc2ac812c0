//! API errors: every failure is JSON `{ "error": "...", "detail": ... }` with a status code
//! (400 invalid, 401 not logged in, 403 forbidden with the reason, 404, 409 conflict with a
//! slot or the supervisor, 429 rate-limited with `Retry-After`, 500).

use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use motus_lab::{AuthzError, ReservationError, StoreError, UserError};
use serde_json::{json, Value};

use crate::backend::BackendError;

/// An error answered to an API client.
#[derive(Debug, Clone, PartialEq)]
pub struct ApiError {
    /// HTTP status.
    pub status: StatusCode,
    /// Short machine-readable code (`forbidden`, `csrf`, `not_logged_in`...).
    pub error: String,
    /// Details (a message, a deny reason, a field...).
    pub detail: Value,
    /// Seconds for `Retry-After` (429).
    pub retry_after: Option<u64>,
    /// The refusal is in the audit log already (the request is not audited again by
    /// [`crate::auth::audit_refusals`]).
    pub audited: bool,
}

impl ApiError {
    /// An error with a text detail.
    #[must_use]
    pub fn new(status: StatusCode, error: &str, detail: impl Into<Value>) -> Self {
        ApiError {
            status,
            error: error.to_string(),
            detail: detail.into(),
            retry_after: None,
            audited: false,
        }
    }

    /// The same error, marked as audited already.
    #[must_use]
    pub fn mark_audited(mut self) -> Self {
        self.audited = true;
        self
    }

    /// The detail as one line of text (its `message` when it is an object with one).
    #[must_use]
    pub fn detail_text(&self) -> String {
        match &self.detail {
            Value::String(s) => s.clone(),
            Value::Object(o) => match o.get("message") {
                Some(Value::String(m)) => m.clone(),
                _ => self.detail.to_string(),
            },
            other => other.to_string(),
        }
    }

    /// 400.
    #[must_use]
    pub fn invalid(detail: impl Into<Value>) -> Self {
        Self::new(StatusCode::BAD_REQUEST, "invalid", detail)
    }

    /// 401.
    #[must_use]
    pub fn unauthenticated(detail: impl Into<Value>) -> Self {
        Self::new(StatusCode::UNAUTHORIZED, "not_logged_in", detail)
    }

    /// 403.
    #[must_use]
    pub fn forbidden(detail: impl Into<Value>) -> Self {
        Self::new(StatusCode::FORBIDDEN, "forbidden", detail)
    }

    /// 404.
    #[must_use]
    pub fn not_found(detail: impl Into<Value>) -> Self {
        Self::new(StatusCode::NOT_FOUND, "not_found", detail)
    }

    /// 500.
    #[must_use]
    pub fn internal(detail: impl Into<Value>) -> Self {
        Self::new(StatusCode::INTERNAL_SERVER_ERROR, "internal", detail)
    }
}

/// The response carries the error itself as an extension, for the audit middleware.
impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let mut r =
            (self.status, Json(json!({ "error": self.error, "detail": self.detail }))).into_response();
        if let Some(s) = self.retry_after {
            if let Ok(v) = HeaderValue::from_str(&s.to_string()) {
                r.headers_mut().insert(header::RETRY_AFTER, v);
            }
        }
        r.extensions_mut().insert(self);
        r
    }
}

impl From<AuthzError> for ApiError {
    fn from(e: AuthzError) -> Self {
        match e {
            AuthzError::Denied(d) => ApiError::forbidden(json!({
                "message": d.reason.to_string(),
                "reason": serde_json::to_value(&d.reason).unwrap_or(Value::Null),
            })),
            AuthzError::Store(s) => ApiError::internal(s.to_string()),
        }
    }
}

impl From<StoreError> for ApiError {
    fn from(e: StoreError) -> Self {
        ApiError::internal(e.to_string())
    }
}

impl From<BackendError> for ApiError {
    fn from(e: BackendError) -> Self {
        let status = match &e {
            BackendError::Invalid { .. } => StatusCode::BAD_REQUEST,
            BackendError::NotFound { .. } => StatusCode::NOT_FOUND,
            BackendError::SafetyHold(_) | BackendError::EStopped | BackendError::State(_) => {
                StatusCode::CONFLICT
            }
            BackendError::Failed(_) => StatusCode::INTERNAL_SERVER_ERROR,
            BackendError::Forbidden(_) => StatusCode::FORBIDDEN,
            BackendError::Busy(_) => StatusCode::SERVICE_UNAVAILABLE,
        };
        let code = match &e {
            BackendError::Invalid { .. } => "invalid",
            BackendError::NotFound { .. } => "not_found",
            BackendError::SafetyHold(_) => "safety_hold",
            BackendError::EStopped => "estop",
            BackendError::State(_) => "state",
            BackendError::Failed(_) => "machine_failure",
            BackendError::Forbidden(_) => "forbidden",
            BackendError::Busy(_) => "busy",
        };
        ApiError::new(status, code, e.to_string())
    }
}

impl From<ReservationError> for ApiError {
    fn from(e: ReservationError) -> Self {
        match e {
            ReservationError::Denied(d) => AuthzError::Denied(d).into(),
            ReservationError::Overlap(r) => ApiError::new(
                StatusCode::CONFLICT,
                "slot_conflict",
                json!({ "message": format!("overlaps reservation {} of {}", r.id, r.user), "reservation": *r }),
            ),
            ReservationError::NotFound(_) | ReservationError::NoActiveSlot(_) => {
                ApiError::not_found(e.to_string())
            }
            ReservationError::AlreadyEnded(_) => {
                ApiError::new(StatusCode::CONFLICT, "slot_conflict", e.to_string())
            }
            ReservationError::Store(s) => s.into(),
            other => ApiError::invalid(other.to_string()),
        }
    }
}

impl From<UserError> for ApiError {
    fn from(e: UserError) -> Self {
        match e {
            UserError::Exists(_) => ApiError::new(StatusCode::CONFLICT, "exists", e.to_string()),
            UserError::NotFound(_) => ApiError::not_found(e.to_string()),
            UserError::LastAdmin(_) => ApiError::new(StatusCode::CONFLICT, "last_admin", e.to_string()),
            UserError::InvalidName { .. } | UserError::WeakPassword(_) => ApiError::invalid(e.to_string()),
            other => ApiError::internal(other.to_string()),
        }
    }
}
