//! Watch and trace: any signal (positions, velocities, statuswords, safety outputs, bus
//! statistics) recorded at its task's cycle into a per-signal ring buffer.
//!
//! * [`Recorder::register`] names a signal and its unit; [`Recorder::record`] appends
//!   one `(time, value)` (time since the recorder's epoch, passed in).
//! * Streaming to the HMI: keep a [`Cursor`] and call [`Recorder::samples_since`]; it
//!   returns the new samples, the advanced cursor and how many were lost to overwriting.
//! * CSV: [`Recorder::write_csv`] and [`Capture::write_csv`] — a header with names and
//!   units, one row per timestamp.
//! * Triggers: [`Recorder::arm`] a [`Trigger`]; when it fires and its post-trigger
//!   samples are in, a [`Capture`] with the pre- and post-trigger window of every signal
//!   is available from [`Recorder::take_captures`].
//!
//! The recorder is single-owner (`&mut self` to record); share it as
//! `Arc<Mutex<Recorder>>` between the recording task and the HMI ([`TraceTask`]).

mod csv;
mod ring;
mod task;
mod trigger;

use std::time::Duration;

pub use ring::Sample;
pub use task::{Probe, TraceTask};
pub use trigger::{Capture, CapturedSignal, Condition, Trigger, TriggerId};

use ring::Ring;
use trigger::Armed;

/// Identifies a registered signal (its registration index).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SignalId(pub u32);

impl SignalId {
    fn index(self) -> usize {
        self.0 as usize
    }
}

/// A signal's description.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SignalInfo {
    /// Its id.
    pub id: SignalId,
    /// Unique name, e.g. `omni.wheel1.position`.
    pub name: String,
    /// Unit, e.g. `rad`, `m/s`, `` (none).
    pub unit: String,
}

/// Trace errors.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TraceError {
    /// The name is taken.
    #[error("signal {0:?} is already registered")]
    DuplicateSignal(String),
    /// Names and units must be non-empty and free of commas, quotes and line breaks (CSV).
    #[error("invalid signal {what} {value:?}: no commas, quotes or line breaks (and a name is not empty)")]
    InvalidName {
        /// `name` or `unit`.
        what: &'static str,
        /// The rejected text.
        value: String,
    },
    /// No such signal.
    #[error("unknown signal id {0}")]
    UnknownSignal(u32),
    /// The pre-trigger window does not fit the ring buffer.
    #[error("pre_samples + post_samples ({requested}) must be below the ring capacity ({capacity})")]
    WindowTooLarge {
        /// pre + post.
        requested: usize,
        /// Ring capacity.
        capacity: usize,
    },
}

/// Where a stream reader stands: the next sequence number per signal.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Cursor {
    next: Vec<u64>,
}

/// New samples of one signal.
#[derive(Debug, Clone, PartialEq)]
pub struct SignalSamples {
    /// Which signal.
    pub signal: SignalId,
    /// New samples, oldest first.
    pub samples: Vec<Sample>,
}

/// What [`Recorder::samples_since`] returns.
#[derive(Debug, Clone, PartialEq)]
pub struct Batch {
    /// New samples per signal (signals without new samples are left out).
    pub signals: Vec<SignalSamples>,
    /// Samples the reader missed because the ring overwrote them.
    pub lost: u64,
    /// The cursor for the next call.
    pub cursor: Cursor,
}

/// Completed captures kept until taken (oldest dropped first).
const MAX_CAPTURES: usize = 16;

/// Per-signal ring buffers with triggers.
#[derive(Debug)]
pub struct Recorder {
    capacity: usize,
    signals: Vec<SignalInfo>,
    rings: Vec<Ring>,
    armed: Vec<Armed>,
    next_trigger: u64,
    captures: Vec<Capture>,
}

fn valid_text(s: &str) -> bool {
    !s.contains([',', '"', '\n', '\r'])
}

impl Recorder {
    /// A recorder whose rings hold `capacity` samples per signal (at least 2).
    pub fn new(capacity: usize) -> Self {
        Recorder {
            capacity: capacity.max(2),
            signals: Vec::new(),
            rings: Vec::new(),
            armed: Vec::new(),
            next_trigger: 0,
            captures: Vec::new(),
        }
    }

    /// Samples held per signal.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Registers a signal.
    pub fn register(&mut self, name: &str, unit: &str) -> Result<SignalId, TraceError> {
        if name.is_empty() || !valid_text(name) {
            return Err(TraceError::InvalidName { what: "name", value: name.to_string() });
        }
        if !valid_text(unit) {
            return Err(TraceError::InvalidName { what: "unit", value: unit.to_string() });
        }
        if self.signals.iter().any(|s| s.name == name) {
            return Err(TraceError::DuplicateSignal(name.to_string()));
        }
        let id = SignalId(u32::try_from(self.signals.len()).unwrap_or(u32::MAX));
        self.signals.push(SignalInfo { id, name: name.to_string(), unit: unit.to_string() });
        self.rings.push(Ring::new(self.capacity));
        Ok(id)
    }

    /// Every signal, in registration order.
    pub fn signals(&self) -> &[SignalInfo] {
        &self.signals
    }

    /// A signal's description.
    pub fn signal(&self, id: SignalId) -> Option<&SignalInfo> {
        self.signals.get(id.index())
    }

    /// The signal called `name`.
    pub fn find(&self, name: &str) -> Option<SignalId> {
        self.signals.iter().find(|s| s.name == name).map(|s| s.id)
    }

