//! A socketcand client: joins a Motus [`Hub`](super::Hub) or a real socketcand daemon.

use super::codec::{Message, StreamParser};
use crate::{CanBus, CanError, CanFrame, Received};
use std::io::{Read, Write};
use std::net::{Shutdown, SocketAddr, TcpStream};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// Bytes read from the socket at a time.
const READ_CHUNK: usize = 8192;

/// How long each handshake step may take.
pub const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(5);

/// A [`CanBus`] over a socketcand connection in raw mode.
pub struct SocketcandBus {
    addr: SocketAddr,
    channel: String,
    writer: Mutex<TcpStream>,
    reading: Mutex<ReadState>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Reads until `parser` yields a message or the stream's read time-out expires.
fn next_message(stream: &mut TcpStream, parser: &mut StreamParser, what: &str) -> Result<Message, CanError> {
    let mut buf = [0u8; 512];
    loop {
        if let Some(m) = parser.next() {
            return Ok(m);
        }
        let n = match stream.read(&mut buf) {
            Ok(n) => n,
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {
                return Err(CanError::Protocol(format!(
                    "socketcand handshake: no {what} within {HANDSHAKE_TIMEOUT:?}"
                )))
            }
            Err(e) => return Err(e.into()),
        };
        if n == 0 {
            return Err(CanError::Closed(format!("socketcand server closed while waiting for {what}")));
        }
        parser.push(buf.get(..n).unwrap_or(&[]));
    }
}

fn expect(stream: &mut TcpStream, parser: &mut StreamParser, want: &Message) -> Result<(), CanError> {
    let what = want.format();
    match next_message(stream, parser, &what)? {
        m if &m == want => Ok(()),
        other => {
            Err(CanError::Protocol(format!("socketcand handshake: expected {what}, got {}", other.format())))
        }
    }
}

impl SocketcandBus {
    /// Connects to `addr`, opens `channel` and switches to raw mode.
    pub fn connect(addr: SocketAddr, channel: &str) -> Result<SocketcandBus, CanError> {
        if channel.is_empty() || channel.contains(|c: char| c.is_whitespace() || c == '<' || c == '>') {
            return Err(CanError::Address(format!("socketcand channel {channel:?} must be one word")));
        }
        let mut stream = TcpStream::connect_timeout(&addr, HANDSHAKE_TIMEOUT)?;
        stream.set_nodelay(true)?;
        stream.set_read_timeout(Some(HANDSHAKE_TIMEOUT))?;
        let mut parser = StreamParser::new();
        expect(&mut stream, &mut parser, &Message::Hi)?;
        stream.write_all(Message::Open(channel.to_owned()).format().as_bytes())?;
        expect(&mut stream, &mut parser, &Message::Ok)?;
        stream.write_all(Message::Rawmode.format().as_bytes())?;
        expect(&mut stream, &mut parser, &Message::Ok)?;
        let reading = stream.try_clone()?;
        Ok(SocketcandBus {
            addr,
            channel: channel.to_owned(),
            writer: Mutex::new(stream),
            reading: Mutex::new(ReadState {
                stream: reading,
                parser,
                timeout: None,
                closed: false,
                chunk: vec![0; READ_CHUNK],
            }),
        })
    }
}

/// The receiving side, read directly by [`CanBus::recv`] (no reader thread: one thread
/// hand-off less per frame).
struct ReadState {
    stream: TcpStream,
    parser: StreamParser,
    /// The read time-out currently set on the socket (set again only when it changes).
    timeout: Option<Duration>,
    closed: bool,
    /// Where the socket's bytes land before the parser takes them (kept: clearing 8 KiB
    /// on every receive cost more than parsing the frames in it).
    chunk: Vec<u8>,
}

impl ReadState {
    fn next_frame(&mut self) -> Option<CanFrame> {
        for msg in self.parser.by_ref() {
            match msg {
                Message::Frame { frame, .. } => return Some(frame),
                Message::Error(text) => tracing::warn!("socketcand: error reported by server: {text}"),
                other => tracing::debug!("socketcand client: ignoring {other:?}"),
            }
        }
        None
    }
}

impl CanBus for SocketcandBus {
    fn send(&self, frame: &CanFrame) -> Result<(), CanError> {
        let text = Message::Send(frame.clone()).format();
        lock(&self.writer)
            .write_all(text.as_bytes())
            .map_err(|e| CanError::Closed(format!("{}: {e}", self.describe())))
    }

    fn send_batch(&self, frames: &[CanFrame]) -> Result<(), CanError> {
        let mut text = String::with_capacity(48 * frames.len());
        for f in frames {
            Message::Send(f.clone()).format_into(&mut text);
        }
        lock(&self.writer)
            .write_all(text.as_bytes())
            .map_err(|e| CanError::Closed(format!("{}: {e}", self.describe())))
    }

    fn recv(&self, timeout: Duration) -> Result<Option<Received>, CanError> {
        let mut guard = lock(&self.reading);
        let r = &mut *guard;
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(frame) = r.next_frame() {
                return Ok(Some(Received { frame, at: Instant::now() }));
            }
            if r.closed {
                return Err(CanError::Closed(format!("{}: connection closed", self.describe())));
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(None);
            }
            // Time-outs are rounded up to whole milliseconds, so the socket option changes
            // rarely (a zero time-out is not allowed: it would mean "block forever").
            let want = Some(Duration::from_millis(left.as_millis().max(1).try_into().unwrap_or(u64::MAX)));
            if r.timeout != want {
                r.stream.set_read_timeout(want)?;
                r.timeout = want;
            }
            match r.stream.read(&mut r.chunk) {
                Ok(0) => r.closed = true,
                Ok(n) => r.parser.push(r.chunk.get(..n).unwrap_or(&[])),
                Err(e)
                    if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) =>
                {
                    return Ok(None)
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => {
                    r.closed = true;
                    return Err(CanError::Closed(format!("{}: {e}", self.describe())));
                }
            }
        }
    }

    fn describe(&self) -> String {
        format!("socketcand://{}/{}", self.addr, self.channel)
    }
}

impl Drop for SocketcandBus {
    fn drop(&mut self) {
        let _ = lock(&self.writer).shutdown(Shutdown::Both);
    }
}
