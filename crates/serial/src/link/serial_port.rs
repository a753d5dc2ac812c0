//! Real serial ports (and the slave side of a pseudo-terminal), via the `serialport` crate.

use super::{LineSettings, Link};
use serialport::{ClearBuffer, SerialPort, TTYPort};
use std::io::{self, Read, Write};
use std::time::Duration;

/// An open serial port in raw 8N1 mode.
pub struct SerialLink {
    port: TTYPort,
    path: String,
    line: LineSettings,
}

impl SerialLink {
    /// Opens `path` (e.g. `/dev/ttyUSB0`, or a simulator's pty link) at `baud`, 8N1,
    /// no flow control, and drops stale input.
    pub fn open(path: &str, baud: u32) -> io::Result<SerialLink> {
        let port = serialport::new(path, baud)
            .data_bits(serialport::DataBits::Eight)
            .parity(serialport::Parity::None)
            .stop_bits(serialport::StopBits::One)
            .flow_control(serialport::FlowControl::None)
            .timeout(Duration::from_millis(10))
            .open_native()
            .map_err(|e| io::Error::new(io::ErrorKind::NotFound, format!("cannot open serial port {path}: {e}")))?;
        let mut link = SerialLink { port, path: path.to_string(), line: LineSettings::n81(baud) };
        link.discard_input()?;
        Ok(link)
    }
}

impl Link for SerialLink {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.port.write_all(bytes)?;
        self.port.flush()
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        if timeout.is_zero() {
            return Ok(0);
        }
        self.port.set_timeout(timeout).map_err(io::Error::other)?;
        match self.port.read(buf) {
            Ok(n) => Ok(n),
            Err(e) if e.kind() == io::ErrorKind::TimedOut || e.kind() == io::ErrorKind::WouldBlock => Ok(0),
            Err(e) => Err(e),
        }
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.port.clear(ClearBuffer::Input).map_err(io::Error::other)
    }

    fn line(&self) -> LineSettings {
        self.line
    }

    fn describe(&self) -> String {
        self.path.clone()
    }
}
