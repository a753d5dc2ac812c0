//! A socketcand client: joins a Motus [`Hub`](super::Hub) or a real socketcand daemon.

use super::codec::{Message, StreamParser};
use crate::{CanBus, CanError, CanFrame, Received};
use std::io::{Read, Write};
use std::net::{Shutdown, SocketAddr, TcpStream};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// How long each handshake step may take.
pub const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(5);

/// A [`CanBus`] over a socketcand connection in raw mode.
pub struct SocketcandBus {
    addr: SocketAddr,
    channel: String,
    writer: Mutex<TcpStream>,
    rx: Mutex<Receiver<Received>>,
    reader: Option<std::thread::JoinHandle<()>>,
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
        stream.set_read_timeout(None)?;
        let (tx, rx) = mpsc::channel();
        let reading = stream.try_clone()?;
        let name = format!("socketcand-client-{addr}");
        let reader = std::thread::Builder::new().name(name).spawn(move || read_loop(reading, parser, &tx))?;
        Ok(SocketcandBus {
            addr,
            channel: channel.to_owned(),
            writer: Mutex::new(stream),
            rx: Mutex::new(rx),
            reader: Some(reader),
        })
    }
}

fn read_loop(mut stream: TcpStream, mut parser: StreamParser, tx: &Sender<Received>) {
    let mut buf = [0u8; 8192];
    loop {
        for msg in parser.by_ref() {
            match msg {
                Message::Frame { frame, .. } => {
                    if tx.send(Received { frame, at: Instant::now() }).is_err() {
                        return;
                    }
                }
                Message::Error(text) => tracing::warn!("socketcand: error reported by server: {text}"),
                other => tracing::debug!("socketcand client: ignoring {other:?}"),
            }
        }
        match stream.read(&mut buf) {
            Ok(0) | Err(_) => return,
            Ok(n) => parser.push(buf.get(..n).unwrap_or(&[])),
        }
    }
}

impl CanBus for SocketcandBus {
    fn send(&self, frame: &CanFrame) -> Result<(), CanError> {
        let text = Message::Send(frame.clone()).format();
        lock(&self.writer)
            .write_all(text.as_bytes())
            .map_err(|e| CanError::Closed(format!("{}: {e}", self.describe())))
    }

    fn recv(&self, timeout: Duration) -> Result<Option<Received>, CanError> {
        match lock(&self.rx).recv_timeout(timeout) {
            Ok(r) => Ok(Some(r)),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => {
                Err(CanError::Closed(format!("{}: connection closed", self.describe())))
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
        if let Some(t) = self.reader.take() {
            let _ = t.join();
        }
    }
}
