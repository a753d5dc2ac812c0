//! Serving the sensor on a link: one packet every period, paced at the line's baud rate
//! (9600 bit/s 8N1: 1.04 ms per byte, 7.29 ms per packet).

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use motus_clock::{SharedClock, SystemClock};
use motus_serial::{Link, Paced};

use crate::sensor::MouseSensor;

/// What [`serve`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ServeStats {
    /// Packets sent.
    pub packets: u64,
    /// Bytes written (packets and garbage).
    pub bytes: u64,
    /// Periods that started late because the previous write took longer than a period
    /// (the line was busy: long garbage bursts, or a period shorter than a packet).
    pub late_periods: u64,
}

/// Sends the sensor's packets on `link` until `stop` is set, then one last packet with
/// the counts still owed, on the system clock (see [`serve_with_clock`]).
///
/// # Errors
/// An IO error of the link.
pub fn serve(link: &mut dyn Link, sensor: &mut MouseSensor, stop: &AtomicBool) -> io::Result<ServeStats> {
    serve_with_clock(link, sensor, stop, &SystemClock::shared())
}

/// Sends the sensor's packets on `link` until `stop` is set, then one last packet with
/// the counts still owed. Bytes leave one by one at the link's baud rate ([`Paced`]; the
/// link is borrowed so a pty outlives the run and a host can read what is still buffered);
/// a period starts at `start + k * period`, or when the line is free if that is later. The
/// one-way converter reads nothing: input from the host is discarded.
///
/// Every wait is on `clock`: on a [`motus_clock::VirtualClock::threaded`] clock shared
/// with a test (the serving thread started with [`motus_clock::spawn`]), a run of minutes
/// takes milliseconds and its timing is exact.
///
/// # Errors
/// An IO error of the link.
pub fn serve_with_clock(
    link: &mut dyn Link,
    sensor: &mut MouseSensor,
    stop: &AtomicBool,
    clock: &SharedClock,
) -> io::Result<ServeStats> {
    const SLICE: Duration = Duration::from_millis(1);
    let mut link = Paced::with_clock(link, Arc::clone(clock));
    let period = sensor.config().period;
    let mut stats = ServeStats::default();
    let mut due = clock.now() + period;
    let mut scratch = [0u8; 64];
    loop {
        // Wait for the period in short slices so a stop is seen quickly.
        while clock.now() < due && !stop.load(Ordering::Relaxed) {
            let left = due.saturating_duration_since(clock.now());
            if left > 2 * SLICE {
                // Discards anything the host wrote (the converter only transmits).
                let before = clock.now();
                let _ = link.read(&mut scratch, SLICE)?;
                if clock.now() == before {
                    // The link returned without moving the clock (an in-memory link on a
                    // virtual clock): the slice is waited on the clock.
                    clock.sleep(SLICE);
                }
            } else {
                clock.sleep_until(due);
            }
        }
        let stopping = stop.load(Ordering::Relaxed);
        let bytes = sensor.next_bytes();
        link.write_all(&bytes)?;
        stats.packets += 1;
        stats.bytes += bytes.len() as u64;
        if stopping {
            tracing::debug!(packets = stats.packets, "mouse sensor stopped");
            return Ok(stats);
        }
        due += period;
        let now = clock.now();
        if due < now {
            stats.late_periods += 1;
            due = now;
        }
    }
}
