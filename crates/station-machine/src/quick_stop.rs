//! The E-stop's quick stops: one worker thread per axis, started with the station at device
//! priority and waiting for a press.
//!
//! A press hands every worker its order at once, so the slowest line does not delay the
//! others (axes on one serial line still take turns on it), and the quick stops run at the
//! device threads' priority even though the press arrives on a web thread (nice +10, which
//! a loaded host schedules late: spawning the stop threads from there cost up to 250 ms per
//! press). The press waits up to [`ESTOP_CONFIRM_WAIT`] for the commands to be sent.

use std::sync::atomic::Ordering;
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_axis::AxisCommand;

use crate::{lock, Shared};

/// How long an E-stop waits for the drives' quick-stop commands to be sent before it
/// answers; a drive still busy on its bus gets its quick stop as soon as its line is free,
/// and a failure is logged.
pub(crate) const ESTOP_CONFIRM_WAIT: Duration = Duration::from_millis(250);

/// How often an idle worker looks at the station's stop flag.
const IDLE_CHECK: Duration = Duration::from_millis(500);

/// A worker's answer: the axis index, the error of its quick stop if any, and when it ended.
type Done = (usize, Option<String>, Instant);

/// The workers' order channels, one per axis (in the order of `Shared::axes`).
pub(crate) struct QuickStoppers {
    orders: Vec<Mutex<Sender<Sender<Done>>>>,
}

impl QuickStoppers {
    /// Starts one worker per axis of `shared`; they end when the station stops.
    pub(crate) fn start(shared: &Arc<Shared>) -> std::io::Result<(QuickStoppers, Vec<JoinHandle<()>>)> {
        let mut orders = Vec::with_capacity(shared.axes.len());
        let mut threads = Vec::with_capacity(shared.axes.len());
        for i in 0..shared.axes.len() {
            let (tx, rx) = channel::<Sender<Done>>();
            let s = Arc::clone(shared);
            threads.push(std::thread::Builder::new().name("motus-estop".into()).spawn(move || {
                motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Device);
                worker(&s, i, &rx);
            })?);
            orders.push(Mutex::new(tx));
        }
        Ok((QuickStoppers { orders }, threads))
    }

    /// Quick-stops every axis at once; waits up to [`ESTOP_CONFIRM_WAIT`] for the commands
    /// to be sent. An axis whose worker is gone is stopped from the calling thread.
    pub(crate) fn stop_all(&self, shared: &Shared) {
        let (tx, rx) = channel::<Done>();
        let mut pending = 0usize;
        for (i, order) in self.orders.iter().enumerate() {
            if lock(order).send(tx.clone()).is_ok() {
                pending += 1;
            } else if let Some(a) = shared.axes.get(i) {
                tracing::warn!(axis = %a.view.id, "E-stop worker gone: quick-stopping inline");
                if let Err(e) = lock(&a.axis).execute(&AxisCommand::QuickStop) {
                    tracing::warn!(axis = %a.view.id, "quick stop: {e}");
                }
            }
        }
        drop(tx);
        let pressed = Instant::now();
        let deadline = pressed + ESTOP_CONFIRM_WAIT;
        let mut slowest: Option<(usize, Duration)> = None;
        while pending > 0 {
            match rx.recv_timeout(deadline.saturating_duration_since(Instant::now())) {
                Ok((i, err, ended)) => {
                    pending -= 1;
                    let took = ended.saturating_duration_since(pressed);
                    if slowest.is_none_or(|(_, t)| took > t) {
                        slowest = Some((i, took));
                    }
                    if let (Some(e), Some(a)) = (err, shared.axes.get(i)) {
                        tracing::warn!(axis = %a.view.id, "quick stop: {e}");
                    }
                }
                Err(_) => {
                    tracing::warn!(
                        "E-stop: {pending} axes still sending their quick stop after {ESTOP_CONFIRM_WAIT:?}"
                    );
                    break;
                }
            }
        }
        if let Some((i, took)) = slowest {
            let axis = shared.axes.get(i).map_or("?", |a| a.view.id.as_str());
            tracing::info!(
                axes = self.orders.len(),
                took_ms = pressed.elapsed().as_secs_f64() * 1e3,
                slowest = axis,
                slowest_ms = took.as_secs_f64() * 1e3,
                "E-stop: quick stops sent"
            );
        }
    }
}

/// Waits for orders and quick-stops axis `i` for each; ends when the station stops.
fn worker(s: &Shared, i: usize, orders: &Receiver<Sender<Done>>) {
    while !s.stop.load(Ordering::Relaxed) {
        let reply = match orders.recv_timeout(IDLE_CHECK) {
            Ok(reply) => reply,
            Err(RecvTimeoutError::Timeout) => continue,
            Err(RecvTimeoutError::Disconnected) => return,
        };
        let Some(a) = s.axes.get(i) else { return };
        let r = lock(&a.axis).execute(&AxisCommand::QuickStop);
        let _ = reply.send((i, r.err().map(|e| e.to_string()), Instant::now()));
    }
}
