//! An external HTTP camera fetched for one viewer: an MJPEG stream
//! (`multipart/x-mixed-replace`, the common lab cameras' `video.mjpg`) is re-sent frame by
//! frame, a still JPEG (`snapshot.jpg`) is fetched again [`STILL_PER_SECOND`] times a second.
//!
//! The request is plain HTTP/1.0 (no chunked answers to decode). Everything the camera
//! sends is bounded: the head to [`MAX_HEAD`] bytes, a picture to [`MAX_FRAME`] bytes, each
//! wait for data to [`READ_TIME_OUT`]. When the camera cannot be reached or answers
//! something else, the viewer gets a "no signal" picture and the station tries again every
//! [`RETRY`].

use std::time::{Duration, Instant};

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use super::{render, Viewer};

/// Longest response head accepted from a camera.
pub const MAX_HEAD: usize = 16 * 1024;
/// Largest picture accepted from a camera.
pub const MAX_FRAME: usize = 4 * 1024 * 1024;
/// Longest wait for the camera's next bytes.
pub const READ_TIME_OUT: Duration = Duration::from_secs(10);
/// Pause before trying an unreachable camera again.
pub const RETRY: Duration = Duration::from_secs(2);
/// How often a still-image camera is fetched.
pub const STILL_PER_SECOND: f64 = 10.0;
/// Most frames per second passed on from a streaming camera (the rest are dropped).
pub const MAX_RELAYED_PER_SECOND: f64 = 30.0;

/// Why a camera's answer was not used.
#[derive(Debug, thiserror::Error)]
pub enum RelayError {
    /// The URL is not `http://host[:port]/path`.
    #[error("camera URL {0:?} is not http://host[:port]/path")]
    Url(String),
    /// Connecting, sending or reading failed.
    #[error("camera {url}: {source}")]
    Io {
        /// The camera.
        url: String,
        /// The error.
        source: std::io::Error,
    },
    /// The camera answered, but not with pictures.
    #[error("camera {url}: {why}")]
    Answer {
        /// The camera.
        url: String,
        /// What was wrong.
        why: String,
    },
    /// The viewer left (not an error of the camera).
    #[error("viewer left")]
    ViewerLeft,
}

/// `host:port` and path of an `http://` URL.
fn split_url(url: &str) -> Option<(String, String)> {
    let rest = url.strip_prefix("http://")?;
    let (authority, path) = match rest.find('/') {
        Some(i) => rest.split_at(i),
        None => (rest, "/"),
    };
    if authority.is_empty() || authority.contains('@') {
        return None;
    }
    // A port follows the last colon unless that colon is inside an IPv6 address's brackets.
    let has_port = authority.rsplit_once(':').is_some_and(|(_, port)| !port.contains(']'));
    let addr = if has_port { authority.to_string() } else { format!("{authority}:80") };
    Some((addr, path.to_string()))
}

/// Bytes read from the camera, kept until used.
struct Upstream {
    stream: TcpStream,
    buf: Vec<u8>,
    url: String,
}

impl Upstream {
    fn io(&self, source: std::io::Error) -> RelayError {
        RelayError::Io { url: self.url.clone(), source }
    }

    fn answer(&self, why: impl Into<String>) -> RelayError {
        RelayError::Answer { url: self.url.clone(), why: why.into() }
    }

    /// Reads more bytes; `Ok(false)` at the end of the stream.
    async fn fill(&mut self) -> Result<bool, RelayError> {
        let mut chunk = [0u8; 16 * 1024];
        let n = match tokio::time::timeout(READ_TIME_OUT, self.stream.read(&mut chunk)).await {
            Ok(Ok(n)) => n,
            Ok(Err(e)) => return Err(self.io(e)),
            Err(_) => return Err(self.answer(format!("nothing received for {} s", READ_TIME_OUT.as_secs()))),
        };
        self.buf.extend_from_slice(chunk.get(..n).unwrap_or_default());
        Ok(n > 0)
    }

    /// Everything up to and including `pattern` (at most `max` bytes before it).
    async fn until(&mut self, pattern: &[u8], max: usize, what: &str) -> Result<Vec<u8>, RelayError> {
        let mut from = 0;
        loop {
            if let Some(i) = find(self.buf.get(from..).unwrap_or_default(), pattern) {
                let end = from + i + pattern.len();
                return Ok(self.buf.drain(..end).collect());
            }
            if self.buf.len() > max + pattern.len() {
                return Err(self.answer(format!("{what} longer than {max} bytes")));
            }
            from = self.buf.len().saturating_sub(pattern.len());
            if !self.fill().await? {
                return Err(
                    self.answer(format!("the camera closed the connection in the middle of the {what}"))
                );
            }
        }
    }

