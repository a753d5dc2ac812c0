//! Bus and per-device statistics.

use std::time::Duration;

/// Counters of one device on the line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DeviceStats {
    /// Transactions requested.
    pub transactions: u64,
    /// Transactions that got a valid reply.
    pub ok: u64,
    /// Attempts that ended without a valid reply.
    pub timeouts: u64,
    /// Attempts repeated after a failure.
    pub retries: u64,
    /// Frame-shaped replies that failed their integrity check.
    pub corrupt_frames: u64,
    /// Valid frames that were not the expected reply (e.g. another address).
    pub unexpected_frames: u64,
    /// Transactions that failed after all attempts.
    pub failures: u64,
}

/// Statistics of the whole line over a window.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BusStats {
    /// Length of the window.
    pub window: Duration,
    /// Totals over all devices.
    pub totals: DeviceStats,
    /// Bytes written.
    pub bytes_tx: u64,
    /// Bytes received.
    pub bytes_rx: u64,
    /// Bytes dropped while resynchronising (noise, and the first byte of each corrupt
    /// frame).
    pub garbage_bytes: u64,
    /// Wire time of all bytes sent and received.
    pub wire_busy: Duration,
    /// Baud rate of the line.
    pub baud: u32,
}

impl BusStats {
    /// Successful transactions per second.
    pub fn transactions_per_second(&self) -> f64 {
        let s = self.window.as_secs_f64();
        if s > 0.0 {
            self.totals.ok as f64 / s
        } else {
            0.0
        }
    }

    /// Fraction (0..=1, may slightly exceed 1 on a pty without pacing) of the window
    /// the line was carrying bytes: the utilisation relative to the wire limit.
    pub fn utilisation(&self) -> f64 {
        let s = self.window.as_secs_f64();
        if s > 0.0 {
            self.wire_busy.as_secs_f64() / s
        } else {
            0.0
        }
    }
}