    /// Records one value of a signal at time `t` (since the recorder's epoch).
    #[inline]
    pub fn record(&mut self, id: SignalId, t: Duration, value: f64) -> Result<(), TraceError> {
        let ring = self.rings.get_mut(id.index()).ok_or(TraceError::UnknownSignal(id.0))?;
        let prev = ring.latest().map(|s| s.value);
        let sample = Sample { t, value };
        ring.push(sample);
        if !self.armed.is_empty() {
            self.check_triggers(id, prev, sample);
        }
        Ok(())
    }

    fn check_triggers(&mut self, id: SignalId, prev: Option<f64>, sample: Sample) {
        let Some(ring) = self.rings.get(id.index()) else { return };
        let seq = ring.total() - 1;
        let mut done = Vec::new();
        for (i, a) in self.armed.iter_mut().enumerate() {
            if a.trigger.signal != id {
                continue;
            }
            let pre = a.trigger.pre_samples as u64;
            let pre_start = ring
                .get(seq.saturating_sub(pre))
                .or_else(|| ring.get(ring.first_seq()))
                .map_or(sample.t, |s| s.t);
            if a.on_sample(prev, sample, seq, pre_start) {
                done.push(i);
            }
        }
        for i in done.into_iter().rev() {
            let a = self.armed.remove(i);
            if let Some(c) = self.capture(&a, sample.t) {
                if self.captures.len() >= MAX_CAPTURES {
                    self.captures.remove(0);
                }
                self.captures.push(c);
            }
        }
    }

    fn capture(&self, a: &Armed, end: Duration) -> Option<Capture> {
        let (fired_at, fired_value, _, start) = a.fired?;
        let signals = self
            .signals
            .iter()
            .zip(&self.rings)
            .map(|(info, ring)| CapturedSignal { signal: info.id, samples: ring.window(start, end) })
            .collect();
        Some(Capture { id: a.id, trigger: a.trigger, fired_at, fired_value, window: (start, end), signals })
    }

    /// The newest sample of a signal.
    pub fn latest(&self, id: SignalId) -> Option<Sample> {
        self.rings.get(id.index()).and_then(Ring::latest)
    }

    /// Every sample of a signal still held, oldest first.
    pub fn samples(&self, id: SignalId) -> Vec<Sample> {
        self.rings.get(id.index()).map(|r| r.since(0).0).unwrap_or_default()
    }

    /// A cursor at the current end: a reader starting here sees only new samples.
    pub fn cursor_now(&self) -> Cursor {
        Cursor { next: self.rings.iter().map(Ring::total).collect() }
    }

    /// Everything recorded after `cursor` (`Cursor::default()` = from the oldest held).
    pub fn samples_since(&self, cursor: &Cursor) -> Batch {
        let mut lost = 0;
        let mut signals = Vec::new();
        let mut next = Vec::with_capacity(self.rings.len());
        for (i, (info, ring)) in self.signals.iter().zip(&self.rings).enumerate() {
            let from = cursor.next.get(i).copied().unwrap_or(0);
            let (samples, l) = ring.since(from);
            lost += l;
            if !samples.is_empty() {
                signals.push(SignalSamples { signal: info.id, samples });
            }
            next.push(ring.total().max(from));
        }
        Batch { signals, lost, cursor: Cursor { next } }
    }

    /// Arms a one-shot trigger.
    pub fn arm(&mut self, trigger: Trigger) -> Result<TriggerId, TraceError> {
        if self.rings.get(trigger.signal.index()).is_none() {
            return Err(TraceError::UnknownSignal(trigger.signal.0));
        }
        let requested = trigger.pre_samples.saturating_add(trigger.post_samples);
        if requested >= self.capacity {
            return Err(TraceError::WindowTooLarge { requested, capacity: self.capacity });
        }
        let id = TriggerId(self.next_trigger);
        self.next_trigger += 1;
        self.armed.push(Armed::new(id, trigger));
        Ok(id)
    }

    /// Disarms a trigger (fired or not); false if unknown or already complete.
    pub fn disarm(&mut self, id: TriggerId) -> bool {
        let before = self.armed.len();
        self.armed.retain(|a| a.id != id);
        self.armed.len() != before
    }

    /// Armed triggers and whether each has fired (waiting for post-trigger samples).
    pub fn armed(&self) -> Vec<(TriggerId, bool)> {
        self.armed.iter().map(|a| (a.id, a.fired.is_some())).collect()
    }

    /// Takes the completed captures, oldest first.
    pub fn take_captures(&mut self) -> Vec<Capture> {
        std::mem::take(&mut self.captures)
    }

    /// Writes the held samples of `ids` (all signals when empty) as CSV.
    pub fn write_csv(&self, ids: &[SignalId], out: &mut dyn std::io::Write) -> std::io::Result<()> {
        let chosen: Vec<SignalId> =
            if ids.is_empty() { self.signals.iter().map(|s| s.id).collect() } else { ids.to_vec() };
        let cols: Vec<(&SignalInfo, Vec<Sample>)> =
            chosen.iter().filter_map(|id| self.signal(*id).map(|info| (info, self.samples(*id)))).collect();
        csv::write(&cols, out)
    }
}

impl Capture {
    /// Writes the capture as CSV (names and units from the recorder that made it).
    pub fn write_csv(&self, recorder: &Recorder, out: &mut dyn std::io::Write) -> std::io::Result<()> {
        let cols: Vec<(&SignalInfo, Vec<Sample>)> = self
            .signals
            .iter()
            .filter_map(|c| recorder.signal(c.signal).map(|info| (info, c.samples.clone())))
            .collect();
        csv::write(&cols, out)
    }
}

#[cfg(test)]
mod tests;