    /// Exactly `n` bytes.
    async fn exact(&mut self, n: usize) -> Result<Vec<u8>, RelayError> {
        while self.buf.len() < n {
            if !self.fill().await? {
                return Err(self.answer("the camera closed the connection in the middle of a picture"));
            }
        }
        Ok(self.buf.drain(..n).collect())
    }

    /// Everything until the camera closes the connection (at most `max` bytes).
    async fn read_to_close(&mut self, max: usize) -> Result<Vec<u8>, RelayError> {
        while self.fill().await? {
            if self.buf.len() > max {
                return Err(self.answer(format!("picture larger than {max} bytes")));
            }
        }
        Ok(std::mem::take(&mut self.buf))
    }
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

/// The response head: status and headers (names in lower case).
struct Head {
    status: u16,
    headers: Vec<(String, String)>,
}

impl Head {
    fn get(&self, name: &str) -> Option<&str> {
        self.headers.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_str())
    }
}

fn parse_headers(text: &str) -> Vec<(String, String)> {
    text.lines()
        .filter_map(|l| l.split_once(':'))
        .map(|(n, v)| (n.trim().to_ascii_lowercase(), v.trim().to_string()))
        .collect()
}

/// Connects and asks for the URL; returns the connection after the response head.
async fn request(url: &str) -> Result<(Upstream, Head), RelayError> {
    let (addr, path) = split_url(url).ok_or_else(|| RelayError::Url(url.to_string()))?;
    let io = |source| RelayError::Io { url: url.to_string(), source };
    let stream = match tokio::time::timeout(READ_TIME_OUT, TcpStream::connect(&addr)).await {
        Ok(Ok(s)) => s,
        Ok(Err(e)) => return Err(io(e)),
        Err(_) => return Err(io(std::io::Error::new(std::io::ErrorKind::TimedOut, "connection timed out"))),
    };
    let mut up = Upstream { stream, buf: Vec::new(), url: url.to_string() };
    let host = addr.trim_end_matches(":80");
    let req = format!("GET {path} HTTP/1.0\r\nHost: {host}\r\nUser-Agent: motus-station\r\nAccept: image/jpeg, multipart/x-mixed-replace\r\n\r\n");
    up.stream.write_all(req.as_bytes()).await.map_err(io)?;
    let head = up.until(b"\r\n\r\n", MAX_HEAD, "response head").await?;
    let text = String::from_utf8_lossy(&head);
    let (status_line, rest) = text.split_once("\r\n").unwrap_or((&text, ""));
    let status = status_line.split_whitespace().nth(1).and_then(|s| s.parse().ok()).unwrap_or(0);
    Ok((up, Head { status, headers: parse_headers(rest) }))
}

/// The boundary of a `multipart/...; boundary=...` content type.
fn boundary(content_type: &str) -> Option<String> {
    let b = content_type.split(';').find_map(|p| p.trim().strip_prefix("boundary="))?;
    let b = b.trim().trim_matches('"');
    // Some cameras put the two leading dashes into the parameter already.
    let b = b.strip_prefix("--").unwrap_or(b);
    (!b.is_empty()).then(|| b.to_string())
}

/// Relays the camera at `url` to `viewer` until the viewer leaves.
pub async fn relay(mut viewer: Viewer, url: String) {
    let started = Instant::now();
    let mut last_error = String::new();
    loop {
        match relay_once(&mut viewer, &url).await {
            Err(RelayError::ViewerLeft) => return,
            Ok(()) => {}
            Err(e) => {
                let text = e.to_string();
                if text != last_error {
                    tracing::warn!(error = %text, "camera not relayed; trying again every {} s", RETRY.as_secs());
                    last_error = text;
                }
                match render::no_signal(started.elapsed().as_secs_f64()) {
                    Ok(jpeg) => {
                        if !viewer.send(&jpeg).await {
                            return;
                        }
                    }
                    Err(e) => tracing::error!(error = %e, "camera frame not encoded"),
                }
                tokio::time::sleep(RETRY).await;
            }
        }
    }
}

