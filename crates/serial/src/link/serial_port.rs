//! Real serial ports (and the slave side of a pseudo-terminal), via the `serialport` crate.
//!
//! After an IO error (adapter unplugged, simulator restarted) the port is closed and
//! reopened at the next operation, so a long-running host reconnects by itself; the
//! operation that failed still reports its error.

use super::{LineSettings, Link};
use serialport::{ClearBuffer, SerialPort, TTYPort};
use std::io::{self, Read, Write};
use std::time::Duration;

/// An open serial port in raw 8N1 mode.
pub struct SerialLink {
    port: Option<TTYPort>,
    path: String,
    line: LineSettings,
}

fn open_port(path: &str, baud: u32) -> io::Result<TTYPort> {
    let port = serialport::new(path, baud)
        .data_bits(serialport::DataBits::Eight)
        .parity(serialport::Parity::None)
        .stop_bits(serialport::StopBits::One)
        .flow_control(serialport::FlowControl::None)
        .timeout(Duration::from_millis(10))
        .open_native()
        .map_err(|e| {
            io::Error::new(io::ErrorKind::NotFound, format!("cannot open serial port {path}: {e}"))
        })?;
    port.clear(ClearBuffer::Input).map_err(io::Error::other)?;
    Ok(port)
}

impl SerialLink {
    /// Opens `path` (e.g. `/dev/ttyUSB0`, or a simulator's pty link) at `baud`, 8N1,
    /// no flow control, and drops stale input.
    pub fn open(path: &str, baud: u32) -> io::Result<SerialLink> {
        let port = open_port(path, baud)?;
        Ok(SerialLink { port: Some(port), path: path.to_string(), line: LineSettings::n81(baud) })
    }

    fn port(&mut self) -> io::Result<&mut TTYPort> {
        if self.port.is_none() {
            tracing::info!(path = %self.path, "reopening serial port");
            self.port = Some(open_port(&self.path, self.line.baud)?);
        }
        self.port.as_mut().ok_or_else(|| io::Error::other("serial port not open"))
    }

    fn failed<T>(&mut self, e: io::Error) -> io::Result<T> {
        tracing::warn!(path = %self.path, error = %e, "serial port failed; it will be reopened");
        self.port = None;
        Err(e)
    }
}

impl Link for SerialLink {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        let port = self.port()?;
        match port.write_all(bytes).and_then(|_| port.flush()) {
            Ok(()) => Ok(()),
            Err(e) => self.failed(e),
        }
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let port = self.port()?;
        if timeout.is_zero() {
            // A poll: only what has already arrived (never "wait forever").
            let ready = match port.bytes_to_read() {
                Ok(n) => n,
                Err(e) => return self.failed(io::Error::other(e)),
            };
            if ready == 0 {
                return Ok(0);
            }
        }
        let port = self.port()?;
        port.set_timeout(timeout.max(Duration::from_millis(1))).map_err(io::Error::other)?;
        match port.read(buf) {
            Ok(0) => self.failed(io::Error::new(io::ErrorKind::UnexpectedEof, "serial port closed")),
            Ok(n) => Ok(n),
            Err(e) if e.kind() == io::ErrorKind::TimedOut || e.kind() == io::ErrorKind::WouldBlock => Ok(0),
            Err(e) if e.kind() == io::ErrorKind::Interrupted => Ok(0),
            Err(e) => self.failed(e),
        }
    }

    fn discard_input(&mut self) -> io::Result<()> {
        let port = self.port()?;
        match port.clear(ClearBuffer::Input) {
            Ok(()) => Ok(()),
            Err(e) => self.failed(io::Error::other(e)),
        }
    }

    fn line(&self) -> LineSettings {
        self.line
    }

    fn describe(&self) -> String {
        self.path.clone()
    }
}
