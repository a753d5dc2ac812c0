//! Bus load: measured over a sliding window ([`BusLoad`]) and planned for a periodic
//! cycle ([`cycle_load`], [`check_cycle`]), with worst-case stuffed frame lengths.

use crate::wire_time::worst_case_bits;
use crate::{CanBus, CanError, CanFrame, Received};
use std::collections::VecDeque;
use std::fmt;
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// The wire budget of one cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleLoad {
    /// Worst-case bits of the cycle's frames.
    pub bits: u64,
    /// Time the bus is busy carrying them.
    pub busy: Duration,
    /// `busy / period`.
    pub fraction: f64,
}

/// A cycle whose frames do not fit in its period.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct CycleTooLong {
    /// Frames in the cycle.
    pub frames: usize,
    /// The cycle period.
    pub period: Duration,
    /// The bit rate.
    pub bitrate: u32,
    /// The load it would need.
    pub load: CycleLoad,
}

fn fmt_ms(d: Duration) -> String {
    let ms = d.as_secs_f64() * 1e3;
    if (ms - ms.round()).abs() < 1e-9 {
        format!("{ms:.0}")
    } else {
        format!("{ms:.1}")
    }
}

impl fmt::Display for CycleTooLong {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let rate = if (self.bitrate / 1000) * 1000 == self.bitrate {
            format!("{} kbit/s", self.bitrate / 1000)
        } else {
            format!("{} bit/s", self.bitrate)
        };
        write!(
            f,
            "a {} ms cycle of {} frames needs {} ms at {rate}",
            fmt_ms(self.period),
            self.frames,
            fmt_ms(self.load.busy)
        )
    }
}

/// Worst-case bits and bus time of `frames` sent once per `period` at `bitrate`.
pub fn cycle_load(frames: &[CanFrame], period: Duration, bitrate: u32) -> CycleLoad {
    let bits: u64 = frames.iter().map(|f| u64::from(worst_case_bits(f))).sum();
    let busy = Duration::from_nanos(bits.saturating_mul(1_000_000_000) / u64::from(bitrate.max(1)));
    let fraction = if period.is_zero() { f64::INFINITY } else { busy.as_secs_f64() / period.as_secs_f64() };
    CycleLoad { bits, busy, fraction }
}

/// [`cycle_load`], failing when the frames need more than the whole period.
pub fn check_cycle(frames: &[CanFrame], period: Duration, bitrate: u32) -> Result<CycleLoad, CycleTooLong> {
    let load = cycle_load(frames, period, bitrate);
    if load.busy > period {
        return Err(CycleTooLong { frames: frames.len(), period, bitrate, load });
    }
    Ok(load)
}

/// The load measured by [`BusLoad`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoadReport {
    /// Worst-case bits per second over the window.
    pub bits_per_second: f64,
    /// `bits_per_second / bitrate`.
    pub fraction: f64,
    /// Worst-case bits of every frame seen since the start.
    pub total_bits: u64,
}

struct State {
    events: VecDeque<(Instant, u32)>,
    window_bits: u64,
    total_bits: u64,
    warned_at: Option<Instant>,
}

/// Accounts the worst-case bits of every frame sent and received through the inner bus.
pub struct BusLoad<B> {
    inner: B,
    bitrate: u32,
    window: Duration,
    threshold: f64,
    state: Mutex<State>,
}

impl<B: CanBus> BusLoad<B> {
    /// Wraps `inner` on a bus at `bitrate`; warns (once per window) when the load over
    /// `window` exceeds `threshold` (a fraction, e.g. 0.7).
    pub fn new(inner: B, bitrate: u32, window: Duration, threshold: f64) -> Self {
        let state = State { events: VecDeque::new(), window_bits: 0, total_bits: 0, warned_at: None };
        BusLoad {
            inner,
            bitrate: bitrate.max(1),
            window: window.max(Duration::from_millis(1)),
            threshold,
            state: Mutex::new(state),
        }
    }

    /// The wrapped bus.
    pub fn inner(&self) -> &B {
        &self.inner
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn expire(&self, state: &mut State, now: Instant) {
        while let Some(&(t, bits)) = state.events.front() {
            if now.duration_since(t) <= self.window {
                break;
            }
            state.window_bits -= u64::from(bits);
            state.events.pop_front();
        }
    }

    fn report(&self, state: &State) -> LoadReport {
        let bits_per_second = state.window_bits as f64 / self.window.as_secs_f64();
        LoadReport {
            bits_per_second,
            fraction: bits_per_second / f64::from(self.bitrate),
            total_bits: state.total_bits,
        }
    }

    /// The load over the last window.
    pub fn load(&self) -> LoadReport {
        let mut state = self.lock();
        self.expire(&mut state, Instant::now());
        self.report(&state)
    }

    fn account(&self, frame: &CanFrame) {
        let now = Instant::now();
        let bits = worst_case_bits(frame);
        let mut state = self.lock();
        state.events.push_back((now, bits));
        state.window_bits += u64::from(bits);
        state.total_bits += u64::from(bits);
        self.expire(&mut state, now);
        let report = self.report(&state);
        if report.fraction > self.threshold
            && !matches!(state.warned_at, Some(t) if now.duration_since(t) < self.window)
        {
            state.warned_at = Some(now);
            tracing::warn!(
                bus = %self.inner.describe(),
                "CAN bus load {:.0} % of {} bit/s over {:?} (threshold {:.0} %)",
                report.fraction * 100.0,
                self.bitrate,
                self.window,
                self.threshold * 100.0
            );
        }
    }
}

impl<B: CanBus> CanBus for BusLoad<B> {
    fn send(&self, frame: &CanFrame) -> Result<(), CanError> {
        self.inner.send(frame)?;
        self.account(frame);
        Ok(())
    }

    fn send_batch(&self, frames: &[CanFrame]) -> Result<(), CanError> {
        self.inner.send_batch(frames)?;
        for f in frames {
            self.account(f);
        }
        Ok(())
    }

    fn recv(&self, timeout: Duration) -> Result<Option<Received>, CanError> {
        let r = self.inner.recv(timeout)?;
        if let Some(r) = &r {
            self.account(&r.frame);
        }
        Ok(r)
    }

    fn describe(&self) -> String {
        format!("{} (bus load)", self.inner.describe())
    }
}