/// One connection to the camera: a whole MJPEG stream, or one still picture and the pause to
/// the next fetch.
async fn relay_once(viewer: &mut Viewer, url: &str) -> Result<(), RelayError> {
    let fetched = Instant::now();
    let (mut up, head) = request(url).await?;
    if head.status != 200 {
        return Err(up.answer(format!("HTTP status {}", head.status)));
    }
    let content_type = head.get("content-type").unwrap_or("").to_ascii_lowercase();
    let length = head.get("content-length").and_then(|v| v.parse::<usize>().ok());
    if content_type.starts_with("multipart/") {
        let b = boundary(head.get("content-type").unwrap_or(""))
            .ok_or_else(|| up.answer("a multipart answer without a boundary"))?;
        return stream_parts(viewer, &mut up, &b).await;
    }
    if !content_type.starts_with("image/") {
        return Err(up.answer(format!("answered {content_type:?}, not pictures")));
    }
    let jpeg = match length {
        Some(n) if n > MAX_FRAME => {
            return Err(up.answer(format!("picture of {n} bytes, more than {MAX_FRAME}")))
        }
        Some(n) => up.exact(n).await?,
        None => up.read_to_close(MAX_FRAME).await?,
    };
    if !viewer.send(&jpeg).await {
        return Err(RelayError::ViewerLeft);
    }
    let next = fetched + Duration::from_secs_f64(1.0 / STILL_PER_SECOND);
    tokio::time::sleep_until(next.into()).await;
    Ok(())
}

/// The parts of an MJPEG stream, each passed on (at most [`MAX_RELAYED_PER_SECOND`]).
async fn stream_parts(viewer: &mut Viewer, up: &mut Upstream, boundary: &str) -> Result<(), RelayError> {
    let delimiter = format!("--{boundary}");
    let min_gap = Duration::from_secs_f64(1.0 / MAX_RELAYED_PER_SECOND);
    let mut last_sent: Option<Instant> = None;
    // Up to the first delimiter (a preamble is allowed).
    up.until(delimiter.as_bytes(), MAX_HEAD, "stream preamble").await?;
    loop {
        // The rest of the delimiter line, then the part's headers.
        let line = up.until(b"\r\n", MAX_HEAD, "part delimiter").await?;
        if line.starts_with(b"--") {
            return Ok(()); // the closing delimiter: the camera ended the stream
        }
        let head = up.until(b"\r\n\r\n", MAX_HEAD, "part head").await?;
        let headers = parse_headers(&String::from_utf8_lossy(&head));
        let length =
            headers.iter().find(|(n, _)| n == "content-length").and_then(|(_, v)| v.parse::<usize>().ok());
        let jpeg = match length {
            Some(n) if n > MAX_FRAME => {
                return Err(up.answer(format!("picture of {n} bytes, more than {MAX_FRAME}")));
            }
            Some(n) => {
                let body = up.exact(n).await?;
                up.until(delimiter.as_bytes(), MAX_HEAD, "gap between pictures").await?;
                body
            }
            None => {
                let mut body = up.until(delimiter.as_bytes(), MAX_FRAME, "picture").await?;
                body.truncate(body.len().saturating_sub(delimiter.len()));
                while body.last().is_some_and(|b| *b == b'\n' || *b == b'\r') {
                    body.pop();
                }
                body
            }
        };
        if last_sent.map_or(true, |t| t.elapsed() >= min_gap) {
            if !viewer.send(&jpeg).await {
                return Err(RelayError::ViewerLeft);
            }
            last_sent = Some(Instant::now());
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]
mod tests {
    use super::*;

    #[test]
    fn urls_and_boundaries() {
        assert_eq!(split_url("http://cam.lab/video.mjpg"), Some(("cam.lab:80".into(), "/video.mjpg".into())));
        assert_eq!(split_url("http://10.0.0.5:8081"), Some(("10.0.0.5:8081".into(), "/".into())));
        assert_eq!(split_url("http://[::1]:9000/a"), Some(("[::1]:9000".into(), "/a".into())));
        assert_eq!(split_url("http://[::1]/a"), Some(("[::1]:80".into(), "/a".into())));
        assert_eq!(split_url("https://cam/a"), None);
        assert_eq!(split_url("http://user:pw@cam/a"), None);
        assert_eq!(boundary("multipart/x-mixed-replace; boundary=frame"), Some("frame".into()));
        assert_eq!(
            boundary("multipart/x-mixed-replace;boundary=\"--myboundary\""),
            Some("myboundary".into())
        );
        assert_eq!(boundary("multipart/x-mixed-replace"), None);
    }
}
