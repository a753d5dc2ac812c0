//! The web HMI's files, built into the binary (no internet, no build step at run time).

use axum::http::header;
use axum::response::IntoResponse;

/// `assets/index.html`.
pub const INDEX_HTML: &str = include_str!("../assets/index.html");
/// `assets/app.js`.
pub const APP_JS: &str = include_str!("../assets/app.js");
/// `assets/style.css`.
pub const STYLE_CSS: &str = include_str!("../assets/style.css");

/// Headers every HMI file gets: no caching of a stale HMI, no framing by other sites, and a
/// content security policy that allows only this origin (plus images and frames from
/// anywhere, for the external camera URL).
fn headers(content_type: &'static str) -> [(header::HeaderName, &'static str); 4] {
    [
        (header::CONTENT_TYPE, content_type),
        (header::CACHE_CONTROL, "no-cache"),
        (header::X_FRAME_OPTIONS, "DENY"),
        (
            header::CONTENT_SECURITY_POLICY,
            "default-src 'self'; img-src * data:; frame-src *; connect-src 'self'; frame-ancestors 'none'",
        ),
    ]
}

/// `GET /`.
pub async fn index() -> impl IntoResponse {
    (headers("text/html; charset=utf-8"), INDEX_HTML)
}

/// `GET /app.js`.
pub async fn app_js() -> impl IntoResponse {
    (headers("text/javascript; charset=utf-8"), APP_JS)
}

/// `GET /style.css`.
pub async fn style_css() -> impl IntoResponse {
    (headers("text/css; charset=utf-8"), STYLE_CSS)
}
