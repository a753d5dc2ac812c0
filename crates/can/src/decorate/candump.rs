//! `candump -l` logs: `(1436509052.249713) can0 605#4000100000000000`, one line per frame.

use super::wall_clock;
use crate::{CanBus, CanError, CanFrame, Received};
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::Path;
use std::sync::{Mutex, MutexGuard};
use std::time::Duration;

/// One `candump -l` line (with its newline) for `frame` seen at `wall` on `iface`.
pub fn candump_line(frame: &CanFrame, wall: Duration, iface: &str) -> String {
    format!("({}.{:06}) {iface} {frame}\n", wall.as_secs(), wall.subsec_micros())
}

/// Logs every frame sent and received through the inner bus to a `candump -l` file.
pub struct CandumpLog<B> {
    inner: B,
    iface: String,
    out: Mutex<Box<dyn Write + Send>>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

impl<B: CanBus> CandumpLog<B> {
    /// Appends to the file at `path` (created if missing); lines name the bus `iface`.
    pub fn create(inner: B, path: &Path, iface: &str) -> Result<Self, CanError> {
        let file: File = OpenOptions::new().create(true).append(true).open(path)?;
        Ok(Self::to_writer(inner, Box::new(file), iface))
    }

    /// Logs to any writer (each line is written and flushed at once).
    pub fn to_writer(inner: B, out: Box<dyn Write + Send>, iface: &str) -> Self {
        CandumpLog { inner, iface: iface.to_owned(), out: Mutex::new(out) }
    }

    /// The wrapped bus.
    pub fn inner(&self) -> &B {
        &self.inner
    }

    fn log(&self, frame: &CanFrame) {
        let line = candump_line(frame, wall_clock(), &self.iface);
        let mut out = lock(&self.out);
        if let Err(e) = out.write_all(line.as_bytes()).and_then(|()| out.flush()) {
            tracing::warn!("candump log: write failed: {e}");
        }
    }
}

impl<B: CanBus> CanBus for CandumpLog<B> {
    fn send(&self, frame: &CanFrame) -> Result<(), CanError> {
        self.inner.send(frame)?;
        self.log(frame);
        Ok(())
    }

    fn send_batch(&self, frames: &[CanFrame]) -> Result<(), CanError> {
        self.inner.send_batch(frames)?;
        for f in frames {
            self.log(f);
        }
        Ok(())
    }

    fn recv(&self, timeout: Duration) -> Result<Option<Received>, CanError> {
        let r = self.inner.recv(timeout)?;
        if let Some(r) = &r {
            self.log(&r.frame);
        }
        Ok(r)
    }

    fn describe(&self) -> String {
        format!("{} (candump log)", self.inner.describe())
    }
}
